"""The compiled Doppler kernels (xnlos_core.signal.kernels): mirrored azimuth pairs, the unpaired
fallback, non-finite input, thread counts, calls from several threads at once, a forked child, and
cubes beyond single precision's range."""
import threading

import numpy as np
import pytest

from xnlos_core.signal import doppler

from xnlos_core.signal import kernels as doppler_kernels
from xnlos_core.signal.doppler import REFINE_SNR, add_chirp_noise, chirp_sequence_cube, crlb_velocity, doppler_ra_maps
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import beam_weights

SMALL = RadarConfig(n_samples=64, max_range=15.0, n_tx=2, n_rx=4, n_chirps=16, n_azimuth_bins=9, field_of_view=0.8)


def _cube(radar, seed=0):
    return add_chirp_noise(chirp_sequence_cube(radar, [4.0, 9.5], [0.2, -0.4], [1e-4, 5e-5], [3.0, -1.0]), radar,
                           np.random.default_rng(seed))


def test_a_symmetric_grid_is_computed_in_mirrored_pairs():
    ipos, ineg = doppler_kernels.azimuth_pairs(beam_weights(SMALL))
    assert ipos.tolist() == [4, 5, 6, 7, 8] and ineg.tolist() == [-1, 3, 2, 1, 0]
    ipos, ineg = doppler_kernels.azimuth_pairs(beam_weights(RadarConfig(n_azimuth_bins=8)))
    assert ipos.tolist() == [4, 5, 6, 7] and ineg.tolist() == [3, 2, 1, 0]


def test_weights_that_are_not_mirror_conjugates_are_computed_one_by_one():
    w = beam_weights(SMALL)
    w[0, 0] *= 1.0 + 1e-6
    ipos, ineg = doppler_kernels.azimuth_pairs(w)
    assert ipos.tolist() == list(range(9)) and (ineg == -1).all()


def test_the_unpaired_kernel_gives_the_paired_maps(monkeypatch):
    cube = _cube(SMALL)
    paired = doppler_ra_maps(cube, SMALL)
    n = SMALL.n_azimuth_bins
    monkeypatch.setattr(doppler_kernels, "azimuth_pairs",
                        lambda w: (np.arange(n, dtype=np.int64), np.full(n, -1, dtype=np.int64)))
    doppler._doppler_plan.cache_clear()
    try:
        assert doppler._doppler_plan(SMALL, "hann").ipos.size == n
        single = doppler_ra_maps(cube, SMALL)
    finally:
        doppler._doppler_plan.cache_clear()
    for name in ("power", "peak_power"):
        a, b = getattr(single, name), getattr(paired, name)
        assert np.abs(a - b).max() <= 1e-6 * b.max()
    assert np.allclose(single.velocity, paired.velocity, atol=1e-4, rtol=0)


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf * 1j])
def test_non_finite_samples_are_an_input_error_with_their_count(bad):
    cube = _cube(SMALL)
    cube[3, 2, 1] = bad
    cube[5, 0, 0] = bad
    with pytest.raises(InputError, match=r"chirp-sequence cube: 2 of 8192 values are NaN or infinite"):
        doppler_ra_maps(cube, SMALL)


def test_workers_beyond_the_pool_are_clamped_and_give_the_same_maps():
    cube = _cube(SMALL, 1)
    one = doppler_ra_maps(cube, SMALL, workers=1)
    many = doppler_ra_maps(cube, SMALL, workers=64)
    assert np.array_equal(one.power, many.power) and np.array_equal(one.velocity, many.velocity)


def test_threads_calling_at_once_get_their_own_maps():
    radars = [SMALL, RadarConfig(n_samples=128, max_range=25.0, n_chirps=8, n_azimuth_bins=31)]
    cubes = [_cube(r, 7) for r in radars]
    want = [doppler_ra_maps(c, r) for c, r in zip(cubes, radars)]
    got, errors = {}, []

    def work(i):
        try:
            for _ in range(5):
                got[i] = doppler_ra_maps(cubes[i % 2], radars[i % 2], workers=2)
        except Exception as exc:  # pragma: no cover - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work, args=(i,)) for i in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not errors
    for i, maps in got.items():
        assert np.array_equal(maps.power, want[i % 2].power)
        assert np.array_equal(maps.velocity, want[i % 2].velocity)


def _child_maps(cube, queue):
    queue.put(doppler_ra_maps(cube, SMALL, workers=2).power)


