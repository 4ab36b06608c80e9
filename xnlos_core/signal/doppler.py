"""Doppler in the FMCW signal chain: chirp-sequence cubes of movers and range–Doppler processing.

The frame path of :mod:`xnlos_core.signal.chain` averages the chirps coherently, which keeps a
static echo and cancels a moving one (≈ 18 dB lost at 1.5 m/s, 28 dB at 5 m/s with the default
timing). This module is the opt-in path that keeps the slow-time axis:

* Timing (TDM-MIMO, :class:`~xnlos_core.radar.RadarConfig`): chirps start every T_c; the N_tx
  transmitters take turns, so TX i of loop m fires at t = (m·N_tx + i)·T_c and each virtual
  channel is sampled in slow time every T_s = N_tx·T_c, N = n_chirps times per frame.
* Cube layout: (n_samples, n_chirps, n_channels) complex128 [√W], the
  :class:`hardware.adc.AdcLayout` default axes, channels tx-major; entry (:, m, i·n_rx + j) is
  RX j during TX i's chirp of loop m. So ``canonical_cube(cube, AdcLayout(), radar)`` is the old
  coherent-mean path of the same data.
* Sign: v_r = dR/dt [m/s] (positive receding) gives slow-time frequency f_D = +2·v_r/λ₀ (the sign
  :func:`xnlos_core.signal.chain.dechirp` gives the carrier phase +L/λ; λ₀ = c/(f_c + B/2),
  ``radar.doppler_wavelength``, because a range bin's phase is the echo's at mid-chirp).
* Scaling: the Doppler FFT divides by Σw_d like the range FFT, so a static echo keeps amplitude
  |A| in its bin. The Doppler-integrated map Σ_d|κ_d|²/ENBW_d is, by Parseval, |A|² for **any**
  velocity (no scalloping); its noise floor is the per-chirp one, σ_c²/G_p = n_chirps·noise_floor.
"""
from __future__ import annotations

import functools
import threading
from dataclasses import dataclass
from typing import Literal

import numpy as np
import scipy.fft

from xnlos_core.signal.antenna import symmetric_window
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import dechirp_paths, range_taper, beam_weights, decouple, processing_gain, range_fft
from xnlos_core.threads import blas_limit
from xnlos_core.types import RAMap
from xnlos_core.validation import as_array


def chirp_start_times(radar: RadarConfig) -> np.ndarray:
    """Start time [s] of TX slot i in chirp loop m, (m·N_tx + i)·T_c, shape (n_chirps, n_tdm)."""
    slot = np.arange(radar.n_chirps)[:, None] * radar.n_tdm + np.arange(radar.n_tdm)[None, :]
    return slot * radar.chirp_interval


def chirp_noise_power(radar: RadarConfig) -> float:
    """Thermal noise per complex sample of one chirp, k·T·f_s·NF [W] (no averaging over chirps)."""
    return radar.noise_power * radar.n_chirps


def add_chirp_noise(cube: np.ndarray, radar: RadarConfig, rng: np.random.Generator) -> np.ndarray:
    """Return a chirp-sequence ``cube`` plus circular Gaussian noise of :func:`chirp_noise_power` per sample."""
    sd = np.sqrt(chirp_noise_power(radar) / 2.0)
    return cube + sd * (rng.standard_normal(cube.shape) + 1j * rng.standard_normal(cube.shape))


