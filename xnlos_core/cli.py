"""Command line: ``xnlos run | sweep | eval | demo | plugins | check | emulate | simulate | train`` (also ``python -m xnlos_core``)."""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from . import __version__
from .errors import ConfigError, XnlosError

DEMO_CONFIG = Path(__file__).with_name("defaults") / "demo.toml"


def _cmd_run(args) -> int:
    from .config import load_pipeline
    from .runner import run_to_dir

    cfg = load_pipeline(args.config)
    if args.frames is not None:
        cfg = cfg.model_copy(update={"run": cfg.run.model_copy(update={"frames": args.frames})})
    summary = run_to_dir(cfg, args.out, source=str(args.config), progress=not args.quiet, overwrite=args.overwrite)
    _report(summary, Path(args.out))
    return 0


def _report(summary: dict, out: Path) -> None:
    errs = {k.rsplit(".", 1)[-1]: v for k, v in summary["metrics"].items() if ".object_error_m." in k}
    for name, v in errs.items():
        print(f"hidden {name}: reconstruction error " + ("n/a (not reconstructed)" if v is None else f"{v:.2f} m"))
    proc = sum(v for k, v in summary["time_ms"].items() if k != "source")
    print(f"{summary['frames']} frame(s), {proc:.1f} ms/frame processing; wrote {out / 'summary.md'}"
          + (f" and {out / summary['figure']}" if summary.get("figure") else ""))


def _cmd_demo(args) -> int:
    args.config, args.frames = DEMO_CONFIG, None
    return _cmd_run(args)


def _cmd_sweep(args) -> int:
    from .sweep import run_sweep

    records = run_sweep(args.config, args.out, scheduler=args.scheduler, workers=args.workers, progress=not args.quiet,
                        overwrite=args.overwrite)
    print((Path(args.out) / "sweep.md").read_text())
    print(f"{len(records)} point(s); wrote {Path(args.out) / 'sweep.md'}")
    return 0


def _cmd_eval(args) -> int:
    from .evaluation import run_eval

    args.out = args.out or Path("out/eval") / args.config.stem
    res = run_eval(args.config, args.out, dataset=args.dataset, split=args.split, limit=args.limit,
                   start=args.start, figures=0 if args.no_figures else args.figures, progress=not args.quiet,
                   overwrite=args.overwrite)
    out = args.out
    print((out / "eval.md").read_text())
    print(f"{len(res['runs'])} run(s) on {sum(r['overall']['maps'] for r in res['runs'])} map(s); wrote "
          f"{out / 'eval.md'} and {out / 'eval.json'}")
    return 0


def _cmd_simulate(args) -> int:
    from sims.dataset import load_dataset_config, manifest_config, simulate_dataset, verify_dataset

    config, out = args.config, args.out
    if out is None and (args.verify or args.repair) and config is not None and config.is_dir():
        config, out = None, config  # xnlos simulate --verify DIR | --repair DIR
    if out is None:
        raise ConfigError("simulate: give --out DIR (or: xnlos simulate --verify DIR | --repair DIR)")
    if args.verify and not args.repair:
        report = verify_dataset(out)
        print(report.render())
        return 0 if report.healthy else 1
    if config is None and args.max_maps is not None:
        raise ConfigError("simulate: --max-maps needs the CONFIG file (the dataset in --out keeps its own size)")
    cfg = (manifest_config(out, repair=args.repair) if config is None
           else load_dataset_config(config, n_maps=args.max_maps))
    s = simulate_dataset(cfg, out, source=str(config or out / "manifest.json"), workers=args.workers,
                         scheduler=args.scheduler, overwrite=args.overwrite, repair=args.repair,
                         progress=not args.quiet)
    print(f"{s['n_maps']} map(s) in {s['n_shards']} shard(s): {s['generated']} generated, {s['skipped']} already "
          f"done, {len(s['repaired'])} repaired, in {s['seconds']:.1f} s; wrote {out / 'manifest.json'}")
    return 0


