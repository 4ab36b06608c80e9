"""Doppler velocity against its Cramér–Rao bound, and the fold test's azimuth (not a test).

    PYTHONPATH=. python benchmarks/doppler_velocity.py [--seeds 10] [--out benchmarks/doppler_velocity.md]

1. RMSE / CRLB: movers on the default radar (512 samples, 64 chirp loops, 4 TX × 8 RX), 20 a cube on
   range-bin centres 19 bins apart at one grid azimuth, per-chirp SNR η of the beamformed cell 10, 20 and
   30 dB, velocity 5, 5¼ and 5½ Doppler bins; ``--seeds`` cubes each. Two kinds of cube: a pure tone
   (each TX slot's start time gives the exact slow-time phase, no range migration) and the chirp-sequence
   cube of :func:`xnlos_core.signal.doppler.chirp_sequence_cube` (the mover's range changes over the frame).
   The bound is :func:`~xnlos_core.signal.doppler.crlb_velocity` (Eq. V1); coverage is the share of
   |error| ≤ 1.96·velocity_std.
2. Folds: one mover at 12.3° and η = 30 dB at velocities beyond ±v_max and just below +v_max; peak azimuth
   by a parabola through the log-power of the best three azimuth bins of its range bin, with the fold test
   (``folds=1``) and without (``folds=0``).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from benchmarks.pages import marked  # noqa: E402
from xnlos_core.radar import RadarConfig  # noqa: E402
from xnlos_core.signal.chain import processing_gain  # noqa: E402
from xnlos_core.signal.doppler import (add_chirp_noise, chirp_noise_power, chirp_sequence_cube,  # noqa: E402
                                       chirp_start_times, crlb_velocity, doppler_ra_maps)


def _cube(radar, k_range, theta, amp, v, tone):
    n = len(k_range)
    r = k_range * radar.range_resolution
    if not tone:
        return chirp_sequence_cube(radar, r, np.full(n, theta), np.full(n, amp, complex), np.full(n, v))
    static = chirp_sequence_cube(radar, r, np.full(n, theta), np.full(n, amp, complex), np.zeros(n))
    slot = np.repeat(np.arange(radar.n_tdm), radar.n_channels // radar.n_tdm)
    t = chirp_start_times(radar)[:, slot]
    return static * np.exp(2j * np.pi * (2 * v / radar.doppler_wavelength) * t)[None]


def bound_table(radar: RadarConfig, seeds: int) -> list[str]:
    sigma_cell = chirp_noise_power(radar) / processing_gain(radar)
    k_range, col = np.arange(20, radar.n_range_bins - 5, 19), 70
    rows = ["| cube | η [dB] | offset [bins] | RMSE / CRLB | mean σ / CRLB | bias / CRLB | ±1.96σ coverage |",
            "|---|---|---|---|---|---|---|"]
    for tone in (True, False):
        for snr_db in (10, 20, 30):
            eta = 10 ** (snr_db / 10)
            bound = float(crlb_velocity(radar, eta))
            for offset in (0.0, 0.25, 0.5):
                v = (5 + offset) * radar.velocity_resolution
                clean = _cube(radar, k_range, radar.azimuth_axis[col], np.sqrt(eta * sigma_cell), v, tone)
                err, sig = [], []
                for seed in range(seeds):
                    rng = np.random.default_rng(seed)
                    m = doppler_ra_maps(add_chirp_noise(clean * np.exp(2j * np.pi * rng.random()), radar, rng), radar)
                    err.append(m.velocity[k_range, col] - v)
                    sig.append(m.velocity_std[k_range, col])
                err, sig = np.concatenate(err), np.concatenate(sig)
                rows.append(f"| {'pure tone' if tone else 'chirp sequence'} | {snr_db} | {offset:g} | "
                            f"{np.sqrt(np.mean(err**2)) / bound:.3f} | {np.mean(sig) / bound:.3f} | "
                            f"{np.mean(err) / bound:+.3f} | {np.mean(np.abs(err) <= 1.96 * sig):.3f} |")
    return rows


def _peak_azimuth(row, radar):
    j = int(np.argmax(row))
    lo, c, hi = np.log(row[j - 1:j + 2])
    return radar.azimuth_axis[j] + 0.5 * (lo - hi) / (lo - 2 * c + hi) * (radar.azimuth_axis[1] - radar.azimuth_axis[0])


def fold_table(radar: RadarConfig) -> list[str]:
    vmax, dv = radar.max_unambiguous_velocity, radar.velocity_resolution
    theta, i = np.deg2rad(12.3), 80
    amp = np.sqrt(1e3 * chirp_noise_power(radar) / processing_gain(radar))
    rows = ["| true v [m/s] | v / v_max | azimuth error, folds=0 | azimuth error, folds=1 | v̂, folds=0 | v̂, folds=1 |",
            "|---|---|---|---|---|---|"]
    for v in (3.0, vmax - 0.3 * dv, -vmax + 0.2 * dv, vmax + 3.3 * dv, -vmax - 5.4 * dv, 2 * vmax + 0.4 * dv):
        cube = add_chirp_noise(chirp_sequence_cube(radar, [i * radar.range_resolution], [theta], [amp], [v]), radar,
                               np.random.default_rng(1))
        cells = []
        for folds in (0, 1):
            m = doppler_ra_maps(cube, radar, folds=folds)
            j = int(np.argmax(m.peak_power[i]))
            cells.append((np.rad2deg(_peak_azimuth(m.peak_power[i], radar) - theta), m.velocity[i, j]))
        rows.append(f"| {v:.3f} | {v / vmax:+.2f} | {cells[0][0]:+.2f}° | {cells[1][0]:+.2f}° | "
                    f"{cells[0][1]:.3f} | {cells[1][1]:.3f} |")
    return rows


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path(__file__).with_name("doppler_velocity.md"))
    args = ap.parse_args(argv)
    radar = RadarConfig()
    lines = ["# Doppler velocity at the Cramér–Rao bound", "",
             f"`PYTHONPATH=. python benchmarks/doppler_velocity.py --seeds {args.seeds}` (its tables: "
             "`python -m benchmarks.regenerate doppler_velocity`)", "",
             "## RMSE against the complex-tone bound", "",
             f"Default radar (N = {radar.n_chirps} loops, Δv = {radar.velocity_resolution:.3f} m/s, v_max = "
             f"{radar.max_unambiguous_velocity:.2f} m/s); {args.seeds} cubes × 20 movers per row; η is the "
             "per-chirp SNR of the beamformed cell; offset from the Doppler bin centre.", "",
             *marked("bound", bound_table(radar, args.seeds)), "",
             "The pure-tone rows measure the estimator: at the bound on and off the grid (the likelihood's 9 bins "
             "hold all but ≤ 7 % of the information on the grid, all of it half a bin off), σ its own. The "
             "chirp-sequence rows add the simulated mover's range change over the frame, which shifts its "
             "slow-time frequency from 2v/λ₀ by a few 1e-4 m/s (a noise-free mover at 5 m/s: −1e-3 m/s); at "
             "30 dB that offset is a third to a whole bound and dominates the RMSE.", "",
             "## Folded velocities: azimuth and velocity", "",
             "One mover at 12.3°, η = 30 dB; azimuth from a parabola through the best three bins.", "",
             *marked("folds", fold_table(radar)), ""]
    args.out.write_text("\n".join(lines))
    print("\n".join(lines))


if __name__ == "__main__":
    main()
