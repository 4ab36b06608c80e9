"""The command line the tracking benchmarks share (forecast_bound, ghost_tracks, wall_history,
centroid_offset): which case of which ablation config to run on which dataset split."""
from __future__ import annotations

import argparse

CASES = {4: "sindy + Doppler behind nlos_cfar", 6: "oracle → sindy + Doppler", 8: "swin_unet → sindy + Doppler"}


def case_parser(doc: str, case: int, split: str) -> argparse.ArgumentParser:
    """An ArgumentParser with --config, --case (default ``case``), --dataset and --split (default ``split``)."""
    ap = argparse.ArgumentParser(description=doc.strip().split("\n\n")[0])
    ap.add_argument("--config", default="configs/ablations/tracking.toml")
    ap.add_argument("--case", type=int, default=case,
                    help=f"index of the sweep case ({case}: {CASES.get(case, 'see the config')})")
    ap.add_argument("--dataset", default="out/data/sequences_large64")
    ap.add_argument("--split", default=split)
    return ap


def family_sequences(pipe, family: str):
    """The sequences (each a list of frames, in order) of one scene family from the pipeline's frame
    source, the pipeline reset before each (the tracks and a wall estimator's history); the source is
    opened here and closed when the iteration ends."""
    from xnlos_core.app.sequence_eval import sequences

    backend = pipe.stages["backend"]
    backend.open(pipe.radar)
    try:
        for _, group in sequences(f for f in backend.frames() if f.meta.get("family") == family):
            pipe.reset()
            yield [f for _, f in group]
    finally:
        backend.close()
