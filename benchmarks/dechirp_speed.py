"""Dechirp and Doppler-chain speed: old vs new, same inputs (not a test).

    python benchmarks/dechirp_speed.py [--repeats 15] [--paths 2000] [--out benchmarks/dechirp_speed.md]

The old implementations are kept here verbatim (``old_dechirp``: one complex exponential per sample
and path; ``old_doppler_ra_maps``: np.fft, fftshift copies, beamforming in (range, Doppler, azimuth)
layout, a (range, azimuth, channel) gather with the compensation applied per cell) and timed back to
back with the library's in one process, alternating old and new on identical inputs, median of
``--repeats`` after a warm-up. The machine is shared, so the ratio (old / new, each a median) is the
figure; absolute ms move with the load (printed). Max relative differences (max |new − old| / max |old|)
are printed beside each row. Default BLAS threads for rows 1–2.

1. dechirp of P random paths (lengths to 1.2 × the unambiguous range, random azimuths and complex
   amplitudes) at the default radar (512 samples × 32 channels);
2. chirp_sequence_cube of 20 moving paths (64 loops × 4 TX slots of dechirps);
3. doppler_ra_maps of one noisy (512, 64, 32) cube → (401, 121) maps with BLAS limited to 1 and to 2
   threads (threadpoolctl) and the new path's workers (FFT and numba threads) equal to that; then the
   new path alone, 10 × ``--repeats`` calls in a row (median and 10–90 % spread).

Max rel. diff: max |new − old| / max |old| over the cube or map (velocity: tests/unit/test_dechirp_fast.py);
the Doppler maps' largest cell-by-cell difference is printed below the table.
"""
from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np
from threadpoolctl import threadpool_limits

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the working tree's packages, not an installed copy

from xnlos_core.signal.antenna import coupling_matrix, steering_vector  # noqa: E402
from xnlos_core.signal.doppler import (DopplerRAMaps, _doppler_fft, _doppler_window,  # noqa: E402
                                add_chirp_noise, chirp_noise_power, chirp_sequence_cube, chirp_start_times,
                                doppler_ra_maps, tdm_compensation)
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig  # noqa: E402
from xnlos_core.signal.chain import _window, beam_weights, dechirp, processing_gain, sample_times  # noqa: E402
from xnlos_core.validation import as_array  # noqa: E402


def old_dechirp(radar: RadarConfig, path_length, azimuth, amplitude, elevation=None) -> np.ndarray:
    """signal_chain.dechirp before the fast path: np.exp per sample and path."""
    L = np.atleast_1d(np.asarray(path_length, dtype=np.float64))
    th = np.atleast_1d(np.asarray(azimuth, dtype=np.float64))
    a = np.atleast_1d(np.asarray(amplitude, dtype=np.complex128))
    el = np.zeros_like(th) if elevation is None else np.atleast_1d(np.asarray(elevation, dtype=np.float64))
    tau = L / SPEED_OF_LIGHT
    fb = radar.chirp_slope * tau
    keep = (fb >= 0) & (fb < radar.sample_rate) & (a != 0)
    L, th, a, tau, fb, el = L[keep], th[keep], a[keep], tau[keep], fb[keep], el[keep]
    t = sample_times(radar)
    phase0 = np.mod(L / radar.wavelength, 1.0) - 0.5 * radar.chirp_slope * tau**2
    cube = np.zeros((radar.n_samples, radar.n_channels), dtype=np.complex128)
    for i in range(0, len(L), 2048):
        sl = slice(i, i + 2048)
        tones = np.exp(2j * np.pi * (np.outer(t, fb[sl]) + phase0[sl]))  # (N, P)
        cube += (tones * a[sl]) @ steering_vector(radar, th[sl], el[sl]).T  # (P, M)
    c = coupling_matrix(radar)
    return cube if c is None else cube @ c.T


def old_chirp_sequence_cube(radar: RadarConfig, r, th, a, v) -> np.ndarray:
    """doppler.chirp_sequence_cube before the fast path: a full-channel old_dechirp per TX slot."""
    n_rx = radar.n_channels // radar.n_tdm
    cube = np.zeros((radar.n_samples, radar.n_chirps, radar.n_channels), dtype=np.complex128)
    for m, starts in enumerate(chirp_start_times(radar)):
        for i, t in enumerate(starts):
            ch = slice(i * n_rx, (i + 1) * n_rx)
            cube[:, m, ch] = old_dechirp(radar, 2.0 * (r + v * t), th, a)[:, ch]
    return cube


