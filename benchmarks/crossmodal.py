"""The cross-modality study's page: `xnlos crossmodal` of the committed config, its tables and notes.

    python benchmarks/crossmodal.py [--figures] [--no-timing] [--config TOML] [--out benchmarks/crossmodal.md]

Runs the study (:func:`xnlos_core.app.crossmodal.study.run_study`, seed 2026 in
``configs/ablations/crossmodal.toml``) into a temporary directory, so every trial is computed afresh
(no saved trials of an earlier run are reused), and writes the page to ``--out``: the study's own
``crossmodal.md`` as ``xnlos crossmodal configs/ablations/crossmodal.toml --out out/crossmodal``
writes it (its tables marked ``ranges``, ``ratios``, ``ratio_notes``, ``f1_grid``), with one line
naming this page's command after the study's command line, then the notes below (figures, set-up,
reading). About 4–5 minutes on 2 cores. ``--figures``: also the study's figures beside the page,
``<page>_range_curve.png`` and ``<page>_panel.png`` (``--no-figures``, the default, writes none).
``--no-timing``: no wall time in the set-up (the tables are the same). ``--config``: another study
(e.g. ``configs/ablations/crossmodal_tiny.toml``, seconds); the notes then still describe the
committed study. The notes under "Reading it" quote the committed tables: when a rerun changes the
tables, revise them.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from xnlos_core.app.crossmodal.config import load_study  # noqa: E402
from xnlos_core.app.crossmodal.study import render_markdown, run_study  # noqa: E402

CONFIG = ROOT / "configs" / "ablations" / "crossmodal.toml"
SHOWN_OUT = "out/crossmodal"  # the --out the page's command line names
FIGURES = {"range_curve.png": "range_curve", "panel.png": "panel"}

FIGURE_NOTES = """\
## Figures

