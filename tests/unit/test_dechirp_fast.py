"""Fast dechirp and Doppler chain: equal to straightforward
reference implementations kept here (one complex exponential per sample; np.fft with fftshift copies,
beamforming per Doppler bin in (range, Doppler, azimuth) layout, per-cell compensated weights)."""
import numpy as np
import pytest
from scipy.signal import get_window

from xnlos_core.signal.antenna import coupling_matrix, steering_vector
from xnlos_core.signal.doppler import (REFINE_HALF, REFINE_SNR, add_chirp_noise, chirp_noise_power,
                                       chirp_sequence_cube, chirp_start_times, crlb_velocity, doppler_ra_maps,
                                       tdm_compensation)
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.chain import beam_weights, dechirp, decouple, processing_gain, range_fft, sample_times

RADAR = RadarConfig()  # the default (largest default) size: 512 samples, 64 loops, 32 channels
COUPLED = RadarConfig(n_samples=509, coupling_db=-15.0, coupling_phase=0.7)  # prime N: padded blocks
SMALL = RadarConfig(n_samples=64, max_range=15.0, n_tx=2, n_rx=4, n_chirps=33, n_azimuth_bins=9, field_of_view=0.8,
                    coupling_db=-20.0, coupling_compensation=True)  # odd n_chirps: complex shift modulation


def ref_dechirp(radar, L, th, a, el=None):
    """Eq. 6 sample by sample: exp(j2π(f_b t_n + f_c τ − S τ²/2)) per sample and path."""
    el = np.zeros_like(th) if el is None else el
    tau = L / SPEED_OF_LIGHT
    fb = radar.chirp_slope * tau
    keep = (fb >= 0) & (fb < radar.sample_rate) & (a != 0)
    L, th, a, tau, fb, el = L[keep], th[keep], a[keep], tau[keep], fb[keep], el[keep]
    phase0 = np.mod(L / radar.wavelength, 1.0) - 0.5 * radar.chirp_slope * tau**2
    tones = np.exp(2j * np.pi * (np.outer(sample_times(radar), fb) + phase0))
    cube = (tones * a) @ steering_vector(radar, th, el).T
    c = coupling_matrix(radar)
    return cube if c is None else cube @ c.T


def _rel(new, old):
    return float(np.abs(new - old).max() / np.abs(old).max())


def _paths(radar, p, seed):
    rng = np.random.default_rng(seed)
    L = rng.uniform(-1.0, 2.4 * radar.max_range, p)  # some beyond the unambiguous range, some negative
    a = rng.standard_normal(p) + 1j * rng.standard_normal(p)
    a[::17] = 0
    return L, rng.uniform(-1.2, 1.2, p), a, rng.uniform(-0.3, 0.3, p)


@pytest.mark.parametrize("radar", [RADAR, COUPLED], ids=["default", "coupled-prime-N"])
def test_dechirp_equals_per_sample_exponentials(radar):
    L, th, a, el = _paths(radar, 2100, 0)  # more than one chunk of 2048 paths
    new, old = dechirp(radar, L, th, a, el), ref_dechirp(radar, L, th, a, el)
    assert new.shape == (radar.n_samples, radar.n_channels) and new.flags.c_contiguous
    assert _rel(new, old) < 1e-11  # no accumulated rounding over the 512 samples (target 1e-5)
    # the last samples, where a recurrence would drift most, on their own
    assert _rel(new[-8:], old[-8:]) < 1e-11
    assert np.array_equal(dechirp(radar, [], [], []), np.zeros((radar.n_samples, radar.n_channels)))


def test_chirp_sequence_cube_equals_a_dechirp_per_tx_slot():
    rng = np.random.default_rng(1)
    radar = SMALL
    r, th = rng.uniform(1.0, 14.0, 7), rng.uniform(-0.7, 0.7, 7)
    a, v = rng.standard_normal(7) + 1j * rng.standard_normal(7), rng.uniform(-8.0, 8.0, 7)
    n_rx = radar.n_channels // radar.n_tdm
    ref = np.zeros((radar.n_samples, radar.n_chirps, radar.n_channels), complex)
    for m, starts in enumerate(chirp_start_times(radar)):
        for i, t in enumerate(starts):
            ch = slice(i * n_rx, (i + 1) * n_rx)
            ref[:, m, ch] = ref_dechirp(radar, 2.0 * (r + v * t), th, a)[:, ch]
    assert _rel(chirp_sequence_cube(radar, r, th, a, v), ref) < 1e-11


def test_range_fft_equals_numpy_fft():
    rng = np.random.default_rng(2)
    cube = rng.standard_normal((RADAR.n_samples, 6)) + 1j * rng.standard_normal((RADAR.n_samples, 6))
    w = get_window(RADAR.range_window, RADAR.n_samples, fftbins=False)
    ref = np.fft.fft(cube * (w / w.sum())[:, None], axis=0)[: RADAR.n_range_bins]
    assert _rel(range_fft(cube, RADAR), ref) < 1e-13
    assert _rel(range_fft(cube, RADAR, workers=2), ref) < 1e-13


