"""The command line the tracking benchmarks share (forecast_bound, ghost_tracks, wall_history,
centroid_offset): which case of which ablation config to run on which dataset split."""
from __future__ import annotations

import argparse

CASES = {4: "sindy + Doppler behind nlos_cfar", 6: "oracle → sindy + Doppler"}


def case_parser(doc: str, case: int, split: str) -> argparse.ArgumentParser:
    """An ArgumentParser with --config, --case (default ``case``), --dataset and --split (default ``split``)."""
    ap = argparse.ArgumentParser(description=doc.strip().split("\n\n")[0])
    ap.add_argument("--config", default="configs/ablations/tracking.toml")
    ap.add_argument("--case", type=int, default=case,
                    help=f"index of the sweep case ({case}: {CASES.get(case, 'see the config')})")
    ap.add_argument("--dataset", default="out/data/sequences_large")
    ap.add_argument("--split", default=split)
    return ap