def chirp_sequence_cube(radar: RadarConfig, range_m, azimuth, amplitude, radial_velocity,
                        elevation=None) -> np.ndarray:
    """Noise-free chirp-sequence ADC cube of moving point paths, (n_samples, n_chirps, n_channels) complex128.

    range_m (P,): one-way range R₀ [m] at the frame start; azimuth (P,) θ [rad]; amplitude (P,)
    complex a [√W]; radial_velocity (P,) v_r = dR/dt [m/s]; elevation (P,) or None.

    Each TX slot is the dechirp of Eq. 6 (:func:`~xnlos_core.signal.chain.dechirp`) at the path
    length the target has when that chirp starts, L = 2·(R₀ + v_r·t), keeping the channels of the
    transmitting TX. That carries the Doppler phase 2·v_r·t/λ across slow time exactly and the
    range migration between chirps (5 m/s over the default 25.6 ms frame moves 0.13 m, half a
    range bin: not negligible for fast movers, so it is kept). Neglected: the motion within one
    chirp (a beat-frequency shift of 2·v_r/λ = 333 Hz at 5 m/s, 0.03 of a 10 kHz range bin) and any
    change of azimuth over the frame.
    """
    r = np.atleast_1d(as_array("range_m", range_m, ndim=None))
    th = np.atleast_1d(as_array("azimuth", azimuth))
    a = np.atleast_1d(as_array("amplitude", amplitude, dtype=np.complex128))
    v = np.atleast_1d(as_array("radial_velocity", radial_velocity))
    el = None if elevation is None else np.atleast_1d(as_array("elevation", elevation))
    shapes = [x.shape for x in (r, th, a, v) + (() if el is None else (el,))]
    if r.ndim != 1 or any(s != r.shape for s in shapes):
        raise InputError(f"chirp_sequence_cube: range_m, azimuth, amplitude, radial_velocity (and elevation) "
                         f"must be 1-D of equal length, got shapes {shapes}")
    el = np.zeros_like(th) if el is None else el
    n_rx = radar.n_channels // radar.n_tdm  # channels recorded per TX slot
    cube = np.zeros((radar.n_samples, radar.n_chirps, radar.n_channels), dtype=np.complex128)
    starts = chirp_start_times(radar)  # (n_chirps, n_tdm)
    for i in range(radar.n_tdm):  # all chirp loops of TX i at once; only its channels are synthesised
        ch = slice(i * n_rx, (i + 1) * n_rx)
        lengths = 2.0 * (r[None, :] + v[None, :] * starts[:, i, None])  # (n_chirps, P)
        amps = np.broadcast_to(a, lengths.shape)
        cube[:, :, ch] = dechirp_paths(radar, lengths, th, amps, el, ch).transpose(1, 0, 2)
    return cube


def _doppler_window(name: str, n: int) -> np.ndarray:
    try:
        return symmetric_window(name, n)
    except Exception as exc:  # scipy raises ValueError/TypeError with little context
        raise InputError(f"doppler window {name!r} is not a scipy.signal window name (e.g. 'hann', "
                         f"'boxcar'): {exc}") from None


