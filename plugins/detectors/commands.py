"""``xnlos train`` and ``xnlos check`` of a training config, added through the command hooks.

The trainer is chosen by the config's ``[model] name``: ``residual_mirror`` trains the Eq. 9
residual, every other name a learned detector.
"""
from __future__ import annotations

import argparse
from pathlib import Path


def add_commands(subparsers) -> None:
    """``xnlos train``: train a learned detector or the residual mirror; rerun to resume."""
    tr = subparsers.add_parser("train", help="train a learned detector (swin_unet, unet, further_than_cfar, rtn) or "
                               "the residual mirror; rerun the same command to resume")
    tr.add_argument("config", type=Path, help="training TOML (configs/training/)")
    tr.add_argument("--out", type=Path, help="override the config's output directory")
    tr.add_argument("--device", help="override the config's device (auto, cpu, cuda[:N], mps)")
    tr.add_argument("--epochs", type=int, help="override optim.epochs")
    tr.add_argument("--overwrite", action="store_true", help="discard a previous run in the output directory")
    tr.add_argument("-q", "--quiet", action="store_true", help="no progress bars")
    tr.set_defaults(func=cmd_train)


def cmd_train(args: argparse.Namespace) -> int:
    from plugins.residual_mirror.train import cli_train, is_residual_config
    from xnlos_core.config import load_toml

    if is_residual_config(load_toml(args.config)):  # [model] name = "residual_mirror": the Eq. 9 trainer
        return cli_train(args)
    from .train import train
    from .train_config import load_train_config, parse_train_config

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


def check_config(table: dict, path: Path) -> str | None:
    """``xnlos check`` of a training config (``[data]`` and ``[model]``); None for any other config."""
    if not ("data" in table and "model" in table):
        return None
    from plugins.residual_mirror.train import check_config as check_residual, is_residual_config

    if is_residual_config(table):
        return check_residual(table, path)
    from .train_config import parse_train_config

    tcfg = parse_train_config(table, str(path))
    if tcfg.data.generate is not None:
        _check_generate(tcfg.data.generate, f"{path}: [data.generate]")
    return f"{path}: valid training config (model {tcfg.model.name}, {tcfg.optim.epochs} epochs)"


def _check_generate(gen, source: str) -> None:
    """What ``xnlos train`` builds from ``[data.generate]`` before simulating (relative paths from the
    working directory, as the trainer takes them)."""
    from xnlos_core.radar import load_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    radar = load_radar(gen.radar, source, ".")
    fm = get_registry().create("forward_model", gen.forward_model.name, gen.forward_model.params, source=source)
    if gen.scene is not None:
        fm.check(load_scene(gen.scene, source, "."), radar)
