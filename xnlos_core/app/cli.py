"""Command line: ``xnlos run | sweep | eval | demo | plugins | check | crossmodal`` (also ``python -m xnlos_core``).

Every other command (``simulate``, ``train``, ``emulate``, …) is added by the package that owns it
through the ``xnlos_add_commands`` hook; ``check`` asks the ``xnlos_check_config`` hook about configs
that are not pipelines."""
from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path

from xnlos_core import __version__
from xnlos_core.errors import ConfigError, PluginError, XnlosError, XnlosWarning
from xnlos_core.files import ROOTS_ENV, os_reason
from xnlos_core.interfaces import KINDS

DEMO_CONFIG = Path(__file__).resolve().parents[1] / "defaults" / "demo.toml"  # xnlos_core/defaults
OWN_MODULES = r"(xnlos_core|sims|plugins|estimators|hardware)(\.|$)"  # warnings that -q keeps
QUIET_HELP = ("quiet: no progress bars, no report and no other library's warnings on stdout/stderr; only errors "
              "and xnlos's own warnings (e.g. a pipeline that can never reconstruct); the files are written as usual")


def _cmd_run(args) -> int:
    from xnlos_core.config import load_pipeline
    from xnlos_core.app.runner import run_to_dir

    cfg = load_pipeline(args.config)
    if args.frames is not None:
        cfg = cfg.model_copy(update={"run": cfg.run.model_copy(update={"frames": args.frames})})
    summary = run_to_dir(cfg, args.out, source=str(args.config), progress=not args.quiet, overwrite=args.overwrite)
    if not args.quiet:
        _report(summary, Path(args.out))
    return 0


def _report(summary: dict, out: Path) -> None:
    from xnlos_core.app.runner import object_verdict

    for name, info in (summary.get("objects") or {}).items():
        if info["status"] == "in line of sight":  # in plain view: no hidden-object error to report
            print(f"{name}: {object_verdict(info)}")
        else:
            print(f"hidden {name}: reconstruction error {object_verdict(info)}")
    proc = sum(v for k, v in summary["time_ms"].items() if k != "source")
    print(f"{summary['frames']} frame(s), {proc:.1f} ms/frame processing; wrote {out / 'summary.md'}"
          + (f" and {out / summary['figure']}" if summary.get("figure") else "")
          + (f" and {out / summary['animation']}" if summary.get("animation") else ""))


def _cmd_demo(args) -> int:
    args.config, args.frames = DEMO_CONFIG, None
    return _cmd_run(args)


def _cmd_sweep(args) -> int:
    from xnlos_core.app.sweep import run_sweep

    records = run_sweep(args.config, args.out, scheduler=args.scheduler, workers=args.workers, progress=not args.quiet,
                        overwrite=args.overwrite)
    if args.quiet:
        return 0
    print((Path(args.out) / "sweep.md").read_text())
    print(f"{len(records)} point(s); wrote {Path(args.out) / 'sweep.md'}")
    return 0


def _cmd_eval(args) -> int:
    from xnlos_core.app.evaluation import run_eval

    args.out = args.out or Path("out/eval") / args.config.stem
    res = run_eval(args.config, args.out, dataset=args.dataset, split=args.split, limit=args.limit,
                   start=args.start, figures=0 if args.no_figures else args.figures, progress=not args.quiet,
                   overwrite=args.overwrite)
    if args.quiet:
        return 0
    out = args.out
    print((out / "eval.md").read_text())
    print(f"{len(res['runs'])} run(s) on {sum(r['overall']['maps'] for r in res['runs'])} map(s); wrote "
          f"{out / 'eval.md'} and {out / 'eval.json'}")
    return 0