def _cmd_train(args) -> int:
    from plugins.residual_mirror.train import cli_train, is_residual_config

    from .config import load_toml

    if is_residual_config(load_toml(args.config)):  # [model] name = "residual_mirror": the Eq. 9 trainer
        return cli_train(args)
    from plugins.detectors.train import train
    from plugins.detectors.train_config import load_train_config, parse_train_config

    cfg = load_train_config(args.config)
    table = cfg.model_dump(mode="json")
    table.update({k: str(v) for k, v in (("out", args.out), ("device", args.device)) if v is not None})
    if args.epochs is not None:
        table["optim"]["epochs"] = args.epochs
    cfg = parse_train_config(table, f"{args.config} (with command-line overrides)")
    s = train(cfg, overwrite=args.overwrite, progress=not args.quiet, source=str(args.config))
    v = s["val"]
    print(f"{s['epochs_run']} epoch(s) on {s['device']} ({s['seconds_per_epoch']:.1f} s/epoch), best epoch "
          f"{s['best_epoch']}: validation Macro-F1 {v['macro_f1']:.3f} (LOS {v['los_f1']:.3f}, mNLOS "
          f"{v['mnlos_f1']:.3f}) at threshold {v['threshold']}, window {v['window']}"
          f"{', one peak per resolution cell' if v.get('cells') else ''}; wrote {s['model']}"
          + (f" and {s['export']}" if s.get("export") else ""))
    return 0


def check_file(path: str | Path) -> str:
    """Validate a pipeline, dataset or training config without running it; returns the one-line verdict.

    Runs what ``run`` / ``simulate`` / ``train`` run before their first frame (for a pipeline: every
    sweep point's :class:`~xnlos_core.pipeline.Pipeline`, which reads the files it names and lets
    the forward model check the scene). Every refusal is an :class:`~xnlos_core.errors.XnlosError`.
    """
    from .config import expand_sweep, load_toml, parse_pipeline
    from .pipeline import Pipeline

    path = Path(path)
    table = load_toml(path)
    if "families" in table and "detector" not in table:  # a dataset config (xnlos simulate)
        from sims.dataset import parse_dataset_config, resolve

        cfg = resolve(parse_dataset_config(table, str(path), path.resolve().parent), str(path))
        return f"{path}: valid dataset config ({cfg.n_maps} maps, forward model {cfg.forward_model.name})"
    if "data" in table and "model" in table and "detector" not in table:  # a training config (xnlos train)
        from plugins.residual_mirror.train import check_config, is_residual_config

        if is_residual_config(table):
            return check_config(table, path)
        from plugins.detectors.train_config import parse_train_config

        tcfg = parse_train_config(table, str(path))
        if tcfg.data.generate is not None:
            _check_generate(tcfg.data.generate, f"{path}: [data.generate]")
        return f"{path}: valid training config (model {tcfg.model.name}, {tcfg.optim.epochs} epochs)"
    points = expand_sweep(table, str(path))
    for assignment, t in points:
        Pipeline(parse_pipeline(t, str(path), path.resolve().parent), source=str(path))
    return f"{path}: valid ({len(points)} pipeline(s))"


def _check_generate(gen, source: str) -> None:
    """What ``xnlos train`` builds from ``[data.generate]`` before simulating (relative paths from the
    working directory, as the trainer takes them)."""
    from .pipeline import load_radar
    from .registry import get_registry
    from .scene import load_scene

    radar = load_radar(gen.radar, source, ".")
    fm = get_registry().create("forward_model", gen.forward_model.name, gen.forward_model.params, source=source)
    if gen.scene is not None:
        fm.check(load_scene(gen.scene, source, "."), radar)


def _cmd_check(args) -> int:
    print(check_file(args.config))
    return 0


