"""``xnlos train`` and ``xnlos check`` of a training config, for every learned component (the
trainer is chosen by the config's ``[model] name``, :mod:`.trainers`). Added through the command
hooks by ``plugins/detectors/plugin.py``."""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

from xnlos_core import hookimpl


@hookimpl
def xnlos_add_commands(subparsers) -> None:
    """``xnlos train``: train a learned detector or the residual mirror; rerun to resume or extend."""
    tr = subparsers.add_parser("train", help="train a learned detector (swin_unet, unet, further_than_cfar, rtn) or "
                               "the residual mirror; rerun the same command to resume, with a larger --epochs "
                               "to extend a finished run")
    tr.add_argument("config", type=Path, help="training TOML (configs/training/)")
    tr.add_argument("--out", type=Path, help="override the config's output directory")
    tr.add_argument("--device", help="override the config's device (auto, cpu, cuda[:N], mps; detectors)")
    tr.add_argument("--epochs", type=int, help="override optim.epochs (more than a finished run has: extend it)")
    tr.add_argument("--export", type=Path, help="also write the final model here, replacing the config's export; "
                    "the only way to write into the installed package (a shipped model)")
    tr.add_argument("--overwrite", action="store_true", help="discard a previous run in the output directory")
    tr.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    tr.set_defaults(func=cmd_train)


def cmd_train(args: argparse.Namespace) -> int:
    from xnlos_core.config import load_toml

    from .trainers import trainer_for

    table = load_toml(args.config)
    trainer = trainer_for(table, str(args.config))
    cfg = trainer.parse(table, str(args.config))
    # paths in the config are taken from its folder; paths on the command line from the working directory
    base_dir = args.config.parent
    cli_paths = {k: v.resolve() for k, v in (("out", args.out), ("export", args.export)) if v is not None}
    overrides = {k: str(v) for k, v in (*cli_paths.items(), ("device", args.device))
                 if v is not None and k in type(cfg).model_fields}  # the residual mirror has no device: CPU
    if overrides or args.epochs is not None:
        table = {**cfg.model_dump(mode="json"), **overrides}
        if args.epochs is not None:
            table["optim"]["epochs"] = args.epochs
        cfg = trainer.parse(table, f"{args.config} (with command-line overrides)")
    s = trainer.train(cfg, overwrite=args.overwrite, progress=not args.quiet, source=str(args.config),
                      named_export=args.export is not None, base_dir=base_dir)
    if s.get("resumed_from_epoch") is not None:
        print(f"resumed after epoch {s['resumed_from_epoch']}")
    if s.get("stop_reason"):
        print(s["stop_reason"])
    print(f"{trainer.report(s)}; wrote {s['model']}" + (f" and {s['export']}" if s.get("export") else ""))
    if s.get("export_skipped"):
        print(f"note: {s['export_skipped']}", file=sys.stderr)
    return 0


@hookimpl
def xnlos_check_config(table: dict, path: Path) -> str | None:
    """``xnlos check`` of a training config (``[data]`` and ``[model]``); None for any other config."""
    if not ("data" in table and "model" in table):
        return None
    from .trainers import trainer_for

    trainer = trainer_for(table, str(path))
    cfg = trainer.parse(table, str(path))
    if trainer.check is not None:
        trainer.check(cfg, str(path), Path(path).parent)
    return f"{path}: valid training config (model {cfg.model.name}, {cfg.optim.epochs} epochs)"