def check_file(path: str | Path) -> str:
    """Validate a pipeline, dataset or training config without running it; returns the one-line verdict.

    Runs what ``run`` / ``simulate`` / ``train`` run before their first frame (for a pipeline: every
    sweep point's :class:`~xnlos_core.pipeline.Pipeline`, which reads the files it names and lets
    the forward model check the scene, and :meth:`~xnlos_core.pipeline.Pipeline.check_inputs`, which
    loads learned checkpoints and opens a recording as a run does). Every refusal is an :class:`~xnlos_core.errors.XnlosError`.
    A pipeline that is valid but cannot deliver what it is configured for (e.g. it can never
    reconstruct: :meth:`~xnlos_core.pipeline.Pipeline.warn_unreachable`) is flagged, not refused:
    its :class:`~xnlos_core.errors.XnlosWarning` is issued again naming the sweep point, and the
    verdict says how many pipelines were flagged.
    """
    from xnlos_core.config import expand_sweep, load_toml, parse_pipeline
    from xnlos_core.pipeline import Pipeline

    path = Path(path)
    table = load_toml(path)
    if "modality" in table and "detector" not in table:  # a cross-modality study (xnlos crossmodal)
        from xnlos_core.app.crossmodal.study import check_study

        return check_study(path)
    if "detector" not in table:  # a dataset or training config: its owner checks it (xnlos_check_config)
        from xnlos_core.registry import get_manager

        verdict = get_manager().pm.hook.xnlos_check_config(table=table, path=path)
        if verdict is not None:
            return verdict
    points = expand_sweep(table, str(path))
    flagged = 0
    for i, (assignment, t) in enumerate(points):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always", XnlosWarning)
            Pipeline(parse_pipeline(t, str(path), path.resolve().parent), source=str(path)).check_inputs()
        ours = [w for w in caught if issubclass(w.category, XnlosWarning)]
        flagged += bool(ours)
        where = "" if len(points) == 1 else f" [sweep point {i}: " + ", ".join(
            f"{k} = {v!r}" for k, v in assignment.items()) + "]"
        for w in caught:
            if w in ours:
                warnings.warn(f"{w.message}{where}", w.category, stacklevel=2)
            else:
                warnings.showwarning(w.message, w.category, w.filename, w.lineno)
    flags = f"; {flagged} flagged: see the warnings" if flagged else ""
    return f"{path}: valid ({len(points)} pipeline(s){flags})"


def _cmd_check(args) -> int:
    verdict = check_file(args.config)
    if not args.quiet:
        print(verdict)
    return 0


def _cmd_plugins(args) -> int:
    from xnlos_core.registry import get_registry

    comps = [c for c in get_registry().components() if not args.kind or c.kind in args.kind]
    rows = [{"kind": c.kind, "name": c.name, "provider": c.provider, "description": c.description,
             "parameters": c.parameters()} for c in comps]
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
        return 0
    for r in rows:
        print(f"{r['kind']:<16} {r['name']:<18} {r['provider']:<24} {r['description']}")
        for pname, info in r["parameters"].items():
            extra = ", ".join(f"{k} {v}" for k, v in info.items() if k in ("gt", "ge", "lt", "le"))
            print(f"{'':<18}- {pname} = {info['default']!r}" + (f"  ({extra})" if extra else "")
                  + (f"  {info['description']}" if info.get("description") else ""))
    return 0