def _cmd_plugins(args) -> int:
    from .registry import get_registry

    comps = get_registry().components()
    rows = [{"kind": c.kind, "name": c.name, "provider": c.provider, "description": c.description,
             "parameters": c.parameters()} for c in comps]
    if args.json:
        print(json.dumps(rows, indent=2, default=str))
        return 0
    for r in rows:
        print(f"{r['kind']:<16} {r['name']:<18} {r['provider']:<24} {r['description']}")
        for pname, info in r["parameters"].items():
            extra = ", ".join(f"{k} {v}" for k, v in info.items() if k in ("gt", "ge", "lt", "le"))
            print(f"{'':<18}- {pname} = {info['default']!r}" + (f"  ({extra})" if extra else ""))
    return 0


def _cmd_emulate(args) -> int:
    from hardware.emulator import run_emulate

    summary = run_emulate(interface=args.interface, channel=args.channel, sensor_id=args.sensor_id,
                          config=args.config, frames=args.frames, duration=args.duration, record=args.record,
                          client=args.client, payload=args.payload, pace=not args.fast, echo=print)
    print(f"{summary['frames_sent']} frame(s) sent in {summary['seconds']:.2f} s")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="xnlos", description="X-band radar NLOS imaging: simulate, detect, "
                                "estimate relay walls and reconstruct hidden objects.")
    p.add_argument("--version", action="version", version=f"xnlos {__version__}")
    p.add_argument("-p", "--plugin", action="append", default=[], metavar="MODULE",
                   help="import and register an extra plugin module (repeatable; your own act: a config "
                        "file can name only installed entry points, in [plugins] load)")
    sub = p.add_subparsers(dest="command", required=True)

    r = sub.add_parser("run", help="run a pipeline config, writing results.jsonl, summary.md and a PNG")
    r.add_argument("config", type=Path)
    r.add_argument("--out", required=True, type=Path)
    r.add_argument("--frames", type=int, help="override run.frames")
    r.add_argument("--overwrite", action="store_true", help="discard results of another config in --out")
    r.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    r.set_defaults(func=_cmd_run)

    d = sub.add_parser("demo", help="run the built-in corner scene (a wall and a hidden car)")
    d.add_argument("--out", default=Path("demo-out"), type=Path)
    d.add_argument("--overwrite", action="store_true")
    d.add_argument("-q", "--quiet", action="store_true")
    d.set_defaults(func=_cmd_demo)

    s = sub.add_parser("sweep", help="run every point of a config's [sweep] grid and tabulate the results")
    s.add_argument("config", type=Path)
    s.add_argument("--out", required=True, type=Path)
    s.add_argument("--scheduler", help="Dask scheduler address (e.g. tcp://127.0.0.1:8786); default: local")
    s.add_argument("--workers", type=int, default=None, help="local worker processes (1 = in process)")
    s.add_argument("--overwrite", action="store_true", help="run every point again, discarding the results in --out")
    s.add_argument("-q", "--quiet", action="store_true")
    s.set_defaults(func=_cmd_sweep)

    ev = sub.add_parser("eval", help="score a pipeline config (or each point of its sweep) on a dataset split: "
                        "F1 / Chamfer per class and family, stage times, Fig. 6-style figures (resumable)")
    ev.add_argument("config", type=Path, help="pipeline TOML, e.g. configs/ablations/table2.toml")
    ev.add_argument("--out", type=Path, help="output directory (default: out/eval/<config file stem>; rerun the "
                    "same command to resume)")
    ev.add_argument("--dataset", help="dataset directory (default: the config's dataset backend, else "
                    "out/data/default)")
    ev.add_argument("--split", choices=["train", "val", "test", "all"], help="split to score (default: the "
                    "config's, else test)")
    ev.add_argument("--limit", type=int, help="score at most this many maps of the split")
    ev.add_argument("--start", type=int, help="skip this many maps of the split first")
    ev.add_argument("--figures", type=int, default=2, help="Fig. 6-style PNGs of the first N maps per run (default 2)")
    ev.add_argument("--no-figures", action="store_true", help="write no figures")
    ev.add_argument("--overwrite", action="store_true", help="discard an evaluation of another config in --out")
    ev.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    ev.set_defaults(func=_cmd_eval)

    c = sub.add_parser("check", help="validate a config (and every sweep point) without running it")
    c.add_argument("config", type=Path)
    c.set_defaults(func=_cmd_check)

    sim = sub.add_parser("simulate", help="generate a sharded RA-map dataset (resumable), or --verify / --repair one")
    sim.add_argument("config", type=Path, nargs="?", help="dataset TOML (configs/datasets/); with --verify or "
                     "--repair and no --out: the dataset directory")
    sim.add_argument("--out", type=Path, help="dataset directory (rerun the same command to resume)")
    sim.add_argument("--workers", type=int, default=None,
                     help="local worker processes (1 = in process; default: every core)")
    sim.add_argument("--scheduler", help="Dask scheduler address (e.g. tcp://127.0.0.1:8786); default: local")
    sim.add_argument("--overwrite", action="store_true", help="discard a dataset of another config in --out")
    sim.add_argument("--verify", action="store_true",
                     help="re-hash every shard and list corrupt or missing ones (exit status 1 if any)")
    sim.add_argument("--repair", action="store_true", help="rebuild corrupt or missing shards")
    sim.add_argument("--max-maps", type=int, help="override the config's n_maps (a smaller dataset with its own "
                     "split, not a prefix of the full one)")
    sim.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sim.set_defaults(func=_cmd_simulate)

    tr = sub.add_parser("train", help="train a learned detector (swin_unet, unet, further_than_cfar, rtn); "
                        "rerun the same command to resume")
    tr.add_argument("config", type=Path, help="training TOML (configs/training/)")
    tr.add_argument("--out", type=Path, help="override the config's output directory")
    tr.add_argument("--device", help="override the config's device (auto, cpu, cuda[:N], mps)")
    tr.add_argument("--epochs", type=int, help="override optim.epochs")
    tr.add_argument("--overwrite", action="store_true", help="discard a previous run in the output directory")
    tr.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    tr.set_defaults(func=_cmd_train)

    pl = sub.add_parser("plugins", help="list registered plugins: kind, name, distribution, parameters")
    pl.add_argument("--json", action="store_true")
    pl.set_defaults(func=_cmd_plugins)

    e = sub.add_parser("emulate", help="run a radar device emulator on a CAN bus (hardware in the loop)")
    e.add_argument("--interface", default="virtual", help="python-can interface (default: virtual)")
    e.add_argument("--channel", default="xnlos0", help="interface channel (default: xnlos0)")
    e.add_argument("--sensor-id", type=int, default=0, help="radar sensor id 0-7 (identifier offset 0x10*id)")
    e.add_argument("--config", type=Path, help="pipeline TOML giving radar, scene, forward model, seed, frame period")
    e.add_argument("--frames", type=int, help="frames to stream (client) or to serve before exiting")
    e.add_argument("--duration", type=float, help="serve this many seconds, then exit")
    e.add_argument("--record", type=Path, help="record the bus to a python-can log (.blf, .asc)")
    e.add_argument("--client", action=argparse.BooleanOptionalAction, default=None,
                   help="also run a 'can' backend in this process that requests the frames "
                        "(default: on for the virtual interface, which other processes cannot reach)")
    e.add_argument("--payload", default="ra_complex64", choices=["ra_complex64", "adc_int16", "adc_complex64"],
                   help="what the client asks the radar to send")
    e.add_argument("--fast", action="store_true",
                   help="send frames as fast as the link allows, not at the frame period")
    e.set_defaults(func=_cmd_emulate)
    return p


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    try:
        if args.plugin:
            from .registry import get_manager

            for mod in args.plugin:
                get_manager().load_module(mod)
        return args.func(args)
    except XnlosError as exc:
        print(f"xnlos: error: {exc}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("xnlos: interrupted; completed frames are saved, rerun the same command to resume", file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
