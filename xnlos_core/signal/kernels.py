"""Compiled (numba) kernels of :func:`xnlos_core.signal.doppler.doppler_ra_maps` (≤ 10 ms per frame).

Why compiled: the Doppler-resolved RA maps need, for each of the 401 × 121 cells, the beam of each of
the 64 Doppler bins (≈ 1e8 complex multiply-adds), then a sum, a maximum, its index and a three-bin
velocity. In numpy every one of those steps is a pass over a 25664 × 121 array (≈ 12–25 MB each),
so the chain was bound by memory passes (42 ms a frame; 7.8–8.6 ms now with 2 threads,
benchmarks/dechirp_speed.md). Here each range bin's whole chain runs while its spectrum is in
cache, one range bin per task over ``numba.prange``:

1. the TDM-compensated windowed spectrum y (n_chirps, n_channels) is split into real and imaginary
   parts in float32;
2. the beams of all Doppler bins come from two small BLAS products (``np.dot``), using that the
   delay-and-sum weights of the mirrored azimuth −θ are the conjugates of θ's
   (w_k(−θ) = conj(w_k(θ)): real tapers, steering phases odd in sin θ). With P = y_r·w_r,
   Q = y_i·w_i, S = y_r·w_i, T = y_i·w_r (per Doppler bin and azimuth of one half of the grid)
       b(θ) = (P − Q) + j(S + T),        b(−θ) = (P + Q) + j(T − S),
   so the pair costs the multiply-adds of one azimuth (half of a full complex product);
3. |b|², its sum over Doppler bins (float64), maximum and first argmax, then the three-bin velocity
   estimate of :func:`~xnlos_core.signal.doppler.doppler_ra_maps` at the peak bin, in double precision.

When the grid is not mirror-symmetric or the mirrored weights are not conjugates (to
:data:`MIRROR_RTOL`), every azimuth is computed on its own (:func:`azimuth_pairs`), so any array and
grid give the right maps; only the speed-up differs.

The kernels are compiled on first use (≈ 5 s) and cached on disk by numba (``cache=True``; ≈ 0.5 s
to load in a new process). Concurrent calls from several Python threads are serialised
(:data:`_LOCK`): numba's ``workqueue`` thread pool, which this module selects unless the user chose
another, does not allow two parallel kernels at once.
"""
from __future__ import annotations

import os
import threading

import numba
import numpy as np
from numba import njit, prange

_LOCK = threading.Lock()
MIRROR_RTOL = 1e-12  # mirrored weights taken as conjugates when they differ by less (float32 beams: 6e-8)

if "NUMBA_THREADING_LAYER" not in os.environ and numba.config.THREADING_LAYER == "default":
    # numba's own work queue rather than its first choice, GNU OpenMP: that one aborts a forked child
    # that runs a parallel kernel ("fork() called from a process already using GNU OpenMP"), and its idle
    # workers spin on the cores that the FFT threads between the kernels need. The work queue is as fast
    # here (7.6 against 7.5 ms a frame) and fork-safe; it is not thread-safe, hence :data:`_LOCK`. A
    # layer chosen by the user (NUMBA_THREADING_LAYER or numba.config) is left alone; this takes effect
    # only if no numba parallel code has run in the process yet.
    numba.config.THREADING_LAYER = "workqueue"


@njit(parallel=True, cache=True, fastmath={"reassoc", "contract"})
def taper_cast(cube, taper, scale, out, row_energy):  # pragma: no cover - compiled
    """out[i, j] = cube[i, j]·taper[i]·scale in complex64; row_energy[i] = Σ_j |cube[i, j]|² (float64).

    cube (n, m) complex128, taper (n,) float64, scale float, out (n, m) complex64 and row_energy (n,)
    float64 (written). A NaN or infinite sample makes its row's energy NaN or inf (reassociation keeps
    that: it never assumes finite values), so one sum checks the whole cube for the caller."""
    n, m = cube.shape
    for i in prange(n):
        t = taper[i] * scale
        e = 0.0
        for j in range(m):
            z = cube[i, j]
            e += z.real * z.real + z.imag * z.imag
            out[i, j] = z * t
        row_energy[i] = e


@njit(parallel=True, cache=True)
def doppler_tapers(prof, taper, boxcar, out):  # pragma: no cover - compiled
    """out[0] = prof·taper[d], out[1] = prof·boxcar[d] (complex64): both Doppler tapers in one pass.

    prof (r, d, k) complex64 range profiles; taper, boxcar (d,) complex128 (window/Σw or 1/N, times
    the fftshift modulation); out (2, r, d, k) complex64 (written)."""
    r, d, k = prof.shape
    for i in prange(r):
        for m in range(d):
            tw = np.complex64(taper[m])
            tb = np.complex64(boxcar[m])
            for c in range(k):
                z = prof[i, m, c]
                out[0, i, m, c] = z * tw
                out[1, i, m, c] = z * tb


