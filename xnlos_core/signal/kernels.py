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
3. |b|², its sum over Doppler bins (float64), maximum and first argmax; the fold test at the strong
   Doppler peaks (rare κ ≠ 0: those bins' beams again, the statistics anew); then the velocity of
   :func:`~xnlos_core.signal.doppler.doppler_ra_maps` at the peak bin (three-bin estimate, and the
   likelihood's Newton steps in strong cells), in double precision.

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
REACH = 0.3  # [bins] the refinement's farthest move from the three-bin estimate
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
def beam_maps(spec_w, spec_u, comp_r, comp_i, wa, wb, ipos, ineg, wt_r, wt_i, velocity_axis, consts, slot,
              kappas, hyps, priors, power, peak_power, velocity, velocity_std):  # pragma: no cover - compiled
    """The maps of :func:`xnlos_core.signal.doppler.doppler_ra_maps`, one range bin per task.

    spec_w, spec_u (r, d, k) complex64: windowed and unwindowed Doppler spectra (bins ascending);
    comp_r, comp_i (d, k) float64: TDM compensation (real, imaginary); wa = [w_r | w_i], wb = [w_i | w_r]
    (k, 2H) float32: the weights of the H computed azimuths; ipos (H,), ineg (H,) int64: the map
    column of each computed azimuth and of its mirror (−1: none); wt_r, wt_i (A, k) float64: all
    weights by azimuth, for the fold test and the velocity; velocity_axis (d,) [m/s]; consts (16,)
    float64 (:func:`xnlos_core.signal.doppler._doppler_plan`): 1/ENBW, tan(π/N)/(π/N), Δv [m/s],
    v_max [m/s], σ_cell [W], λ₀/(4π·T_s)·√(6/(N(N²−1))) [m/s], the fold test's and the refinement's
    SNR thresholds (peak-bin power over its noise floor), the window's relative sidelobe cut, its main
    lobe's half width [bins], the refinement's half span L [bins], n_tdm, Newton steps, the fold test's
    least coherence, its least significance [σ] and its least coherence at the grid's edge; slot (k,) int64:
    each channel's TX slot i; kappas (F,) int64: fold hypotheses κ; hyps (d, F) int64: the indices into
    kappas tested per Doppler bin (−1: none), the first κ = 0.
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
        rowsum = np.empty(d)
        _pair_stats(ps, qt, ipos, ineg, consts[0], power[i], peak_power[i], peak, rowsum)
        fold = np.zeros(d, np.int64)
        known = np.zeros(d, np.bool_)
        if _resolve_folds(yr, yi, wt_r, wt_i, slot, kappas, hyps, priors, consts, rowsum, fold, known):
            # a Doppler bin's fold is not κ = 0 (rare): its beams again with its κ, the statistics anew
            pw = np.empty((d, n_az), np.float32)
            _beam_powers(ps, qt, ipos, ineg, pw)
            beam = np.empty(n_az)
            for m in range(d):
                if fold[m] != 0:
                    _fold_beams(yr, yi, m, wt_r, wt_i, slot, fold[m], int(consts[11]), beam)
                    for a in range(n_az):
                        pw[m, a] = np.float32(beam[a])
            _doppler_stats(pw, consts[0], power[i], peak_power[i], peak)
        ur = np.empty((d, k))  # the unwindowed spectrum split once: contiguous float64 rows vectorise
        ui = np.empty((d, k))
        for m in range(d):
            for c in range(k):
                ur[m, c] = spec_u[i, m, c].real
                ui[m, c] = spec_u[i, m, c].imag
        _velocity(ur, ui, comp_r, comp_i, wt_r, wt_i, slot, peak, fold, known, velocity_axis, consts, power[i],
                  peak_power[i], velocity[i], velocity_std[i])


@njit(cache=True, fastmath={"reassoc", "contract"})
def _beam_powers(ps, qt, ipos, ineg, pw):  # pragma: no cover - compiled
    """|b|² (d, A) float32 of one range bin: b(θ) = (P − Q) + j(S + T) for the computed azimuths and
    b(−θ) = (P + Q) + j(T − S) for their mirrors, from ps = [P | S], qt = [Q | T] (d, 2H) float32."""
    d = ps.shape[0]
    h = ps.shape[1] // 2
    for m in range(d):
        for j in range(h):
            p_ = ps[m, j]
            s_ = ps[m, h + j]
            q_ = qt[m, j]
            t_ = qt[m, h + j]
            a1 = p_ - q_
            b1 = s_ + t_
            pw[m, ipos[j]] = a1 * a1 + b1 * b1
            if ineg[j] >= 0:
                a2 = p_ + q_
                b2 = t_ - s_
                pw[m, ineg[j]] = a2 * a2 + b2 * b2


@njit(cache=True, fastmath={"reassoc", "contract"})
def _pair_stats(ps, qt, ipos, ineg, inv_enbw, power, peak_power, peak, rowsum):  # pragma: no cover - compiled
    """:func:`_doppler_stats` straight from ps = [P | S], qt = [Q | T] (d, 2H) float32 (the beams of
    :func:`_beam_powers` formed on the fly, no (d, A) array), plus rowsum (d,): Σ_θ|b|² per Doppler bin
    (a sum, not a maximum, so that the loop vectorises; it bounds max_θ|b|² from above)."""
    d = ps.shape[0]
    h = ps.shape[1] // 2
    sp = np.zeros(h)
    sn = np.zeros(h)
    mp = np.full(h, -1.0, np.float32)
    mn = np.full(h, -1.0, np.float32)
    ap = np.zeros(h, np.float32)  # argmax as float32 (exact below 2^24): float-only selects vectorise
    an = np.zeros(h, np.float32)
    paired = ineg.max() >= 0
    for m in range(d):
        fm = np.float32(m)
        rm = 0.0
        rn = 0.0
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
            rm += pw1
            rn += pw2
        # an unpaired grid (ineg all −1) has no mirrored beams (a paired one's −1, broadside, counts twice)
        rowsum[m] = rm + rn if paired else rm
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
def _doppler_stats(pw, inv_enbw, power, peak_power, peak):  # pragma: no cover - compiled
    """Σ_d|b|²·inv_enbw (summed in float64), max|b|² and its first argmax per azimuth, into the (A,) rows."""
    d, n_az = pw.shape
    sp = np.zeros(n_az)
    mp = np.full(n_az, -1.0, np.float32)
    ap = np.zeros(n_az, np.float32)  # argmax as float32 (exact below 2^24): float-only selects vectorise
    for m in range(d):
        fm = np.float32(m)
        for j in range(n_az):
            p_ = pw[m, j]
            sp[j] += p_
            g = p_ > mp[j]
            mp[j] = p_ if g else mp[j]
            ap[j] = fm if g else ap[j]
    for j in range(n_az):
        power[j] = sp[j] * inv_enbw
        peak_power[j] = mp[j]
        peak[j] = np.int64(ap[j])


@njit(cache=True, fastmath={"reassoc", "contract"})
def _fold_beams(yr, yi, m, wt_r, wt_i, slot, kappa, n_tdm, out):  # pragma: no cover - compiled
    """|b|² (A,) float64 of Doppler bin m's compensated windowed spectrum (yr, yi (d, k) float32) beamformed
    with the fold hypothesis κ: each channel times exp(−j2π·κ·i/N_tx), i its TX slot."""
    n_az, k = wt_r.shape
    gr = np.empty(k)
    gi = np.empty(k)
    for c in range(k):
        ph = -2.0 * np.pi * kappa * slot[c] / n_tdm
        cr = np.cos(ph)
        ci = np.sin(ph)
        zr = np.float64(yr[m, c])
        zi = np.float64(yi[m, c])
        gr[c] = zr * cr - zi * ci
        gi[c] = zr * ci + zi * cr
    for a in range(n_az):
        br = 0.0
        bi = 0.0
        for c in range(k):
            br += gr[c] * wt_r[a, c] - gi[c] * wt_i[a, c]
            bi += gr[c] * wt_i[a, c] + gi[c] * wt_r[a, c]
        out[a] = br * br + bi * bi


@njit(cache=True, fastmath={"reassoc", "contract"})
def _coherence(yr, yi, m, wt_r, wt_i, a, peak, noise):  # pragma: no cover - compiled
    """ρ of Doppler bin m under fold hypothesis κ: the share of the channels' signal energy that one plane
    wave explains, noise removed. With b̂ the highest beam (at azimuth θ̂, weights w = w(θ̂)), E = Σ_c|y_c|²,
    σ² = noise/‖w‖² the noise per channel and τ = (Σ_c|w_c|)²/(K·‖w‖²) the taper's efficiency,

        ρ = (|b̂|²/‖w‖² − σ²) / (τ·(E − K·σ²))                                               (F1)

    ≈ 1 for one echo seen with the right κ (Cauchy–Schwarz, with equality for a plane wave), ≈ 0.85 with a
    neighbouring κ on the default 4-TX array (the slot phases a staircase), and lower where echoes from
    several azimuths share the range–Doppler bin (a wall's static returns). a: θ̂'s index, peak: |b̂|² [W],
    from the beams of the fold test under κ."""
    k = wt_r.shape[1]
    wn = 0.0
    wabs = 0.0
    for c in range(k):
        q = wt_r[a, c] * wt_r[a, c] + wt_i[a, c] * wt_i[a, c]
        wn += q
        wabs += np.sqrt(q)
    energy = 0.0
    for c in range(k):
        energy += np.float64(yr[m, c]) * np.float64(yr[m, c]) + np.float64(yi[m, c]) * np.float64(yi[m, c])
    sigma2 = noise / wn
    den = (wabs * wabs / (k * wn)) * (energy - k * sigma2)
    if den <= 0.0:
        return 0.0
    return (peak / wn - sigma2) / den


@njit(cache=True, fastmath={"reassoc", "contract"})
def _fold_beam_at(yr, yi, m, wt_r, wt_i, slot, kappa, n_tdm, a, vr, vi):  # pragma: no cover - compiled
    """(Re b, Im b) of Doppler bin m's beam at azimuth index a under fold hypothesis κ (as :func:`_fold_beams`,
    one azimuth); vr, vi (k,) are written with the effective weights v_c = exp(−j2π·κ·i_c/N_tx)·w_c(θ_a),
    so that b = Σ_c y_c·v_c."""
    k = wt_r.shape[1]
    br = 0.0
    bi = 0.0
    for c in range(k):
        ph = -2.0 * np.pi * kappa * slot[c] / n_tdm
        cr = np.cos(ph)
        ci = np.sin(ph)
        vr[c] = cr * wt_r[a, c] - ci * wt_i[a, c]
        vi[c] = cr * wt_i[a, c] + ci * wt_r[a, c]
        zr = np.float64(yr[m, c])
        zi = np.float64(yi[m, c])
        br += zr * vr[c] - zi * vi[c]
        bi += zr * vi[c] + zi * vr[c]
    return br, bi


@njit(cache=True, fastmath={"reassoc", "contract"})
def _fold_gain_sigma(yr, yi, m, wt_r, wt_i, slot, kappa, n_tdm, a0, a1, noise):  # pragma: no cover - compiled
    """σ_Δ [W] of the fold test's gain Δ = |b_κ(θ₁)|² − |b_0(θ₀)|² of Doppler bin m, from the channels'
    noise: with b = Σ_c y_c·v_c (:func:`_fold_beam_at`) and y_c = s_c + n_c, n_c ~ CN(0, σ²),
    σ² = noise/‖w(θ₀)‖² (as :func:`_coherence`), to first order in n

        Δ − E[Δ] = 2·Re Σ_c n_c·u_c,   u_c = b₁*·v₁_c − b₀*·v₀_c,   σ_Δ² = 2σ²·Σ_c |u_c|²              (F2)

    The two beams see the same noise, so σ_Δ is much smaller than either beam's own spread."""
    k = wt_r.shape[1]
    v0r = np.empty(k)
    v0i = np.empty(k)
    v1r = np.empty(k)
    v1i = np.empty(k)
    b0r, b0i = _fold_beam_at(yr, yi, m, wt_r, wt_i, slot, 0, n_tdm, a0, v0r, v0i)
    b1r, b1i = _fold_beam_at(yr, yi, m, wt_r, wt_i, slot, kappa, n_tdm, a1, v1r, v1i)
    wn = 0.0
    uu = 0.0
    for c in range(k):
        wn += wt_r[a0, c] * wt_r[a0, c] + wt_i[a0, c] * wt_i[a0, c]
        ur = (b1r * v1r[c] + b1i * v1i[c]) - (b0r * v0r[c] + b0i * v0i[c])  # conj(b)·v, real part
        ui = (b1r * v1i[c] - b1i * v1r[c]) - (b0r * v0i[c] - b0i * v0r[c])  # imaginary part
        uu += ur * ur + ui * ui
    return np.sqrt(2.0 * noise / wn * uu)


@njit(cache=True, fastmath={"reassoc", "contract"})
def _resolve_folds(yr, yi, wt_r, wt_i, slot, kappas, hyps, priors, consts, rowsum, fold, known):  # pragma: no cover
    """The fold test of one range bin (:func:`xnlos_core.signal.doppler.doppler_ra_maps`): at each Doppler
    bin m that is a local maximum of rowsum (d,) = Σ_θ|b|² above the window's sidelobes of the range
    bin's strongest bin, and whose best beam max_θ|b|² is above the fold threshold, each hypothesis κ
    of hyps[m] is beamformed over the whole azimuth grid; the highest beam times the hypothesis' prior
    wins (κ = 0 unless another is higher by more than 1e-5, relatively), a κ ≠ 0 only when one plane
    wave explains the bin under it (:func:`_coherence` ≥ consts[13], or ≥ consts[15] when κ = 0's best beam lies
    on the azimuth grid's first or last column) and its beam's gain over κ = 0's is
    consts[14] standard deviations of the noise's part of that gain (:func:`_fold_gain_sigma`, Eq. F2)
    or more; it holds for the bins of that
    peak's main lobe (κ ± 1 across the spectrum's wrap). fold (d,) and known (d,) are written; returns
    whether any fold is not 0."""
    d = rowsum.shape[0]
    n_az = wt_r.shape[0]
    n_tdm = int(consts[11])
    d_h = int(consts[9])
    noise = consts[4] / (consts[0] * d)  # a beam's noise power [W]: σ_cell·ENBW/N
    thr = consts[6] * noise  # the fold threshold on max_θ|b|² [W]
    top = rowsum.max()
    cut = max(thr, consts[8] * top)
    cand = np.empty(d, np.int64)
    n = 0
    for m in range(d):
        lo = rowsum[(m + d - 1) % d]
        hi = rowsum[(m + 1) % d]
        if rowsum[m] >= cut and rowsum[m] >= lo and rowsum[m] > hi and hyps[m, 1] >= 0:
            cand[n] = m
            n += 1
    if n == 0:
        return False
    cand = cand[:n]
    cand = cand[np.argsort(rowsum[cand])]  # ascending: the strongest peak's lobe is assigned last
    beam = np.empty(n_az)
    for t in range(n):
        m = cand[t]
        _fold_beams(yr, yi, m, wt_r, wt_i, slot, 0, n_tdm, beam)
        best = 0
        a0 = int(np.argmax(beam))
        peak0 = beam[a0]
        best_val = peak0 * priors[m, 0]
        if best_val < thr * priors[m, 0]:
            continue
        edge = a0 == 0 or a0 == n_az - 1
        best_az = 0
        best_peak = 0.0
        for h in range(1, hyps.shape[1]):
            f = hyps[m, h]
            if f < 0:
                break
            _fold_beams(yr, yi, m, wt_r, wt_i, slot, kappas[f], n_tdm, beam)
            a = int(np.argmax(beam))
            val = beam[a] * priors[m, h]
            if val > best_val * (1.0 + 1e-5):  # beyond single-precision rounding of the beams
                best_val = val
                best = kappas[f]
                best_az = a
                best_peak = beam[a]
        # κ = 0's peak on the grid's edge: the echo may lie beyond it, where κ = 0's beam is not seen while a
        # neighbouring κ steers it inside; there the fold needs the stricter coherence consts[15]
        if best != 0 and _coherence(yr, yi, m, wt_r, wt_i, best_az, best_peak, noise) < consts[15 if edge else 13]:
            best = 0  # no single plane wave under κ: several echoes share the bin, the fold is not readable
        if best != 0 and best_peak - peak0 < consts[14] * _fold_gain_sigma(yr, yi, m, wt_r, wt_i, slot, best, n_tdm,
                                                                           a0, best_az, noise):
            best = 0  # the gain over κ = 0 is within the noise's reach (Eq. F2): a weak echo's fold is not readable
        for o in range(-d_h, d_h + 1):
            mm = m + o
            adj = 0
            if mm < 0:
                mm += d
                adj = -1
            elif mm >= d:
                mm -= d
                adj = 1
            fold[mm] = best + adj
            known[mm] = True
    for m in range(d):
        if fold[m] != 0:
            return True
    return False


@njit(cache=True)
def _ml_objective(zr, zi, delta, n, alt, co, so):  # pragma: no cover - compiled
    """F(δ) = |Σ_o Z̃_o R(δ − o)|² / Σ_o R(δ − o)², o = −L … L (zr, zi (2L+1,)): the concentrated
    likelihood of one tone at δ bins from the centre bin given 2L+1 unwindowed bins (×σ²/N), with
    R(x) = sin(πx)/sin(πx/N) (N at x = 0), the real periodic sinc. sin(π(δ − o)) = (−1)^o·sin(πδ) and
    sin(π(δ − o)/N) from sin, cos(πδ/N) and the tables alt = (−1)^o, co = cos(πo/N), so = sin(πo/N):
    three trigonometric calls per evaluation."""
    half = (zr.shape[0] - 1) // 2
    s1 = np.sin(np.pi * delta)
    sd = np.sin(np.pi * delta / n)
    cd = np.cos(np.pi * delta / n)
    sr = 0.0
    si = 0.0
    g = 0.0
    for j in range(zr.shape[0]):
        den = sd * co[j] - cd * so[j]
        x = delta - (j - half)
        rr = float(n) if abs(x) < 1e-12 else alt[j] * s1 / den
        sr += zr[j] * rr
        si += zi[j] * rr
        g += rr * rr
    return (sr * sr + si * si) / g


@njit(cache=True, fastmath={"reassoc", "contract"})
def _velocity(spec_r, spec_i, comp_r, comp_i, wt_r, wt_i, slot, peak, fold, known, velocity_axis, consts, power,
              peak_power, velocity, velocity_std):  # pragma: no cover - compiled
    """One range bin of :func:`beam_maps`: velocity and its σ per azimuth (formulas in
    :func:`xnlos_core.signal.doppler.doppler_ra_maps`). The unwindowed spectrum (spec_r, spec_i: real and
    imaginary parts, (d, k) float64) at 2L+1 bins around the peak bin, all compensated with the peak bin's
    f_D + κ/T_s, is beamformed at the azimuth in double precision. Candan's
    δ = tan(π/N)/(π/N)·Re[(X₋ − X₊) / (2X₀ − X₋ − X₊)], clipped to ±½, starts; above the refinement
    threshold, Newton steps on the likelihood F(δ) (:func:`_ml_objective`, derivatives by central
    differences) give δ and σ_δ² = σ_cell/(N·(−F''(δ))) when they end at a maximum within :data:`REACH`
    of the start; else the three-bin δ and σ_v = crb/√max(power/σ_cell − 1, 1e-12).
    v = v_k + δ·Δv + 2κ·v_max, folded into [−v_max, v_max) where no fold test was made."""
    d, k = spec_r.shape
    candan, dv, vmax, sigma_cell, crb = consts[1], consts[2], consts[3], consts[4], consts[5]
    refine = consts[7] * sigma_cell / (consts[0] * d)  # the refinement threshold on peak_power [W]
    half = int(consts[10])
    n_tdm = int(consts[11])
    steps = int(consts[12])
    nb = 2 * half + 1
    alt = np.empty(nb)  # (−1)^o, cos(πo/N), sin(πo/N) of the likelihood's bins, and their phase factors
    co = np.empty(nb)
    so = np.empty(nb)
    pr = np.empty(nb)
    pi_ = np.empty(nb)
    for j in range(nb):
        o = j - half
        alt[j] = 1.0 if o % 2 == 0 else -1.0
        co[j] = np.cos(np.pi * o / d)
        so[j] = np.sin(np.pi * o / d)
        pr[j] = np.cos(np.pi * o * (d - 1) / d)
        pi_[j] = np.sin(np.pi * o * (d - 1) / d)
    xr = np.empty(nb)
    xi = np.empty(nb)
    wr = np.empty(k)
    wi = np.empty(k)
    for col in range(peak.shape[0]):
        pk = peak[col]
        kap = fold[pk]
        if kap == 0:
            for c in range(k):
                wr[c] = comp_r[pk, c] * wt_r[col, c] - comp_i[pk, c] * wt_i[col, c]
                wi[c] = comp_r[pk, c] * wt_i[col, c] + comp_i[pk, c] * wt_r[col, c]
        else:
            for c in range(k):
                ph = -2.0 * np.pi * kap * slot[c] / n_tdm
                fr = comp_r[pk, c] * np.cos(ph) - comp_i[pk, c] * np.sin(ph)
                fi = comp_r[pk, c] * np.sin(ph) + comp_i[pk, c] * np.cos(ph)
                wr[c] = fr * wt_r[col, c] - fi * wt_i[col, c]
                wi[c] = fr * wt_i[col, c] + fi * wt_r[col, c]
        ml = peak_power[col] >= refine
        if ml:
            for o in range(-half, half + 1):
                b = (pk + o) % d
                sr = 0.0
                si = 0.0
                for c in range(k):
                    sr += spec_r[b, c] * wr[c] - spec_i[b, c] * wi[c]
                    si += spec_r[b, c] * wi[c] + spec_i[b, c] * wr[c]
                xr[o + half] = sr
                xi[o + half] = si
        else:  # the three bins in one pass over the channels
            lo = (pk + d - 1) % d
            hi = (pk + 1) % d
            amr = 0.0
            ami = 0.0
            a0r = 0.0
            a0i = 0.0
            apr = 0.0
            api = 0.0
            for c in range(k):
                ur = spec_r[lo, c]
                ui = spec_i[lo, c]
                amr += ur * wr[c] - ui * wi[c]
                ami += ur * wi[c] + ui * wr[c]
                ur = spec_r[pk, c]
                ui = spec_i[pk, c]
                a0r += ur * wr[c] - ui * wi[c]
                a0i += ur * wi[c] + ui * wr[c]
                ur = spec_r[hi, c]
                ui = spec_i[hi, c]
                apr += ur * wr[c] - ui * wi[c]
                api += ur * wi[c] + ui * wr[c]
            xr[half - 1] = amr
            xi[half - 1] = ami
            xr[half] = a0r
            xi[half] = a0i
            xr[half + 1] = apr
            xi[half + 1] = api
        xmr, xmi = xr[half - 1], xi[half - 1]
        x0r, x0i = xr[half], xi[half]
        xpr, xpi = xr[half + 1], xi[half + 1]
        den = complex(2.0 * x0r - xmr - xpr, 2.0 * x0i - xmi - xpi)
        delta = (complex(xmr - xpr, xmi - xpi) / den).real if abs(den) > 0 else 0.0
        delta = min(0.5, max(-0.5, candan * delta))
        std = crb / np.sqrt(max(power[col] / sigma_cell - 1.0, 1e-12))
        if ml:
            # Z̃_o = X_o·exp(+jπ·o·(N−1)/N): the bins' common linear phase removed, so the tone's bins are
            # α·R(δ − o) with one complex α (module doc of doppler_ra_maps, Eq. V2)
            for j in range(nb):
                a_ = xr[j]
                b_ = xi[j]
                xr[j] = a_ * pr[j] - b_ * pi_[j]
                xi[j] = a_ * pi_[j] + b_ * pr[j]
            h = 1e-3
            x = delta
            curv = 0.0
            for _ in range(steps):
                fm_ = _ml_objective(xr, xi, x - h, d, alt, co, so)
                f0 = _ml_objective(xr, xi, x, d, alt, co, so)
                fp = _ml_objective(xr, xi, x + h, d, alt, co, so)
                curv = (fp - 2.0 * f0 + fm_) / (h * h)
                if not curv < 0.0:
                    break
                step = -0.5 * (fp - fm_) / h / curv
                step = min(0.25, max(-0.25, step))
                x += step
                if abs(step) < 1e-9:
                    break
            if abs(x - delta) <= REACH:  # farther: another tone's lobe; the three-bin estimate stays
                fm_ = _ml_objective(xr, xi, x - h, d, alt, co, so)
                f0 = _ml_objective(xr, xi, x, d, alt, co, so)
                fp = _ml_objective(xr, xi, x + h, d, alt, co, so)
                curv = (fp - 2.0 * f0 + fm_) / (h * h)
                if curv < 0.0:
                    delta = x
                    std = dv * np.sqrt(sigma_cell / (d * -curv))
        v = velocity_axis[pk] + delta * dv + 2.0 * vmax * kap
        if not known[pk]:
            v += vmax
            v = v - 2.0 * vmax * np.floor(v / (2.0 * vmax)) - vmax
        velocity[col] = v
        velocity_std[col] = std


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