`crossmodal_range_curve.png`: F1 vs distance (solid reconstruction, dashed detection) and, below on
the same axis, each row's range to failure (seeds •, median ◆ with its 95 % bootstrap interval,
▶ / ◀ where seeds reached a bound of the sweep). `crossmodal_panel.png`: Fig. 5-style panel, car 1 m
behind the corner (scene, raw measurement, intensity / detections, reconstruction per modality).
Both are written by `python benchmarks/crossmodal.py --figures` (as the registry's command does)."""

SETUP = """\
* Scene (same for all modalities): sensor at the origin looking along +x; relay wall a 45° concrete
  facade (15, 10) → (35, −10) m, rms roughness σ_h = 1 mm; a building (front line y = −1 m, side
  x = 22 m) hides the street behind the corner; a car 4.5 × 1.8 × 1.5 m, heading along the street.
  **Distance behind the corner** d: from the building's front line (y = −1 m) to the car's nearest
  point, along the street (−y).
* Power: 1.6 mW for every modality (radar: 1.6 mW per TX, TDM-MIMO, one TX at a time; SPAD: laser
  average power).
* **Range to failure**: per row and seed, the distance is bisected between 0.5 and 150 m
  (geometric midpoints on a 1 mm grid, to hi/lo ≤ 1.03) until the trial's reconstruction fails;
  success = reconstruction F1 ≥ 0.5 for that trial (the existing score: a reconstructed point within
  1.5 m of the car). Row range: lower median over the 20 seeds, 95 % percentile bootstrap over
  resampled seeds (2000 resamples). A seed still in range at 150 m or already failing at 0.5 m is
  censored at that bound; a median or interval end on such a seed is reported as the bound and no
  ratio is formed from a bound.
* **Radar range axis from the configuration**: the presets crop the RA map at `max_range = 100` m,
  which would cap the measurable distance near 74 m (the car's mirror image across the facade lies
  ≈ 26 m farther than d). The study keeps the presets' bandwidth (0.25 m bins) and chirp and doubles
  `n_samples` 512 → 1024 until the unambiguous range N·c/2B = 255.8 m covers the car's image at the
  upper bound (180.5 m + gate), and sets `max_range` to that whole unambiguous range (no crop).
* SPAD: 850 nm, 1 MHz repetition, 10 ms per scan point, confocal 16 × 16 scan of a 2 × 2 m facade
  patch, 1024 bins × 0.5 ns (depth to 76 m), patches 0.15 m; per-scan-point median subtracted before
  LCT and f-k. **Patch placement** (`placement = "facing"`): the wall point facing the car head-on
  (foot of the perpendicular) lies 1.9 m (d = 0.5) to 22.8 m (d = 30) along the facade from its
  midpoint, but the sensor sees the facade only up to 1.68 m past the midpoint (the line over the
  building's corner (22, −1)), so the patch sits at the nearest scannable position, offset 0.68 m
  (was 0.40 m fixed), at every distance. **Collection** at the sensor's real view angle: 25.5 m away,
  cos θ_v = 0.69 from the wall normal (was taken as 1). **Ambient**: night 1e4 detections/s, daylight
  2e7 detections/s (sunlit facade at 850 nm, ≈ 0.9 W m⁻² nm⁻¹, 1 nm filter, albedo 0.8, 25 mm
  aperture, 1 cm spot at ≈ 25 m, efficiency 0.3): 100 background counts per bin and scan point
  (night: 0.05).
* **Depth bins**: bin k is centred at round trip t0 + kΔt in the forward model and in the solvers
  (the forward model used to put bin k's centre at (k + ½)Δt while LCT / f-k read it at kΔt: a
  half-bin, 3.7 cm, depth bias at 0.5 ns bins).
* 77 GHz radar: preset `automotive_77ghz` (the X-band preset with the carrier at 77 GHz: same
  element layout in wavelengths, same range grid, 1.6 mW); the diffuse three-bounce NLOS path off the
  rough facade is on (`auto` rule), off for X-band. Radars: image forward model, `nlos_cfar`
  (pfa 1e-5), `lsq` wall, `mirror` reconstructor. The Swin-UNet row of earlier versions is left out
  (it is trained on 100 m maps; the range axis here is 255.8 m)."""

READING = """\
## Reading it

* **X-band**: median range 65.8 m, 95 % interval [53.8, 73.5] m; 17 of 20 seeds fail between 51 and
  105 m (F1 on the grid 0.65 at 60 m, 0 at 100 m): the X-band range is now measured, not a bound.
  Success per seed is not monotone in distance: three seeds already fail at 0.5 m and one at 1.2 m
  although the grid's F1 is ≈ 0.8 from 1 to 30 m (a stationary double-bounce echo is classified mNLOS
  and mirrored into the building in many frames, and a trial with a spurious point but no hit fails).
  Bisection then reports the transition its bracket holds; the median is robust to such seeds.
* **SPAD (night)**: f-k's reconstruction F1 is 0.55 at 0.5 m and 0.62 at 1 m, 0 from 2 m on
  (≈ 0.9, 0.46 and 0.16 expected signal photons per scan point at 0.5, 1 and 2 m against 0.05
  background counts per bin); its per-seed bisection is therefore close to a coin flip at the lower bound (9 of 20
  seeds already fail at 0.5 m). Its median, 0.53 m, falls just on a bracketed seed, so it is a
  measurement, but a fragile one: the interval's lower end is the 0.5 m bound. LCT never
  reconstructs (photon noise amplified by its t⁴ compensation, as before). Detection (the gated
  photon excess) is reliable at ≤ 1 m (F1 ≈ 1) and gone at 2 m. The SPAD's range is capped by
  geometry as much as by photons: LCT and f-k reconstruct only laterally inside the 2 m aperture, the
  patch cannot move past the sensor's sight line, and the car moves along the street at 45° to the
  wall, so from about 2 m on the car lies beside the aperture.
* **SPAD (daylight)**: 100 background counts per bin and scan point against ≤ 0.9 signal photons per scan point:
  no detection, no reconstruction at any distance (range < 0.5 m in every seed).
* **77 GHz** (σ_h = 1 mm): fails at every distance in every seed (range < 0.5 m): the specular
  mirror path loses ≈ 45 dB to the rough facade on top of the extra free-space loss. No X-band /
  77 GHz ratio exists within this sweep; the report says the bound was reached.
* **Ratios**: X-band / SPAD f-k (night) = 123 with a 95 % interval from 60 to unbounded (in
  resamples where the SPAD's median falls on a censored seed the ratio has no upper end). Against LCT
  and against the daylight SPAD, and against 77 GHz, no ratio is printed: those ranges are below the
  sweep's lower bound. The paper reports ~10× (Fig. 5); the SPAD here is weaker than the paper's
  (1.6 mW, 10 ms per point, 2 m aperture in a corner whose facade the sensor sees only next to the
  corner). The earlier page's "X-band / SPAD ≥ 60" was the ratio of the sweep's two ends (60 m / 1 m),
  not a measurement."""


def shown_path(path: Path) -> str:
    """``path`` as the page prints it: relative to the repository root when inside it."""
    path = path.resolve()
    return str(path.relative_to(ROOT)) if path.is_relative_to(ROOT) else str(path)


def trial_count(cells: Path) -> int:
    """Trials the study computed: the entries of its ``cells/*.json`` (one per modality, seed, distance)."""
    return sum(len(json.loads(p.read_text())["trials"]) for p in cells.glob("*.json"))


def page(study_md: str, name: str, timing: str | None) -> str:
    """The page: the study's ``crossmodal.md`` (``study_md``) with this page's command after its
    command line, then the notes; ``timing`` (or None) closes the set-up's run line."""
    lines = study_md.rstrip("\n").split("\n")
    at = next(i for i, ln in enumerate(lines) if ln.startswith("Command: `xnlos crossmodal ")) + 1
    lines[at:at] = ["", f"Page: `python -m benchmarks.regenerate {name}` (`benchmarks/{name}.py`: the command above in "
                    f"a temporary directory, every trial afresh, then the notes below); "
                    f"`python -m benchmarks.regenerate --check {name}` compares the marked tables with such a rerun."]
    run = ("* Apart from the `Page:` line, the text above is the study's own `crossmodal.md`, byte for byte "
           "as the command at the top writes it: seed 2026, 20 seeds, the full study, not a reduced setting. "
           "The same config gives the same tables on every run (trials draw their noise from "
           "SeedSequence(seed, modality, seed index), the bootstrap from the config's seed); "
           f"`python -m benchmarks.regenerate --check {name}` (the slow test "
           f"`tests/unit/test_benchmark_pages.py::test_committed_tables_match_a_rerun[{name}]`) compares the "
           "committed tables with a rerun. `configs/ablations/crossmodal_tiny.toml` is the same study at test "
           "size.")
    if timing:
        run += f" {timing}"
    return "\n".join([*lines, "", FIGURE_NOTES, "", "## Set-up", "", run, SETUP, "", READING]) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--config", type=Path, default=CONFIG, help="study TOML (default: the committed study)")
    ap.add_argument("--figures", action=argparse.BooleanOptionalAction, default=False,
                    help="write the study's figures beside the page (<page>_range_curve.png, <page>_panel.png)")
    ap.add_argument("--no-timing", action="store_true", help="no wall time on the page (the tables are the same)")
    ap.add_argument("--out", type=Path, default=ROOT / "benchmarks" / "crossmodal.md")
    args = ap.parse_args()
    cfg, _ = load_study(args.config)
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        res = run_study(args.config, tmp, figures=args.figures)
        wall = time.perf_counter() - t0
        trials = trial_count(Path(tmp) / "cells")
        if args.figures:
            for src, suffix in FIGURES.items():
                shutil.copyfile(Path(tmp) / src, args.out.with_name(f"{args.out.stem}_{suffix}.png"))
    study_md = render_markdown(cfg, res, shown_path(args.config), SHOWN_OUT)
    load = " / ".join(f"{x:.1f}" for x in os.getloadavg())
    timing = None if args.no_timing else (
        f"This run: {trials} trials, {wall:.0f} s wall{' with the figures' if args.figures else ''} on "
        f"{platform.machine()}, {os.cpu_count()} cores, load average {load} (1 / 5 / 15 min) at the end.")
    args.out.write_text(page(study_md, "crossmodal", timing), encoding="utf-8")
    print(study_md)


if __name__ == "__main__":
    main()
