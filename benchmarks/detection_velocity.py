"""Which cell a detection's radial velocity should be read at: the nearest cell to the detector's
peak, or the strongest cell (|κ|²) within ±1 or ±2 cells of it, or the cell of smallest stated σ within ±1
(:mod:`plugins.detectors.detection_doppler`).

Runs the detector of one case of ``configs/ablations/tracking.toml`` (default 8: the Swin-UNet fine-tuned on
the 64-chirp sequences) with ``velocity_radius`` 0 on the first ``--sequences`` ``hidden_car_approach``
sequences of a dataset split, and keeps each mNLOS detection within 1 m of the mirror image of a road user
moving ≥ 0.5 m/s. Its error is the velocity read at each choice of cell minus the image's true radial velocity
r̂'ᵀv' [m/s]. Reported: detections, RMSE, the share of errors above 1 m/s (gross: another return's
Doppler bin) and the RMSE without them.

Writes benchmarks/detection_velocity.md.

    python benchmarks/detection_velocity.py [--case 8] [--split val] [--sequences 6]
"""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from tracking_case import case_parser, family_sequences

CHOICES = ("nearest cell", "strongest within ±1", "strongest within ±2", "smallest σ within ±1")


def errors(case: int, config: str, dataset: str, split: str, n_seq: int) -> tuple[str, dict[str, np.ndarray]]:
    """(case name, {choice: errors (K,) [m/s]}) over the kept detections (module docstring)."""
    from plugins.detectors.detection_doppler import nearest_cells, strongest_cells
    from xnlos_core.app.evaluation import plan_runs
    from xnlos_core.pipeline import Pipeline
    from xnlos_core.types import MNLOS

    r = plan_runs(config, dataset=dataset, split=split)[case]
    cfg = r["config"].model_copy(deep=True)
    cfg.detector.params = {**dict(cfg.detector.params), "velocity_radius": 0}
    pipe = Pipeline(cfg, source=r["source"])
    detector = pipe.stages["detector"]
    out = {c: [] for c in CHOICES}
    for si, frames in enumerate(family_sequences(pipe, "hidden_car_approach")):
        if si >= n_seq:
            break
        for f in frames:
            gt, ra = f.ground_truth, f.ra_map
            if ra.velocity is None or gt is None or gt.mnlos_velocity is None or not len(gt.mnlos_points):
                continue
            det = detector.detect(f)
            moving = np.linalg.norm(gt.mnlos_velocity, axis=1) >= 0.5
            for i in np.flatnonzero(det.label == MNLOS):
                d = np.linalg.norm(gt.mnlos_points - det.position[i], axis=1)
                j = int(np.argmin(d))
                if d[j] > 1.0 or not moving[j]:
                    continue
                truth = float(gt.mnlos_points[j] @ gt.mnlos_velocity[j]) / float(np.linalg.norm(gt.mnlos_points[j]))
                fr = np.interp(det.range[i], ra.range_axis, np.arange(ra.shape[0]))
                fc = np.interp(det.azimuth[i], ra.azimuth_axis, np.arange(ra.shape[1]))
                rr, cc = nearest_cells([fr], [fc], ra.shape)
                cells = {CHOICES[0]: (rr, cc), CHOICES[1]: strongest_cells(ra, rr, cc, 1),
                         CHOICES[2]: strongest_cells(ra, rr, cc, 2), CHOICES[3]: _smallest_sigma(ra, rr, cc)}
                for name, (a, b) in cells.items():
                    out[name].append(float(ra.velocity[a[0], b[0]]) - truth)
    return r["name"], {k: np.array(v) for k, v in out.items()}


def _smallest_sigma(ra, rr, cc):
    """The cell of smallest velocity σ within ±1 cell of (rr, cc) (1,)."""
    h, w = ra.shape
    r0, c0 = int(rr[0]), int(cc[0])
    block = ra.velocity_std[max(r0 - 1, 0):min(r0 + 2, h), max(c0 - 1, 0):min(c0 + 2, w)]
    a, b = np.unravel_index(int(np.argmin(block)), block.shape)
    return np.array([max(r0 - 1, 0) + a]), np.array([max(c0 - 1, 0) + b])


def main() -> None:
    ap = case_parser(__doc__, 8, "val")
    ap.add_argument("--sequences", type=int, default=6)
    args = ap.parse_args()
    t0 = time.perf_counter()
    name, errs = errors(args.case, args.config, args.dataset, args.split, args.sequences)
    wall = time.perf_counter() - t0
    lines = [f"# The cell a detection's radial velocity is read at ({args.split} split of "
             f"{Path(args.dataset).name})", "",
             f"Behind {name}: mNLOS detections within 1 m of the mirror image of a moving road user, in the "
             f"first {args.sequences} hidden-car sequences. Error: the velocity read at the cell minus the "
             "image's true radial velocity.", "",
             "| cell | detections | RMSE [m/s] | errors > 1 m/s | RMSE without them [m/s] |", "|---|---|---|---|---|"]
    for choice, e in errs.items():
        gross = np.abs(e) > 1.0
        rm = float(np.sqrt(np.mean(e ** 2))) if len(e) else float("nan")
        rin = float(np.sqrt(np.mean(e[~gross] ** 2))) if (~gross).any() else float("nan")
        lines.append(f"| {choice} | {len(e)} | {rm:.2f} | {100 * gross.mean() if len(e) else 0:.1f} % | {rin:.2f} |")
    lines += ["", f"`python benchmarks/detection_velocity.py --case {args.case} --split {args.split} "
              f"--sequences {args.sequences}` ({wall:.0f} s)", ""]
    Path(__file__).with_name("detection_velocity.md").write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