def ref_doppler_ra_maps(cube, radar, window="hann", remove_static=False):
    """doppler_ra_maps in double precision throughout, without the fold test (these cubes' movers are
    inside the unambiguous span): returns power, peak_power, peak bin, velocity, velocity_std and the
    refined cells."""
    n, d, k = cube.shape
    prof = decouple(range_fft(cube.reshape(n, d * k), radar).reshape(-1, k), radar).reshape(-1, d, k)
    if remove_static:
        prof = prof - prof.mean(axis=1, keepdims=True)

    def dfft(x, name):
        w = get_window(name, d, fftbins=False)
        return np.fft.fftshift(np.fft.fft(x * (w / w.sum())[None, :, None], axis=1), axes=1)

    r = prof.shape[0]
    comp = tdm_compensation(radar)
    weights = beam_weights(radar)
    rd_w = dfft(prof, window) * comp[None]
    bf = (rd_w.reshape(r * d, k) @ weights).reshape(r, d, -1)  # double precision throughout
    pw = np.abs(bf) ** 2
    w = get_window(window, d, fftbins=False)
    enbw = d * (w**2).sum() / w.sum() ** 2
    power = pw.sum(axis=1, dtype=np.float64) / enbw
    peak = np.argmax(pw, axis=1)
    peak_power = np.take_along_axis(pw, peak[:, None, :], axis=1)[:, 0].astype(np.float64)
    rd_r = dfft(prof, "boxcar")
    rows = np.arange(r)[:, None]
    xm, x0, xp = (np.einsum("rak,ka->ra", rd_r[rows, (peak + o) % d] * comp[peak], weights) for o in (-1, 0, 1))
    den = 2 * x0 - xm - xp
    delta = np.where(np.abs(den) > 0, np.real((xm - xp) / np.where(np.abs(den) > 0, den, 1.0)), 0.0)
    delta = np.clip(np.tan(np.pi / d) / (np.pi / d) * delta, -0.5, 0.5)
    vmax = radar.max_unambiguous_velocity
    sigma_cell = chirp_noise_power(radar) / processing_gain(radar)
    eta = np.maximum(power / sigma_cell - 1.0, 1e-12)
    v_std = radar.doppler_wavelength / (4 * np.pi * radar.chirp_loop_time) * np.sqrt(6.0 / (eta * d * (d**2 - 1.0)))
    # refinement where the peak bin is REFINE_SNR over its floor: the tone's likelihood on 2L + 1 unwindowed
    # bins, max_u |Σ_q Z_q·D(u − q)|² / Σ_q |D(u − q)|², D(x) = Σ_m exp(−j2πxm/N) (closed form), searched on
    # a grid of 1e-3 bins ±0.3 bins about the three-bin start, then a parabola through the best three
    ml = peak_power >= REFINE_SNR * sigma_cell * enbw / d
    half = min(REFINE_HALF, (d - 1) // 2)
    ri, ai = np.nonzero(ml)
    pk = peak[ri, ai]
    offs = np.arange(-half, half + 1)
    x = np.stack([np.einsum("nk,nk->n", rd_r[ri, (pk + o) % d] * comp[pk], weights[:, ai].T) for o in offs], 1)
    q = (pk - d // 2)[:, None] + offs[None, :]  # unwrapped frequency index of each bin [bins]

    def dk(u):  # (n, G) → (n, G, 2L+1) D(u − q)
        y = u[:, :, None] - q[:, None, :]
        small = np.abs(np.sin(np.pi * y / d)) < 1e-12
        ratio = np.sin(np.pi * y) / np.where(small, 1.0, np.sin(np.pi * y / d))
        return np.exp(-1j * np.pi * y * (d - 1) / d) * np.where(small, d, ratio)

    def f(u):
        k_ = dk(u)
        return np.abs(np.einsum("nq,ngq->ng", x, k_)) ** 2 / np.sum(np.abs(k_) ** 2, axis=2)

    start = (pk - d // 2) + delta[ri, ai]
    grid = start[:, None] + np.arange(-0.3, 0.3 + 1e-9, 1e-3)[None, :]
    vals = f(grid)
    best = np.argmax(vals, axis=1)
    inside = (best > 0) & (best < grid.shape[1] - 1)  # at the edge: another tone's lobe, the three-bin value stays
    j = np.clip(best, 1, grid.shape[1] - 2)
    rows = np.arange(len(j))
    y0, y1, y2 = vals[rows, j - 1], vals[rows, j], vals[rows, j + 1]
    u = grid[rows, j] + 0.5e-3 * (y0 - y2) / (y0 - 2 * y1 + y2)
    h = 1e-3
    curv = (f((u + h)[:, None]) - 2 * f(u[:, None]) + f((u - h)[:, None]))[:, 0] / h**2
    v = radar.velocity_axis[peak] + delta * radar.velocity_resolution
    ok = inside & (curv < 0)
    v[ri[ok], ai[ok]] = u[ok] * radar.velocity_resolution
    v = np.mod(v + vmax, 2 * vmax) - vmax
    v_std[ri[ok], ai[ok]] = radar.velocity_resolution * np.sqrt(sigma_cell / (d * -curv[ok]))
    return power, peak_power, peak, v, v_std, ml


def _check_maps(new, radar, ref):
    power, peak_power, peak, v, v_std, ml = ref
    # doppler_ra_maps runs in single precision (range and Doppler FFTs, beams), this reference in double:
    # within 1e-6 of each map's maximum (measured 2.4e-7), and cell by cell within 1e-3 (measured 3.4e-4,
    # in a noise cell 95 dB below the maximum; the first, partly double-precision version was 3.3e-5 off)
    for fast, exact in ((new.power, power), (new.peak_power, peak_power)):
        assert np.abs(fast - exact).max() <= 1e-6 * exact.max()
        assert np.allclose(fast, exact, rtol=1e-3, atol=0)
    # the strongest Doppler bin: a cell whose two best bins are within single-precision rounding may
    # pick either (none did in these cubes, ≤ 0.1 % allowed); everywhere else the velocity agrees
    # (≤ 0.1 % allowed); a cell with the leakage of two movers (range sidelobes) has a likelihood with
    # several maxima, where Newton steps and this grid search may settle on different ones (≤ 1 % in all)
    dv = np.abs(new.velocity - v)
    assert (dv > 1e-3).mean() <= 1e-2
    assert np.median(dv) < 1e-4  # m/s; the bins are 0.57 m/s (default) and 2.2 m/s (SMALL) wide
    # refined cells (the likelihood's σ): the same cells but a few at the threshold
    d = radar.n_chirps
    refined = new.peak_power >= REFINE_SNR * new.peak_noise_floor
    assert (refined != ml).mean() <= 1e-3
    both = refined & ml & (dv <= 1e-3)
    assert (refined & ml).sum() - both.sum() <= 1e-2 * dv.size
    # (single-precision spectra: the curvature of a flat likelihood at 10 dB differs by ≤ 1.3e-3 measured)
    assert np.allclose(new.velocity_std[both], v_std[both], rtol=5e-3, atol=0)
    # elsewhere σ_v is a closed form of the cell's power, ∝ 1/√(power/σ² − 1): ill-conditioned where
    # power ≈ σ², so compared where the per-chirp SNR η ≥ 1 and checked as that closed form of new.power
    eta = power / new.noise_floor - 1.0
    rest = ~refined & ~ml
    assert np.allclose(new.velocity_std[rest & (eta >= 1)], v_std[rest & (eta >= 1)], rtol=1e-3, atol=0)
    closed = crlb_velocity(radar, np.maximum(new.power / new.noise_floor - 1.0, 1e-12))
    assert np.allclose(new.velocity_std[~refined], closed[~refined], rtol=1e-12)


def test_doppler_ra_maps_equal_the_reference_at_the_default_size():
    cube = add_chirp_noise(chirp_sequence_cube(RADAR, [20.0, 35.0, 61.3], [0.3, -0.2, 0.05],
                                               [1e-4, 3e-5, 2e-5], [5.0, -1.3, 11.0]), RADAR, np.random.default_rng(3))
    ref = ref_doppler_ra_maps(cube, RADAR)
    _check_maps(doppler_ra_maps(cube, RADAR), RADAR, ref)
    _check_maps(doppler_ra_maps(cube, RADAR, workers=2), RADAR, ref)
    # the movers themselves: same bin, velocity to 1e-5 m/s (Δv = 0.57 m/s)
    new = doppler_ra_maps(cube, RADAR)
    cells = np.unravel_index(np.argsort(ref[1], axis=None)[-3:], ref[1].shape)
    assert np.allclose(new.velocity[cells], ref[3][cells], atol=1e-5, rtol=0)


@pytest.mark.parametrize("window,remove_static", [("hann", True), ("boxcar", False)])
def test_doppler_ra_maps_equal_the_reference_odd_chirps_coupling(window, remove_static):
    rng = np.random.default_rng(4)
    cube = add_chirp_noise(chirp_sequence_cube(SMALL, [4.0, 9.5], [0.2, -0.4], [1e-4, 5e-5], [3.0, 0.0]), SMALL, rng)
    _check_maps(doppler_ra_maps(cube, SMALL, window=window, remove_static=remove_static), SMALL,
                ref_doppler_ra_maps(cube, SMALL, window=window, remove_static=remove_static))


def test_both_forward_models_render_through_the_fast_path():
    """The image model and the ray tracer share sims.render.render_paths, which synthesises with these."""
    import sims.image
    import sims.raytrace.model
    import sims.render
    assert sims.image.render_paths is sims.render.render_paths is sims.raytrace.model.render_paths
    assert sims.render.dechirp is dechirp and sims.render.chirp_sequence_cube is chirp_sequence_cube
    assert sims.render.doppler_ra_maps is doppler_ra_maps
