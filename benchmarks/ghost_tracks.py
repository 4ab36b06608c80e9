"""Where a tracker's hidden-car tracks lie: confirmed track frames by distance to the nearest car and
by track speed (not a test).

Runs one case of ``configs/ablations/tracking.toml`` on the ``hidden_car_approach`` sequences of a
dataset split (``Pipeline.reset()`` at each sequence) and counts every reported track in every frame by
its distance to the nearest road user of the frame's object truth — within 2 m (the match radius), 2–4 m
(the visible side of a 4.5 m car), 4–10 m and beyond 10 m: mNLOS points mirrored through a wall that is
not their relay wall — and by its speed (< 1, 1–4, ≥ 4 m/s). ``--history`` overrides ``lsq``'s
``history_frames`` (the walls' frames), to compare one frame against several on the same sequences.

    python benchmarks/ghost_tracks.py [--dataset out/data/sequences_large64] [--split val] [--case 4] [--history 1]
"""
from __future__ import annotations

import time
from collections import Counter

import numpy as np

from tracking_case import case_parser, family_sequences

FAMILY = "hidden_car_approach"
DISTANCES = ((2.0, "< 2 m"), (4.0, "2–4 m"), (10.0, "4–10 m"), (np.inf, "≥ 10 m"))
SPEEDS = ((1.0, "< 1 m/s"), (4.0, "1–4 m/s"), (np.inf, "≥ 4 m/s"))


def _bin(value: float, edges) -> str:
    return next(name for edge, name in edges if value < edge)


def count(config: str, case: int, dataset: str, split: str, history: int | None) -> tuple[str, int, Counter]:
    """(case name, lsq's history_frames, Counter {(distance bin, speed bin): track frames})."""
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline

    r = plan_runs(config, dataset=dataset, split=split)[case]
    cfg = r["config"]
    if history is not None:
        cfg.wall_estimator.params["history_frames"] = history
    pipe = Pipeline(cfg, source=r["source"])
    frames = pipe.stages["wall_estimator"].get_params().get("history_frames", 1)
    out: Counter = Counter()
    for seq in family_sequences(pipe, FAMILY):
        for frame in seq:
            tracks = pipe.process(frame).tracks
            cars = np.asarray(frame.meta["object_truth"]["position"], dtype=np.float64).reshape(-1, 2)
            for p, v in zip(tracks.position, tracks.velocity):
                d = float(np.min(np.linalg.norm(cars - p, axis=1))) if len(cars) else np.inf
                out[_bin(d, DISTANCES), _bin(float(np.linalg.norm(v)), SPEEDS)] += 1
    return r["name"], frames, out


def main() -> None:
    ap = case_parser(__doc__, case=4, split="val")
    ap.add_argument("--history", type=int, default=None, help="lsq history_frames (default: the config's)")
    a = ap.parse_args()
    t0 = time.perf_counter()
    name, frames, c = count(a.config, a.case, a.dataset, a.split, a.history)
    print(f"{name}, {a.split} split, walls from {frames} frame(s): track frames of hidden-car "
          f"sequences by distance to the nearest car ({time.perf_counter() - t0:.0f} s)\n")
    print("| distance | " + " | ".join(s for _, s in SPEEDS) + " | all |")
    print("|---" * (len(SPEEDS) + 2) + "|")
    for _, d in DISTANCES:
        row = [c[d, s] for _, s in SPEEDS]
        print(f"| {d} | " + " | ".join(map(str, row)) + f" | {sum(row)} |")


if __name__ == "__main__":
    main()