def old_range_profiles(cube, radar: RadarConfig) -> np.ndarray:
    """doppler._range_profiles before the fast path (no coupling compensation, no static removal): np.fft,
    window evaluated per call."""
    arr = as_array("chirp-sequence cube", cube, dtype=np.complex128)
    n, d, k = arr.shape
    w = _window(radar.range_window, radar.n_samples)
    spec = np.fft.fft(arr.reshape(n, d * k) * (w / w.sum())[:, None], axis=0)[: radar.n_range_bins]
    return spec.reshape(-1, d, k)


def old_doppler_ra_maps(cube, radar: RadarConfig, *, window: str = "hann") -> DopplerRAMaps:
    """doppler.doppler_ra_maps before the Doppler chain's speed target (radars without coupling compensation)."""
    prof = old_range_profiles(cube, radar)
    r, d, k = prof.shape
    comp = tdm_compensation(radar)
    rd_w = (_doppler_fft(prof, window) * comp[None]).astype(np.complex64)
    weights = beam_weights(radar)
    bf = (rd_w.reshape(r * d, k) @ weights.astype(np.complex64)).reshape(r, d, -1)
    pw = np.square(bf.real) + np.square(bf.imag)
    del bf, rd_w
    w = _doppler_window(window, d)
    enbw = d * float((w**2).sum() / w.sum() ** 2)
    power = pw.sum(axis=1, dtype=np.float64) / enbw
    peak = np.argmax(pw, axis=1)
    peak_power = np.take_along_axis(pw, peak[:, None, :], axis=1)[:, 0].astype(np.float64)
    del pw
    rd_r = _doppler_fft(prof, "boxcar")
    rows = np.arange(r)[:, None]
    x = []
    for off in (-1, 0, 1):
        g = rd_r[rows, (peak + off) % d] * comp[peak]
        x.append(np.einsum("rak,ka->ra", g, weights))
    xm, x0, xp = x
    den = 2 * x0 - xm - xp
    safe = np.abs(den) > 0
    delta = np.where(safe, np.real((xm - xp) / np.where(safe, den, 1.0)), 0.0)
    delta = np.clip(np.tan(np.pi / d) / (np.pi / d) * delta, -0.5, 0.5)
    ts, vmax = radar.chirp_loop_time, radar.max_unambiguous_velocity
    v = radar.velocity_axis[peak] + delta * radar.velocity_resolution
    v = np.mod(v + vmax, 2 * vmax) - vmax
    sigma_cell = chirp_noise_power(radar) / processing_gain(radar)
    eta = np.maximum(power / sigma_cell - 1.0, 1e-12)
    v_std = radar.doppler_wavelength / (4 * np.pi * ts) * np.sqrt(12.0 / (eta * d * (d**2 - 1.0)))
    return DopplerRAMaps(power=power, peak_power=peak_power, velocity=v, velocity_std=v_std,
                         noise_floor=sigma_cell, peak_noise_floor=sigma_cell * enbw / d, radar=radar)


def _pair(old, new, repeats: int) -> tuple[float, float, float, float]:
    """Median wall seconds of old() and new(), then median CPU seconds (process time, all threads) of
    each, alternated call by call after one warm-up each. CPU time is the steadier figure on a loaded
    machine (it does not count time waiting for a core)."""
    old(), new()
    to, tn, co, cn = [], [], [], []
    for _ in range(repeats):
        for f, ts, cs in ((old, to, co), (new, tn, cn)):
            t, c = time.perf_counter(), time.process_time()
            f()
            ts.append(time.perf_counter() - t)
            cs.append(time.process_time() - c)
    return float(np.median(to)), float(np.median(tn)), float(np.median(co)), float(np.median(cn))


def _spread(f, n: int) -> tuple[float, float, float]:
    """Median, 10th and 90th percentile wall ms of n calls of f() in a row (after one warm-up)."""
    f()
    ts = []
    for _ in range(n):
        t = time.perf_counter()
        f()
        ts.append(1e3 * (time.perf_counter() - t))
    return float(np.median(ts)), float(np.percentile(ts, 10)), float(np.percentile(ts, 90))


def _rel(new: np.ndarray, old: np.ndarray) -> float:
    return float(np.abs(new - old).max() / np.abs(old).max())


def _cellwise(new: np.ndarray, old: np.ndarray) -> float:
    return float(np.max(np.abs(new - old) / np.abs(old)))