@njit(parallel=True, cache=True, fastmath={"reassoc", "contract"})
def beam_maps(spec_w, spec_u, comp_r, comp_i, wa, wb, ipos, ineg, wt_r, wt_i, velocity_axis, consts,
              power, peak_power, velocity, velocity_std):  # pragma: no cover - compiled
    """The maps of :func:`xnlos_core.signal.doppler.doppler_ra_maps`, one range bin per task.

    spec_w, spec_u (r, d, k) complex64: windowed and unwindowed Doppler spectra (bins ascending);
    comp_r, comp_i (d, k) float64: TDM compensation (real, imaginary); wa = [w_r | w_i], wb = [w_i | w_r]
    (k, 2H) float32: the weights of the H computed azimuths; ipos (H,), ineg (H,) int64: the map
    column of each computed azimuth and of its mirror (−1: none); wt_r, wt_i (A, k) float64: all
    weights by azimuth, for the velocity; velocity_axis (d,) [m/s]; consts (6,) float64: 1/ENBW,
    tan(π/N)/(π/N), Δv [m/s], v_max [m/s], σ_cell [W], λ₀/(4π·T_s)·√(12/(N(N²−1))) [m/s].
    Written, each (r, A) float64: power Σ_d|b|²/ENBW [W], peak_power max_d|b|² [W], velocity [m/s],
    velocity_std [m/s].

    Reassociation is allowed (``fastmath``) so that the sums over channels vectorise; rounding then
    differs from a left-to-right sum by a few float64 ulps (the beams themselves are float32).
    """
    r, d, k = spec_w.shape
    n_az = power.shape[1]
    for i in prange(r):
        yr = np.empty((d, k), np.float32)
        yi = np.empty((d, k), np.float32)
        for m in range(d):
            for c in range(k):
                zr = np.float64(spec_w[i, m, c].real)
                zi = np.float64(spec_w[i, m, c].imag)
                yr[m, c] = zr * comp_r[m, c] - zi * comp_i[m, c]
                yi[m, c] = zr * comp_i[m, c] + zi * comp_r[m, c]
        ps = np.dot(yr, wa)  # (d, 2H): P | S
        qt = np.dot(yi, wb)  # (d, 2H): Q | T
        peak = np.empty(n_az, np.int64)
        _doppler_stats(ps, qt, ipos, ineg, consts[0], power[i], peak_power[i], peak)
        ur = np.empty((d, k))  # the unwindowed spectrum split once: contiguous float64 rows vectorise
        ui = np.empty((d, k))
        for m in range(d):
            for c in range(k):
                ur[m, c] = spec_u[i, m, c].real
                ui[m, c] = spec_u[i, m, c].imag
        _velocity(ur, ui, comp_r, comp_i, wt_r, wt_i, peak, velocity_axis, consts, power[i],
                  velocity[i], velocity_std[i])


@njit(cache=True, fastmath={"reassoc", "contract"})
def _doppler_stats(ps, qt, ipos, ineg, inv_enbw, power, peak_power, peak):  # pragma: no cover - compiled
    """One range bin of :func:`beam_maps`: b(θ) = (P − Q) + j(S + T) for the computed azimuths and
    b(−θ) = (P + Q) + j(T − S) for their mirrors, from ps = [P | S], qt = [Q | T] (d, 2H) float32;
    Σ|b|²·inv_enbw (summed in float64), max|b|² and its first argmax per azimuth, into the (A,) rows."""
    d = ps.shape[0]
    h = ps.shape[1] // 2
    sp = np.zeros(h)
    sn = np.zeros(h)
    mp = np.full(h, -1.0, np.float32)
    mn = np.full(h, -1.0, np.float32)
    ap = np.zeros(h, np.float32)  # argmax as float32 (exact below 2^24): float-only selects vectorise
    an = np.zeros(h, np.float32)
    for m in range(d):
        fm = np.float32(m)
        for j in range(h):
            p_ = ps[m, j]
            s_ = ps[m, h + j]
            q_ = qt[m, j]
            t_ = qt[m, h + j]
            a1 = p_ - q_
            b1 = s_ + t_
            pw1 = a1 * a1 + b1 * b1
            a2 = p_ + q_
            b2 = t_ - s_
            pw2 = a2 * a2 + b2 * b2
            sp[j] += pw1
            sn[j] += pw2
            g1 = pw1 > mp[j]
            g2 = pw2 > mn[j]
            mp[j] = pw1 if g1 else mp[j]
            ap[j] = fm if g1 else ap[j]
            mn[j] = pw2 if g2 else mn[j]
            an[j] = fm if g2 else an[j]
    for j in range(h):
        col = ipos[j]
        power[col] = sp[j] * inv_enbw
        peak_power[col] = mp[j]
        peak[col] = np.int64(ap[j])
        col = ineg[j]
        if col >= 0:
            power[col] = sn[j] * inv_enbw
            peak_power[col] = mn[j]
            peak[col] = np.int64(an[j])