def build_parser(manager=None) -> argparse.ArgumentParser:
    """The ``xnlos`` parser: the application's commands here, every other one added by the package
    that owns it through the ``xnlos_add_commands`` hook of ``manager`` (default: the process-wide
    :func:`~xnlos_core.registry.get_manager`)."""
    if manager is None:
        from xnlos_core.registry import get_manager

        manager = get_manager()
    p = argparse.ArgumentParser(prog="xnlos", description="X-band radar NLOS imaging: simulate, detect, "
                                "estimate relay walls and reconstruct hidden objects.")
    p.add_argument("--version", action="version", version=f"xnlos {__version__}")
    p.add_argument("-p", "--plugin", action="append", default=[], metavar="MODULE",
                   help="import and register an extra plugin module (repeatable; your own act: a config "
                        "file can name only installed entry points, in [plugins] load)")
    p.add_argument("--root", action="append", default=[], metavar="DIR",
                   help="a further folder config files may name files in (repeatable; also "
                        f"{ROOTS_ENV}, or [paths] roots in the project's xnlos.toml)")
    sub = p.add_subparsers(dest="command", required=True, metavar="COMMAND")

    r = sub.add_parser("run", help="run a pipeline config, writing results.jsonl, summary.md and a PNG")
    r.add_argument("config", type=Path)
    r.add_argument("--out", required=True, type=Path)
    r.add_argument("--frames", type=positive_int, help="override run.frames (≥ 1; more than a finished run "
                   "holds extends it)")
    r.add_argument("--overwrite", action="store_true", help="discard results of another config in --out")
    r.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)
    r.set_defaults(func=_cmd_run)

    d = sub.add_parser("demo", help="run the built-in corner scene (a wall and a hidden car)")
    d.add_argument("--out", default=Path("demo-out"), type=Path)
    d.add_argument("--overwrite", action="store_true")
    d.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)
    d.set_defaults(func=_cmd_demo)

    s = sub.add_parser("sweep", help="run every point of a config's [sweep] grid and tabulate the results")
    s.add_argument("config", type=Path)
    s.add_argument("--out", required=True, type=Path)
    s.add_argument("--scheduler", help="Dask scheduler address (e.g. tcp://127.0.0.1:8786); default: local")
    s.add_argument("--workers", type=int, default=None, help="local worker processes (1 = in process)")
    s.add_argument("--overwrite", action="store_true", help="run every point again, discarding the results in --out")
    s.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)
    s.set_defaults(func=_cmd_sweep)

    ev = sub.add_parser("eval", help="score a pipeline config (or each point of its sweep) on a dataset split: "
                        "F1 / Chamfer per class and family, stage times, Fig. 6-style figures (resumable)")
    ev.add_argument("config", type=Path, help="pipeline TOML, e.g. configs/ablations/table2.toml")
    ev.add_argument("--out", type=Path, help="output directory (default: out/eval/<config file stem>; rerun the "
                    "same command to resume)")
    ev.add_argument("--dataset", help="dataset directory, relative to the working directory (default: the "
                    "config's dataset backend, else out/data/default)")
    ev.add_argument("--split", choices=["train", "val", "test", "all"], help="split to score (default: the "
                    "config's, else test)")
    ev.add_argument("--limit", type=int, help="score at most this many maps of the split")
    ev.add_argument("--start", type=int, help="skip this many maps of the split first")
    ev.add_argument("--figures", type=int, default=2, help="Fig. 6-style PNGs of the first N maps per run (default 2)")
    ev.add_argument("--no-figures", action="store_true", help="write no figures")
    ev.add_argument("--overwrite", action="store_true", help="discard an evaluation of another config in --out")
    ev.add_argument("-q", "--quiet", action="store_true", help=QUIET_HELP)
    ev.set_defaults(func=_cmd_eval)

    c = sub.add_parser("check", help="validate a config (and every sweep point) without running it")
    c.add_argument("config", type=Path)
    c.add_argument("-q", "--quiet", action="store_true", help="no verdict line; only errors and warnings (exit "
                   "status 0: valid)")
    c.set_defaults(func=_cmd_check)

    pl = sub.add_parser("plugins", help="list registered plugins: kind, name, distribution, parameters")
    pl.add_argument("--json", action="store_true")
    pl.add_argument("--kind", action="append", choices=KINDS, metavar="KIND",
                    help=f"only plugins of this kind (repeatable): {', '.join(KINDS)}")
    pl.set_defaults(func=_cmd_plugins)

    from xnlos_core.app.new_plugin import add_command as add_new_plugin

    add_new_plugin(sub)

    from xnlos_core.app.crossmodal.study import add_command as add_crossmodal

    add_crossmodal(sub)
    try:  # simulate, train, emulate, …: added by the packages that own them
        manager.pm.hook.xnlos_add_commands(subparsers=sub)
    except argparse.ArgumentError as exc:
        raise PluginError(f"a plugin's xnlos_add_commands hook failed: {exc} (plugins: "
                          f"{', '.join(sorted(n for n, _ in manager.pm.list_name_plugin()))})") from exc
    return p