def main(argv=None) -> list[str]:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=15)
    ap.add_argument("--paths", type=int, default=2000)
    ap.add_argument("--out", type=Path, default=None)
    args = ap.parse_args(argv)
    radar = RadarConfig()
    rng = np.random.default_rng(31)
    p = args.paths
    L = rng.uniform(2.0, 2.4 * radar.max_range, p)
    th = rng.uniform(-1.2, 1.2, p)
    a = rng.standard_normal(p) + 1j * rng.standard_normal(p)
    rows = []

    t4 = _pair(lambda: old_dechirp(radar, L, th, a), lambda: dechirp(radar, L, th, a), args.repeats)
    rows.append((f"dechirp, {p} paths → ({radar.n_samples}, {radar.n_channels})", *t4,
                 _rel(dechirp(radar, L, th, a), old_dechirp(radar, L, th, a))))

    q = 20
    r0, th0 = rng.uniform(3.0, 60.0, q), rng.uniform(-1.0, 1.0, q)
    a0, v0 = rng.standard_normal(q) + 1j * rng.standard_normal(q), rng.uniform(-12.0, 12.0, q)
    t4 = _pair(lambda: old_chirp_sequence_cube(radar, r0, th0, a0, v0),
               lambda: chirp_sequence_cube(radar, r0, th0, a0, v0), max(3, args.repeats // 3))
    cube = chirp_sequence_cube(radar, r0, th0, a0, v0)
    rows.append((f"chirp_sequence_cube, {q} moving paths → {cube.shape}", *t4,
                 _rel(cube, old_chirp_sequence_cube(radar, r0, th0, a0, v0))))

    cube = add_chirp_noise(chirp_sequence_cube(radar, [20.0, 35.0], [0.3, -0.2], [1e-4, 3e-5], [5.0, -1.3]),
                           radar, np.random.default_rng(0))
    old = old_doppler_ra_maps(cube, radar)
    cellwise, spread = [], []
    for threads in (1, 2):  # FFT workers and kernel threads of the new path; the old one had BLAS's only
        new = doppler_ra_maps(cube, radar, workers=threads)
        rel = max(_rel(new.power, old.power), _rel(new.peak_power, old.peak_power))
        cellwise.append(max(_cellwise(new.power, old.power), _cellwise(new.peak_power, old.peak_power)))
        with threadpool_limits(threads):
            t4 = _pair(lambda: old_doppler_ra_maps(cube, radar),
                       lambda: doppler_ra_maps(cube, radar, workers=threads), args.repeats)
            spread.append((threads, _spread(lambda: doppler_ra_maps(cube, radar, workers=threads), 10 * args.repeats)))
        rows.append((f"doppler_ra_maps {cube.shape} → {old.power.shape}, {threads} thread(s)", *t4, rel))

    load = os.getloadavg()
    lines = ["# Dechirp and Doppler-chain speed", "",
             "`python benchmarks/dechirp_speed.py" + (f" --repeats {args.repeats}" if args.repeats != 15 else "")
             + (f" --paths {p}" if p != 2000 else "") + "`", "",
             f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, load average "
             f"{load[0]:.1f} / {load[1]:.1f} / {load[2]:.1f} (1 / 5 / 15 min) at the end of the run; "
             f"old and new alternated, median of {args.repeats}", "",
             "| what | old ms | new ms | old / new | old CPU ms | new CPU ms | CPU old / new | max rel. diff |",
             "|---|---|---|---|---|---|---|---|"]
    lines += [f"| {n} | {1e3 * o:.1f} | {1e3 * w:.1f} | {o / w:.2f}× | {1e3 * co:.1f} | {1e3 * cn:.1f} | "
              f"{co / cn:.2f}× | {d:.1e} |" for n, o, w, co, cn, d in rows]
    lines += ["", f"doppler_ra_maps alone, {10 * args.repeats} calls in a row (ms): "
              + "; ".join(f"{t} thread(s): median {m:.2f}, 10–90 % {lo:.2f}–{hi:.2f}" for t, (m, lo, hi) in spread)
              + ". Doppler rows' max rel. diff is max |new − old| / max |old| per map (power, peak power); "
              f"cell by cell the largest |new − old| / |old| is {max(cellwise):.1e} (single-precision FFTs: "
              "noise cells far below the map's maximum).", ""]
    if args.out:
        args.out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return lines


if __name__ == "__main__":
    main()
