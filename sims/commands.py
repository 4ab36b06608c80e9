"""``xnlos simulate`` and ``xnlos check`` of a dataset config, added through the command hooks."""
from __future__ import annotations

import argparse
from pathlib import Path

from xnlos_core import hookimpl
from xnlos_core.errors import ConfigError


@hookimpl
def xnlos_add_commands(subparsers) -> None:
    """``xnlos simulate``: generate a sharded RA-map dataset (resumable), or verify / repair one."""
    sim = subparsers.add_parser("simulate", help="generate a sharded RA-map dataset (resumable), or --verify / "
                                "--repair one")
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
    sim.add_argument("--max-maps", type=int, help="override the config's n_maps: fewer give the full dataset's "
                     "first maps, with its scenes and splits (no training or validation scene of the full dataset "
                     "lands in test; split sizes are the prefix's); more give a larger dataset with its own split")
    sim.add_argument("-q", "--quiet", action="store_true", help="no progress bar")
    sim.set_defaults(func=cmd_simulate)


def cmd_simulate(args: argparse.Namespace) -> int:
    from .dataset import load_dataset_config, manifest_config, simulate_dataset, verify_dataset

    config, out = args.config, args.out
    if out is None and (args.verify or args.repair) and config is not None:
        if not config.is_dir():
            what = "does not exist" if not config.exists() else "is a file, not a dataset folder"
            raise ConfigError(f"simulate --{'verify' if args.verify else 'repair'} {config}: {what}; expected the "
                              "folder of a dataset that xnlos simulate wrote (it holds manifest.json)")
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
    if cfg.full_n_maps is not None:
        sizes = ", ".join(f"{k} {v}" for k, v in s["splits"].items())
        print(f"{cfg.n_maps} of the full dataset's {cfg.full_n_maps} maps: the first scenes of each of its "
              f"splits, split as there ({sizes})")
    return 0


@hookimpl
def xnlos_check_config(table: dict, path: Path) -> str | None:
    """``xnlos check`` of a dataset config (one with ``families``); None for any other config."""
    if "families" not in table:
        return None
    from .dataset import parse_dataset_config, resolve

    cfg = resolve(parse_dataset_config(table, str(path), path.resolve().parent), str(path))
    return f"{path}: valid dataset config ({cfg.n_maps} maps, forward model {cfg.forward_model.name})"