# what an interrupted command keeps (its resume unit), by command
INTERRUPTED = {"run": "completed frames are saved", "demo": "completed frames are saved",
               "eval": "scored maps are saved", "sweep": "finished points and frames are saved",
               "train": "finished epochs are saved (last.pt)", "simulate": "finished shards are saved",
               "crossmodal": "finished cells are saved"}


def argv_command(argv: list[str] | None) -> str | None:
    """The command word of ``argv`` (default sys.argv[1:]): the first argument naming one of
    :data:`INTERRUPTED`'s commands, or None."""
    return next((a for a in (sys.argv[1:] if argv is None else argv) if a in INTERRUPTED), None)


def positive_int(text: str) -> int:
    """argparse type: an integer ≥ 1 (a count of frames, epochs, maps)."""
    try:
        n = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected a whole number ≥ 1, got {text!r}") from None
    if n < 1:
        raise argparse.ArgumentTypeError(f"expected a whole number ≥ 1, got {n}")
    return n


def _early_options(argv: list[str] | None) -> argparse.Namespace:
    """The ``-p MODULE`` and ``--root DIR`` options, read before the full parser exists (the plugins'
    commands join it; the roots hold for every config read)."""
    pre = argparse.ArgumentParser(add_help=False)
    pre.add_argument("-p", "--plugin", action="append", default=[])
    pre.add_argument("--root", action="append", default=[])
    return pre.parse_known_args(argv)[0]


def _add_roots(roots: list[str]) -> None:
    """Put ``--root`` folders in front of :data:`~xnlos_core.files.ROOTS_ENV` (so worker processes see
    them too); a folder that does not exist is an error now rather than a puzzling refusal later."""
    for r in roots:
        if not Path(r).expanduser().is_dir():
            raise ConfigError(f"--root {r}: not an existing folder")
    if roots:
        old = os.environ.get(ROOTS_ENV, "")
        os.environ[ROOTS_ENV] = os.pathsep.join([*map(str, roots), *([old] if old else [])])


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """xnlos's own warnings as ``xnlos: warning: …`` (no source line: the message names the input);
    any other as Python prints it."""
    out = sys.stderr if file is None else file
    if issubclass(category, XnlosWarning):
        out.write(f"xnlos: warning: {message}\n")
    else:
        out.write(warnings.formatwarning(message, category, filename, lineno, line))


def main(argv: list[str] | None = None) -> int:
    try:
        from xnlos_core.registry import get_manager

        manager = get_manager()
        early = _early_options(argv)
        _add_roots(early.root)
        for mod in early.plugin:
            manager.load_module(mod)
        args = build_parser(manager).parse_args(argv)
        with warnings.catch_warnings():
            warnings.showwarning = _show_warning
            if getattr(args, "quiet", False):  # other libraries' warnings off; xnlos's own stay
                warnings.simplefilter("ignore")
                warnings.filterwarnings("default", module=OWN_MODULES)
                warnings.simplefilter("default", XnlosWarning)
            return args.func(args)
    except XnlosError as exc:
        print(f"xnlos: error: {exc}", file=sys.stderr)
        return 2
    except OSError as exc:  # an output folder or file that cannot be written (--out on a read-only place, …)
        where = exc.filename if exc.filename is not None else "a file"
        reason = ("a file is in the way (expected a folder to write into, or a path where one can be made)"
                  if isinstance(exc, (FileExistsError, NotADirectoryError)) else os_reason(exc))
        print(f"xnlos: error: cannot use {where}: {reason}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        done = INTERRUPTED.get(argv_command(argv), "completed work is saved")
        print(f"xnlos: interrupted; {done}, rerun the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