def tdm_compensation(radar: RadarConfig) -> np.ndarray:
    """exp(−j2π·f_D·i·T_c) per Doppler bin and channel, (n_chirps, n_channels) complex128.

    TX i fires i·T_c after TX 0, so a mover's echo on TX i's virtual channels carries the extra
    phase 2π·f_D·i·T_c, which would steer the beam off. It is removed with each bin's centre
    f_D; a target off the bin centre keeps ≤ π·i/(N·N_tx) rad (0.04 rad by default), and a
    folded (ambiguous) target gets the wrong correction, so its azimuth is biased unless
    :func:`doppler_ra_maps`' fold test chooses another κ (an extra exp(−j2π·κ·i/N_tx) per TX slot).
    """
    i_tx = np.repeat(np.arange(radar.n_tdm), radar.n_channels // radar.n_tdm)
    return np.exp(-2j * np.pi * np.outer(radar.doppler_axis * radar.chirp_interval, i_tx))


def _cube_array(cube, radar: RadarConfig, finite: bool = True) -> np.ndarray:
    """``cube`` as a complex128 array of shape (n_samples, n_chirps, n_channels) for ``radar`` (no copy when
    it already is one); InputError naming the shape expected, or NaN/inf when ``finite``."""
    want = (radar.n_samples, radar.n_chirps, radar.n_channels)
    arr = as_array("chirp-sequence cube", cube, dtype=np.complex128, finite=finite)
    if arr.shape != want:
        raise InputError(f"chirp-sequence cube: expected shape (n_samples, n_chirps, n_channels) = {want} "
                         f"for this radar, got {arr.shape}")
    return arr


def _range_profiles(cube, radar: RadarConfig, remove_static: bool, workers: int | None = None) -> np.ndarray:
    """Validated chirp-sequence cube → range profiles (n_range_bins, n_chirps, n_channels) complex128:
    range FFT, coupling compensation, optional static-clutter removal (module doc of range_doppler)."""
    arr = _cube_array(cube, radar)
    n, d, k = arr.shape
    prof = decouple(range_fft(arr.reshape(n, d * k), radar, workers=workers).reshape(-1, k), radar).reshape(-1, d, k)
    return prof - prof.mean(axis=1, keepdims=True) if remove_static else prof


_SAFE_AMPLITUDE = (1e-12, 1e15)  # [√W] largest |Re|, |Im| of a cube that needs no rescaling (module doc)


def _range_profiles32(cube, radar: RadarConfig, remove_static: bool, threads: int,
                      work: np.ndarray) -> tuple[np.ndarray, float]:
    """:func:`_range_profiles` in single precision for :func:`doppler_ra_maps` → ((n_range_bins, n_chirps,
    n_channels) complex64 profiles, scale): the range window and the cast in one compiled pass (which
    also sums the energy that reveals non-finite samples) into ``work`` (n_samples, n_chirps·n_channels)
    complex64, then the range FFT in place with ``threads`` workers.

    The profiles are ``scale`` times the cube's: 1, unless the cube's largest component lies outside
    :data:`_SAFE_AMPLITUDE`, where it is 1/that (a second pass; the first pass's energy bounds the
    largest sample, so in-range cubes cost nothing more). Single precision holds powers of
    ~1e-38 to 3e38 W, so a cube of amplitude 1e20 √W would overflow |κ|² and one of 1e-20 √W lose
    its noise floor to underflow; rescaled, every finite cube keeps the same relative accuracy."""
    from xnlos_core.signal import kernels as kernels

    arr = _cube_array(cube, radar, finite=False)  # non-finite samples: found by the cast pass below
    n, d, k = arr.shape
    flat, taper = np.ascontiguousarray(arr).reshape(n, d * k), range_taper(radar.range_window, n)
    energy = np.empty(n)
    kernels.run(kernels.taper_cast, threads, flat, taper, 1.0, work, energy)
    bound = float(np.sqrt(energy.sum()))  # ≥ the largest |sample|; NaN or inf: a non-finite sample, or overflow
    if not np.isfinite(bound):
        bad = int(flat.size - np.count_nonzero(np.isfinite(flat)))
        if bad:
            raise InputError(f"chirp-sequence cube: {bad} of {arr.size} values are NaN or infinite; all must be finite")
    scale = 1.0
    if not bound <= _SAFE_AMPLITUDE[1] or bound < _SAFE_AMPLITUDE[0]:  # rare (0: all zero, or squares underflowed)
        big = float(np.max(np.maximum(np.abs(flat.real), np.abs(flat.imag))))
        if big > _SAFE_AMPLITUDE[1] or 0.0 < big < _SAFE_AMPLITUDE[0]:
            scale = 1.0 / big
            kernels.run(kernels.taper_cast, threads, flat, taper, scale, work, energy)
    prof = scipy.fft.fft(work, axis=0, overwrite_x=True, workers=threads)[: radar.n_range_bins].reshape(-1, d, k)
    if radar.coupling_compensation:
        prof = decouple(prof.reshape(-1, k), radar).reshape(-1, d, k).astype(np.complex64)
    return (prof - prof.mean(axis=1, keepdims=True) if remove_static else prof), scale


def _doppler_fft(prof: np.ndarray, window: str) -> np.ndarray:
    """Windowed (normalised by the window's sum) Doppler FFT over axis 1, fft-shifted."""
    w = _doppler_window(window, prof.shape[1])
    return np.fft.fftshift(np.fft.fft(prof * (w / w.sum())[None, :, None], axis=1), axes=1)


def _shift_modulation(n: int) -> np.ndarray:
    """(n,) factors e^{−j2π·m·c/n}, c = n − ⌊n/2⌋: FFT(x·mod) = fftshift(FFT(x)), so the shift costs no copy.
    For even n (the default 64) they are exactly ±1 (float64), so the product is exact."""
    m = np.arange(n)
    if n % 2 == 0:
        return np.where(m % 2 == 0, 1.0, -1.0)
    return np.exp(-2j * np.pi * m * ((n - n // 2) % n) / n)


FOLD_SNR = 20.0  # 13 dB: the Doppler bin's best beam over its noise floor above which its fold is tested
FOLD_MARGIN = 1.1  # a velocity outside the unambiguous span must beam this much higher than the one inside
FOLD_COHERENCE = 0.9  # ... and one plane wave must explain this share of the bin's signal under it (kernels._coherence)
FOLD_Z = 2.0  # ... and its beam's gain over κ = 0's must be this many σ of the noise's part of that gain
#                (kernels._fold_gain_sigma, Eq. F2): at 12–18 dB a neighbouring κ beamed 10–20 % higher by chance
FOLD_EDGE_COHERENCE = 0.97  # the least coherence where κ = 0's best beam is on the azimuth grid's edge: an echo
#                             beyond the grid under a neighbouring κ reached 0.92 there
REFINE_SNR = 10.0  # 10 dB: a cell's peak-bin power over its noise floor above which its velocity is refined
REFINE_HALF = 4  # the refinement's likelihood takes 2·4 + 1 unwindowed Doppler bins around the peak
NEWTON_STEPS = 4


def _fold_hypotheses(radar: RadarConfig, folds: int) -> tuple[np.ndarray, np.ndarray]:
    """(kappas (F,), hyps (n_chirps, max(F, 2))) int64 for :func:`doppler_ra_maps`' fold test.

    Doppler bin k (velocity v_k, ascending, v_0 = −v_max) stands for every v_k + 2κ·v_max; the test
    considers the κ whose velocity lies within ±(2·folds + 1)·v_max (bin 0, at −v_max, also gets
    κ = folds + 1, so the span is symmetric: at folds = 0 it decides between −v_max and +v_max, the
    unambiguous span's edge), ordered by |velocity| (κ = 0 first) and dropping a κ whose phase
    exp(−j2π·κ·i/N_tx) on every TX slot i equals an earlier one's (κ ≡ κ' mod N_tx: the array cannot
    tell them apart). hyps[k] lists the indices into kappas, −1 padded; one hypothesis: no test."""
    d, n_tdm, vmax = radar.n_chirps, radar.n_tdm, radar.max_unambiguous_velocity
    per_bin = []
    for v in radar.velocity_axis:
        ks = [kk for kk in range(-folds - 1, folds + 2)
              if abs(v + 2 * kk * vmax) <= (2 * folds + 1) * vmax * (1 + 1e-12)]
        ks.sort(key=lambda kk: (round(abs(v + 2 * kk * vmax) / vmax, 9), kk != 0))
        kept, seen = [], set()
        for kk in ks:
            if kk % n_tdm not in seen:
                seen.add(kk % n_tdm)
                kept.append(kk)
        per_bin.append(kept)
    kappas = np.array(sorted({kk for ks in per_bin for kk in ks}), dtype=np.int64)
    hyps = np.full((d, max(2, max(len(ks) for ks in per_bin))), -1, dtype=np.int64)
    for k, ks in enumerate(per_bin):
        hyps[k, :len(ks)] = [int(np.searchsorted(kappas, kk)) for kk in ks]
    return kappas, hyps


def _window_lobes(w: np.ndarray) -> tuple[float, int]:
    """(peak sidelobe power relative to the main lobe, main-lobe half width in bins, ≥ 1) of the window
    ``w``'s spectrum, from a 64× zero-padded FFT."""
    pad = 64
    spec = np.abs(np.fft.rfft(w, pad * len(w))) ** 2
    spec /= spec[0]
    rising = np.flatnonzero(np.diff(spec) > 0)
    if len(rising) == 0:  # no sidelobes resolved (n ≤ 2)
        return 0.0, 1
    first_null = int(rising[0])
    return float(spec[first_null:].max()), max(1, int(np.floor(first_null / pad + 1e-9)))


@dataclass(frozen=True)
class _DopplerPlan:
    """Everything :func:`doppler_ra_maps` needs that depends only on (radar, window), computed once.

    taper (n_chirps,) complex128: Doppler window / Σw times the fftshift modulation; boxcar (n_chirps,)
    complex128: the same for the unwindowed spectrum (1/N times the modulation); comp_r, comp_i (n_chirps,
    n_channels) float64: :func:`tdm_compensation`'s real and imaginary parts; wt_r, wt_i (n_azimuth,
    n_channels) float64: those of :func:`beam_weights`, transposed; ipos, ineg (H,) int64: the
    azimuths the kernel computes and their mirrors (:func:`~xnlos_core.signal.kernels.azimuth_pairs`);
    wa = [Re w | Im w], wb = [Im w | Re w] (n_channels, 2H) float32 of the ipos columns; enbw:
    N·Σw²/(Σw)² [bins]; sigma_cell: chirp noise / G_p [W]; velocity_axis (n_chirps,) [m/s] and
    consts (16,) float64: the kernel's constants (:func:`~xnlos_core.signal.kernels.beam_maps`, σ_cell
    for a cube that needs no rescaling); slot (n_channels,) int64: each channel's TX slot; kappas,
    hyps: :func:`_fold_hypotheses`. Arrays read-only (shared by calls).
    """

    taper: np.ndarray
    boxcar: np.ndarray
    comp_r: np.ndarray
    comp_i: np.ndarray
    wt_r: np.ndarray
    wt_i: np.ndarray
    ipos: np.ndarray
    ineg: np.ndarray
    wa: np.ndarray
    wb: np.ndarray
    velocity_axis: np.ndarray
    consts: np.ndarray
    slot: np.ndarray
    kappas: np.ndarray
    hyps: np.ndarray
    priors: np.ndarray
    enbw: float
    sigma_cell: float


def crlb_velocity(radar: RadarConfig, eta) -> np.ndarray:
    """Cramér–Rao bound σ_v [m/s] of the radial velocity of one complex tone in complex white Gaussian noise.

    eta: per-chirp SNR η = |a|²/σ² of the slow-time samples (linear, any shape). With N = n_chirps
    samples every T_s = n_tdm·T_c [s] (``radar.chirp_loop_time``), the frequency bound is (Rife &
    Boorstyn 1974, complex samples, amplitude and phase unknown)

        var(f̂_D) ≥ 6 / ((2π)²·η·N·(N² − 1)·T_s²)   [Hz²]                                  (V1)

    and v = λ₀·f_D/2 (λ₀ = ``radar.doppler_wavelength``) gives σ_v = λ₀/(4π·T_s)·√(6/(η·N·(N² − 1))).
    (A real tone's bound has 12 in place of 6: its η counts the power of one of two conjugate lines.)"""
    d = radar.n_chirps
    return radar.doppler_wavelength / (4 * np.pi * radar.chirp_loop_time) * np.sqrt(
        6.0 / (np.asarray(eta, dtype=np.float64) * d * (d**2 - 1.0)))


@functools.lru_cache(maxsize=16)
def _doppler_plan(radar: RadarConfig, window: str, folds: int = 1) -> _DopplerPlan:
    from xnlos_core.signal.kernels import azimuth_pairs  # numba: imported with the first Doppler map, not at startup

    d = radar.n_chirps
    w = _doppler_window(window, d)
    mod = _shift_modulation(d)
    weights = np.ascontiguousarray(beam_weights(radar))
    ipos, ineg = azimuth_pairs(weights)
    comp = tdm_compensation(radar)
    w32 = weights[:, ipos].astype(np.complex64)
    enbw = d * float((w**2).sum() / w.sum() ** 2)
    sigma_cell = chirp_noise_power(radar) / processing_gain(radar)
    crb = float(crlb_velocity(radar, 1.0))
    psl, lobe = _window_lobes(w)
    kappas, hyps = _fold_hypotheses(radar, folds)
    vmax = radar.max_unambiguous_velocity
    outside = np.abs(radar.velocity_axis[:, None] + 2 * vmax * kappas[hyps]) > vmax * (1 + 1e-9)
    priors = np.where(outside & (hyps >= 0), 1.0 / FOLD_MARGIN, 1.0)
    arrays = dict(taper=(mod * (w / w.sum())).astype(np.complex128), boxcar=(mod / d).astype(np.complex128),
                  comp_r=np.ascontiguousarray(comp.real), comp_i=np.ascontiguousarray(comp.imag),
                  wt_r=np.ascontiguousarray(weights.T.real), wt_i=np.ascontiguousarray(weights.T.imag),
                  ipos=ipos, ineg=ineg,
                  wa=np.ascontiguousarray(np.hstack([w32.real, w32.imag])),
                  wb=np.ascontiguousarray(np.hstack([w32.imag, w32.real])),
                  velocity_axis=np.array(radar.velocity_axis, dtype=np.float64),
                  consts=np.array([1.0 / enbw, np.tan(np.pi / d) / (np.pi / d), radar.velocity_resolution,
                                   radar.max_unambiguous_velocity, sigma_cell, crb, FOLD_SNR, REFINE_SNR,
                                   2.0 * psl, lobe, min(REFINE_HALF, (d - 1) // 2), radar.n_tdm, NEWTON_STEPS,
                                   FOLD_COHERENCE, FOLD_Z, FOLD_EDGE_COHERENCE]),
                  slot=np.repeat(np.arange(radar.n_tdm, dtype=np.int64), radar.n_channels // radar.n_tdm),
                  kappas=kappas, hyps=hyps, priors=priors)
    for a in arrays.values():
        a.flags.writeable = False
    return _DopplerPlan(**arrays, enbw=enbw, sigma_cell=sigma_cell)


def range_doppler(cube, radar: RadarConfig, *, window: str = "hann", remove_static: bool = False,
                  compensate: bool = True) -> np.ndarray:
    """Range FFT, coupling compensation, optional static-clutter removal, Doppler FFT and TDM compensation.

    cube: (n_samples, n_chirps, n_channels) complex [√W] (module doc). window: scipy window of the
    Doppler FFT, normalised by its sum. remove_static: subtract each range bin's and channel's
    mean over the chirps (zero-Doppler clutter; it removes a static target too). compensate:
    :func:`tdm_compensation`. Returns (n_range_bins, n_chirps, n_channels) complex128, Doppler
    bins ascending like ``radar.doppler_axis``. Raises InputError on a wrong shape or NaN.
    """
    rd = _doppler_fft(_range_profiles(cube, radar, remove_static), window)
    return rd * tdm_compensation(radar)[None] if compensate else rd


@dataclass(frozen=True)
class DopplerRAMaps:
    """Range–azimuth maps after Doppler processing, each (n_range_bins, n_azimuth_bins) float64.

    power: Σ_d|κ_d|²/ENBW_d [W], the Doppler-integrated power (a point target: |A|² at any
    velocity); peak_power: max_d|κ_d|² [W], the strongest Doppler bin (coherent gain over the
    chirps, minus the window's scalloping ≤ 1.42 dB for Hann); velocity: v̂_r [m/s] of the
    strongest bin, interpolated; velocity_std: its σ [m/s] (:func:`doppler_ra_maps`);
    noise_floor / peak_noise_floor: expected value [W] of ``power`` / ``peak_power``'s bin in a
    noise-only cell.
    """

    power: np.ndarray
    peak_power: np.ndarray
    velocity: np.ndarray
    velocity_std: np.ndarray
    noise_floor: float
    peak_noise_floor: float
    radar: RadarConfig

    def ra_map(self, which: Literal["power", "peak_power"] = "power") -> RAMap:
        """RAMap whose |κ|² is ``power`` (or ``peak_power``), phase 0, for the detectors of the RA path."""
        return RAMap.from_radar(np.sqrt(getattr(self, which)).astype(np.complex64), self.radar)


_WORK = threading.local()


def _work_buffers(radar: RadarConfig) -> tuple[np.ndarray, np.ndarray]:
    """This thread's scratch arrays of :func:`doppler_ra_maps` for ``radar``'s size: (n_samples,
    n_chirps·n_channels) and (2, n_range_bins, n_chirps, n_channels) complex64 (8 + 13 MB at the default
    size). Kept between calls: fresh ones would be paged in on every frame (≈ 2–3 ms of page faults);
    one pair per thread, replaced when the size changes."""
    shapes = ((radar.n_samples, radar.n_chirps * radar.n_channels),
              (2, radar.n_range_bins, radar.n_chirps, radar.n_channels))
    bufs = getattr(_WORK, "bufs", None)
    if bufs is None or tuple(b.shape for b in bufs) != shapes:
        bufs = _WORK.bufs = tuple(np.empty(s, dtype=np.complex64) for s in shapes)
    return bufs


def measured_cell_noise(spectrum: np.ndarray, radar: RadarConfig, window: str = "hann") -> float:
    """σ_cell [W] (the expected ``power`` of a noise-only RA cell, :attr:`DopplerRAMaps.noise_floor`)
    measured in a windowed range–Doppler spectrum (n_range_bins, n_chirps, n_channels), Doppler bins
    ascending, normalised like :func:`range_doppler` (in the spectrum's own units).

    Per channel, a noise-only cell of the spectrum is circular Gaussian of power
    m = σ_c²·Σw_r²/(Σw_r)²·Σw_d²/(Σw_d)² (σ_c² the per-chirp noise per sample), so |X|² is
    exponential and its median is m·ln 2. The median over the cells is robust to echoes in up to half
    of them; the three Doppler bins around zero (static clutter and its Hann leakage) are left out when
    n_chirps ≥ 8. Beamforming then gives σ_cell = σ_c²/G_p = m · (Σw_a²/(Σw_a)²)/(Σw_d²/(Σw_d)²), the beam
    factor Σ_k|w_k|² of :func:`~xnlos_core.signal.chain.beam_weights` (averaged over the azimuths)
    (:mod:`xnlos_core.signal.chain`). Assumes white noise, uncorrelated across channels (coupling
    compensation correlates it a little). Returns the smallest positive float when the spectrum is
    zero (noise-free data), so that η stays defined.
    """
    d = spectrum.shape[1]
    keep = np.ones(d, bool)
    if d >= 8:
        keep[d // 2 - 1:d // 2 + 2] = False  # zero Doppler at d//2 (bins ascending, fft-shifted)
    cells = spectrum[:, keep]
    m = float(np.median(cells.real.astype(np.float64) ** 2 + cells.imag.astype(np.float64) ** 2)) / np.log(2.0)
    wd = _doppler_window(window, d)
    beam = float(np.mean(np.sum(np.abs(beam_weights(radar)) ** 2, axis=0)))  # Σw_a²/(Σw_a)², from the beams used
    sigma = m * beam / float((wd**2).sum() / wd.sum() ** 2)
    return sigma if np.isfinite(sigma) and sigma > 0 else float(np.finfo(np.float64).tiny)


def doppler_ra_maps(cube, radar: RadarConfig, *, window: str = "hann", remove_static: bool = False,
                    workers: int | None = None, noise: Literal["model", "measured"] = "model",
                    folds: int = 1) -> DopplerRAMaps:
    """Chirp-sequence cube → :class:`DopplerRAMaps`: :func:`range_doppler`, then beamforming per Doppler bin.

    Velocity per cell: the strongest bin k of the windowed spectrum; on the unwindowed spectrum,
    TDM-compensated with bin k's f_D (and its fold, below) and beamformed at the cell's azimuth, Candan's
    three-bin estimate δ = tan(π/N)/(π/N)·Re[(X_{k−1} − X_{k+1}) / (2X_k − X_{k−1} − X_{k+1})] starts.
    Where the cell's peak bin is :data:`REFINE_SNR` (10 dB) over its noise floor (``peak_noise_floor``),
    Newton steps maximise the likelihood of one complex tone given the 2L + 1 = 9 unwindowed bins
    around k: with Z̃_o = X_{k+o}·exp(jπ·o·(N − 1)/N) and the real kernel R(x) = sin(πx)/sin(πx/N),

        ℓ(δ) = (N/σ_cell)·|Σ_o Z̃_o·R(δ − o)|² / Σ_o R(δ − o)²                                    (V2)

    (the bins' noise is σ_cell/N each), and σ_δ² = 1/(−ℓ''(δ̂)) [bins²], σ_v = Δv·σ_δ: the observed
    information of the same likelihood, so ±1.96σ covers 95 % on and off the grid. On all N bins ℓ'' is
    (2π)²·η·N·(N² − 1)/6 per cycle² and σ_v the bound of :func:`crlb_velocity` (Eq. V1); the 9 bins keep
    all but ≤ 7 % of that information on the grid and all of it half a bin off (RMSE 0.94–1.09× the
    bound at 10–30 dB, benchmarks/doppler_velocity.md). A step that ends more than 0.3 bin from the
    start (another tone's lobe) keeps the three-bin δ. Other cells: the three-bin δ, and σ_v the bound of
    Eq. V1 at η = power/σ_cell − 1 (floored at 1e-12), which holds above the estimator's threshold
    (η·N ≳ 10 dB). v̂ = λ₀/2·(f_k + δ/(N·T_s)) + 2κ·v_max.

    Folds (TDM-MIMO): TX i fires i·T_c into each loop, so bin k stands for f_k + κ/T_s (v + 2κ·v_max) and
    hypothesis κ compensates TX i's channels with exp(−j2π(f_k + κ/T_s)·i·T_c), an extra exp(−j2π·κ·i/N_tx)
    that the array can see: only the right κ makes the virtual array's phases a plane wave. At each Doppler
    bin that is a local maximum of the range bin's beam energy, within the window's sidelobe level of its
    strongest bin and whose best beam is :data:`FOLD_SNR` (13 dB) over its floor, every κ of
    :func:`_fold_hypotheses` (``folds``: κ within ±(2·folds + 1)·v_max; the −v_max bin also as +v_max) is
    beamformed over all azimuths and the highest peak wins, a κ outside the span only when it beats the
    one inside by :data:`FOLD_MARGIN` (10 %) and one plane wave explains at least :data:`FOLD_COHERENCE`
    (90 %) of the bin's signal under it (Eq. F1 of :func:`xnlos_core.signal.kernels._coherence`: a wall's
    static echoes from several azimuths in one bin can beam higher under a neighbouring κ by chance, and
    were then reported at ±2·v_max), and only when its gain over κ = 0's beam is :data:`FOLD_Z` (2) standard
    deviations of the noise's share in that gain or more (Eq. F2 of
    :func:`xnlos_core.signal.kernels._fold_gain_sigma`: a right κ gains ≈ 15–18 % of the beam over a
    neighbouring one on the default 4-TX array, which noise matches at 12–18 dB, where weak mirrored cars
    were reported at ±36 m/s. One echo in the span at 12–18 dB peak SNR: wrong folds 9 of 900 without the
    rule, 0 with it; one beyond v_max: unfolded in 93 % of 300 at 22 dB (94 % without), 65 % at 19 dB
    (83 %), 3 % at 12 dB (9 %)). Where κ = 0's best beam lies on the azimuth grid's first or last column the
    echo may lie beyond the grid: κ = 0's peak is not seen there while a neighbouring κ steers the beam inside
    and wins; such a fold needs :data:`FOLD_EDGE_COHERENCE` (97 %) (one echo in the span 4–6° beyond the ±60°
    grid at 19–23 dB: wrong folds 8 of 80 with 90 %, 1 with 97 %; one beyond v_max at 55–58°: kept folded
    in 4 of 80, none before); the bins of that peak's main lobe take its κ, their beams are
    recomputed, and their velocities are reported unfolded (elsewhere folded into [−v_max, v_max)). κ ≡ κ'
    mod N_tx cannot be told apart (one TX: no test).

    Implementation (:mod:`xnlos_core.signal.kernels`, numba): the range and Doppler FFTs run in
    single precision (:func:`scipy.fft.fft`) and everything after them in compiled kernels, one range
    bin per task: the beams of each Doppler bin from two small float32 products per range bin (the
    mirrored half of the azimuth grid comes from the same products), then the sum, maximum, argmax and
    the velocity (double precision) while that range bin is in cache. Windows, compensation and
    weights are computed once per (radar, window) (:func:`_doppler_plan`), scratch arrays once per
    thread and size (:func:`_work_buffers`). Against a double-precision evaluation the maps agree
    within 1e-6 of their maximum and cell by cell within 1e-3 (the largest differences in noise
    cells ~95 dB below the maximum), the velocities to 1e-4 m/s (median; ≤ 1e-5 m/s on targets),
    tests/unit/test_dechirp_fast.py. 7.8–8.6 ms per default-size frame with ``workers=2`` on 2 cores
    (42 ms in numpy), benchmarks/dechirp_speed.md. The first call of a process loads the compiled
    kernels from numba's cache (≈ 0.5 s; ≈ 5 s to compile them when the cache is empty).

    workers: threads of the FFTs and of the kernels (None: one, the thread policy's choice for
    simulation workers); BLAS is held to one thread during the kernels.

    folds: velocity folds tested on each side of the unambiguous span (0: only its edge; 0–8).

    noise: where σ_cell² comes from. "model": the radar's thermal noise (:func:`chirp_noise_power`),
    right for simulated cubes, whose amplitudes are in √W. "measured": the noise floor of the cube's
    own range–Doppler spectrum (:func:`measured_cell_noise`), for recorded data, whose amplitude
    scale (``[recording] scale``) is arbitrary: η, hence σ_v, is then the same for the cube times any
    factor, and ``noise_floor`` is the measured one.
    """
    if noise not in ("model", "measured"):
        raise InputError(f"doppler_ra_maps: noise must be 'model' or 'measured', got {noise!r}")
    if radar.n_chirps < 3:
        raise InputError(f"doppler_ra_maps: Doppler processing needs n_chirps ≥ 3 (three-bin velocity "
                         f"interpolation), this radar has n_chirps={radar.n_chirps}")
    from xnlos_core.signal import kernels as kernels  # numba: imported with the first Doppler map, not at startup

    threads = max(1, workers or 1)
    if isinstance(folds, bool) or not isinstance(folds, (int, np.integer)) or not 0 <= folds <= 8:
        raise InputError(f"doppler_ra_maps: folds must be an integer from 0 to 8 (velocity folds tested each side "
                         f"of the unambiguous span), got {folds!r}")
    plan = _doppler_plan(radar, window, int(folds))
    work, spec = _work_buffers(radar)
    prof, scale = _range_profiles32(cube, radar, remove_static, threads, work)  # (r, d, k) complex64, scale·cube
    r, d, k = prof.shape
    # both Doppler spectra (windowed for the maps, unwindowed for the velocity) in one FFT call; the
    # fftshift is a modulation folded into the tapers, so the bins come out ascending
    kernels.run(kernels.doppler_tapers, threads, prof, plan.taper, plan.boxcar, spec)
    spec = scipy.fft.fft(spec, axis=2, overwrite_x=True, workers=threads)
    n_az, consts = radar.n_azimuth_bins, plan.consts.copy()  # writable: one compiled signature of the kernel
    scale2 = 1.0
    if scale != 1.0:
        with np.errstate(over="ignore"):  # a cube below ~1e-154 √W: its powers are below float64's range anyway
            scale2 = np.float64(scale) ** 2
        consts[4] *= scale2  # σ_cell in the rescaled cube's units
    if noise == "measured":  # in the rescaled cube's units already: measured on its spectrum
        consts[4] = measured_cell_noise(spec[0], radar, window)
    power, peak_power, v, v_std = (np.empty((r, n_az)) for _ in range(4))
    with blas_limit(1):  # one small product per range bin and numba thread: BLAS threads would only compete
        kernels.run(kernels.beam_maps, threads, spec[0], spec[1], plan.comp_r, plan.comp_i, plan.wa, plan.wb,
                    plan.ipos, plan.ineg, plan.wt_r, plan.wt_i, plan.velocity_axis, consts, plan.slot,
                    plan.kappas, plan.hyps, plan.priors, power, peak_power, v, v_std)
    if scale != 1.0:  # back to the cube's own units
        power /= scale2
        peak_power /= scale2
    sigma_cell, enbw = plan.sigma_cell, plan.enbw
    if noise == "measured":
        with np.errstate(over="ignore"):
            sigma_cell = float(consts[4] / scale2)
    return DopplerRAMaps(power=power, peak_power=peak_power, velocity=v, velocity_std=v_std,
                         noise_floor=sigma_cell, peak_noise_floor=sigma_cell * enbw / d, radar=radar)