@njit(cache=True, fastmath={"reassoc", "contract"})
def _velocity(spec_r, spec_i, comp_r, comp_i, wt_r, wt_i, peak, velocity_axis, consts, power,
              velocity, velocity_std):  # pragma: no cover - compiled
    """One range bin of :func:`beam_maps`: velocity and its σ per azimuth (formulas in
    :func:`xnlos_core.signal.doppler.doppler_ra_maps`). The unwindowed spectrum (spec_r, spec_i: real and
    imaginary parts, (d, k) float64) at the peak bin and its two neighbours, all three compensated
    with the peak bin's f_D, is beamformed at the azimuth in double precision; Candan's
    δ = tan(π/N)/(π/N)·Re[(X₋ − X₊) / (2X₀ − X₋ − X₊)], clipped to ±½, gives v = v_k + δ·Δv folded
    into [−v_max, v_max); σ_v = crb/√max(power/σ_cell − 1, 1e-12)."""
    d, k = spec_r.shape
    candan, dv, vmax, sigma_cell, crb = consts[1], consts[2], consts[3], consts[4], consts[5]
    for col in range(peak.shape[0]):
        pk = peak[col]
        lo = (pk + d - 1) % d
        hi = (pk + 1) % d
        xmr = 0.0
        xmi = 0.0
        x0r = 0.0
        x0i = 0.0
        xpr = 0.0
        xpi = 0.0
        for c in range(k):
            wr = comp_r[pk, c] * wt_r[col, c] - comp_i[pk, c] * wt_i[col, c]
            wi = comp_r[pk, c] * wt_i[col, c] + comp_i[pk, c] * wt_r[col, c]
            ur = spec_r[lo, c]
            ui = spec_i[lo, c]
            xmr += ur * wr - ui * wi
            xmi += ur * wi + ui * wr
            ur = spec_r[pk, c]
            ui = spec_i[pk, c]
            x0r += ur * wr - ui * wi
            x0i += ur * wi + ui * wr
            ur = spec_r[hi, c]
            ui = spec_i[hi, c]
            xpr += ur * wr - ui * wi
            xpi += ur * wi + ui * wr
        den = complex(2.0 * x0r - xmr - xpr, 2.0 * x0i - xmi - xpi)
        delta = (complex(xmr - xpr, xmi - xpi) / den).real if abs(den) > 0 else 0.0
        delta = min(0.5, max(-0.5, candan * delta))
        v = velocity_axis[pk] + delta * dv + vmax
        velocity[col] = v - 2.0 * vmax * np.floor(v / (2.0 * vmax)) - vmax
        velocity_std[col] = crb / np.sqrt(max(power[col] / sigma_cell - 1.0, 1e-12))


def azimuth_pairs(weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(ipos, ineg): the azimuth columns :func:`beam_maps` computes and the mirror of each (−1: none).

    weights (k, A) complex. When every column A−1−a equals conj(column a) to within :data:`MIRROR_RTOL`
    of the largest weight (a grid symmetric about broadside, real tapers: the default; ``np.linspace``
    leaves the two halves of the grid a few ulps apart), ipos is the upper half ⌊A/2⌋, …, A−1 and ineg
    its mirrors (−1 for the broadside column of an odd grid); otherwise every column is computed on its
    own (ipos = 0, …, A−1, ineg all −1)."""
    n = weights.shape[1]
    tol = MIRROR_RTOL * float(np.abs(weights).max(initial=0.0))
    if np.abs(weights[:, ::-1] - weights.conj()).max(initial=0.0) <= tol:
        ipos = np.arange(n // 2, n)
        ineg = n - 1 - ipos
        ineg[ineg == ipos] = -1
        return ipos.astype(np.int64), ineg.astype(np.int64)
    return np.arange(n, dtype=np.int64), np.full(n, -1, dtype=np.int64)


def run(fn, threads: int, *args):
    """Call compiled kernel ``fn(*args)`` on ``threads`` numba threads (clamped to the pool size),
    one call at a time in the process (:data:`_LOCK`)."""
    n = max(1, min(int(threads), numba.config.NUMBA_NUM_THREADS))
    with _LOCK:
        before = numba.get_num_threads()
        numba.set_num_threads(n)
        try:
            return fn(*args)
        finally:
            numba.set_num_threads(before)