@pytest.mark.skipif(not hasattr(__import__("os"), "fork"), reason="fork start method only")
def test_a_forked_child_computes_maps_after_its_parent():
    """numba's GNU OpenMP layer aborts such a child; the kernels run on the fork-safe work queue."""
    import multiprocessing as mp

    cube = _cube(SMALL, 3)
    want = doppler_ra_maps(cube, SMALL, workers=2).power
    ctx = mp.get_context("fork")
    queue = ctx.Queue()
    child = ctx.Process(target=_child_maps, args=(cube, queue))
    child.start()
    got = queue.get(timeout=30)
    child.join(timeout=30)
    assert child.exitcode == 0 and np.array_equal(got, want)


@pytest.mark.parametrize("gain", [1e25, 1e-22])
def test_cubes_beyond_single_precision_range_are_rescaled(gain):
    """|κ|² of a 1e25 √W cube would overflow float32 and a 1e-22 √W cube's noise would underflow;
    the chain rescales them internally, so the maps scale by gain² and the velocities stay the same."""
    cube = _cube(SMALL, 5)
    # the measured noise floor scales with the cube, so every SNR-gated choice (refinement, fold test) is
    # the same for both; against the radar's model floor a 1e25 √W cube's noise is itself a 500 dB "echo"
    unit = doppler_ra_maps(cube, SMALL, noise="measured")
    far = doppler_ra_maps(cube * gain, SMALL, noise="measured")
    for name in ("power", "peak_power"):
        a, b = getattr(far, name) / gain**2, getattr(unit, name)
        assert np.isfinite(a).all() and (a > 0).all()
        assert np.abs(a - b).max() <= 1e-5 * b.max() and np.allclose(a, b, rtol=1e-3, atol=0)
    # velocity: as for any change of rounding (a gain of 1 + 1e-7 does the same), a noise cell whose two
    # best Doppler bins are within float32 rounding may pick the other one (1 of these 549 cells)
    dv = np.abs(far.velocity - unit.velocity)
    assert (dv > 1e-3).mean() <= 0.01 and np.median(dv) < 1e-4
    snr = unit.power / unit.noise_floor - 1.0  # σ_v ∝ 1/√snr is ill-conditioned where snr ≈ 0: compared where ≥ 1
    assert np.allclose(far.velocity_std[snr >= 1], unit.velocity_std[snr >= 1], rtol=1e-3)
    assert far.noise_floor / gain**2 == pytest.approx(unit.noise_floor, rel=1e-5)
    # against the radar's own noise floor σ_v shrinks by the gain (the rescaling must not leak into it): in
    # the cells refined at both scales, σ_v·gain is the unit cube's; the others' σ_v is the closed form
    plain_unit, far = doppler_ra_maps(cube, SMALL), doppler_ra_maps(cube * gain, SMALL)
    assert far.noise_floor == plain_unit.noise_floor
    both = ((plain_unit.peak_power >= REFINE_SNR * plain_unit.peak_noise_floor)
            & (far.peak_power >= REFINE_SNR * far.peak_noise_floor))
    both &= np.abs(far.velocity - plain_unit.velocity) <= 1e-3  # the same maximum of the likelihood
    assert both.any() or gain < 1  # a 1e-22 √W cube is below the radar's noise everywhere
    # (median: the likelihood's curvature is taken where its Newton steps end, which rounding moves a little)
    assert not both.any() or np.median(np.abs(far.velocity_std[both] * gain / plain_unit.velocity_std[both] - 1)) < 1e-3
    plain = far.peak_power < REFINE_SNR * far.peak_noise_floor
    eta = np.maximum(far.power / far.noise_floor - 1.0, 1e-12)
    assert np.allclose(far.velocity_std[plain], crlb_velocity(SMALL, eta)[plain], rtol=1e-9)


def test_a_cube_whose_squares_underflow_still_gives_its_velocities():
    """At 1e-170 √W even float64 squares underflow (the energy sum is 0, the powers are below float64's
    range and come out 0), yet the rescaled chain still finds every mover's velocity."""
    cube = _cube(SMALL, 5)
    unit, tiny = doppler_ra_maps(cube, SMALL, noise="measured"), doppler_ra_maps(cube * 1e-170, SMALL, noise="measured")
    assert np.isfinite(tiny.power).all() and (tiny.power >= 0).all() and np.isfinite(tiny.velocity_std).all()
    dv = np.abs(tiny.velocity - unit.velocity)
    assert (dv > 1e-3).mean() <= 0.01 and np.median(dv) < 1e-4
