"""Recordings keep their chirps: Doppler maps with velocity σ from the noise measured in the data,
frame timestamps from a stated frame period, and a range axis that ends at max_range."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from hardware.recording import FramePeriodWarning, Recording, recording_radar
from hardware.recording_checks import RecordingWarning
from hardware.testing import write_dca1000_recording
from xnlos_core.errors import ConfigError
from xnlos_core.radar import SPEED_OF_LIGHT, RadarConfig
from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube, doppler_ra_maps

RADAR = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, chirp_period=200e-6, n_chirps=16,
                    n_tx=2, n_rx=4, max_range=20.0, n_azimuth_bins=31, frame_period=0.1)
TARGET = dict(range_m=[6.0], azimuth=[0.2], amplitude=[2e-6], radial_velocity=[1.3])
SCALE = 1e-7


def _cube(seed=0, radar=RADAR):
    return add_chirp_noise(chirp_sequence_cube(radar, **TARGET), radar, np.random.default_rng(seed))


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        return fn(*a, **kw)


def _npy_recording(tmp_path, cube, scale=1.0, name="c"):
    np.save(tmp_path / f"{name}.npy", cube[None].astype(np.complex128))
    radar = {k: v for k, v in RADAR.model_dump().items() if v is not None}
    return _quiet(Recording.from_table, {"recording": {"file": f"{name}.npy", "format": "npy", "scale": scale},
                                         "radar": radar}, "t.toml", tmp_path)


def _peak_cell(ra):
    return np.unravel_index(np.argmax(ra.power), ra.shape)


def test_frames_carry_velocity_and_sigma_like_the_simulators_map(tmp_path):
    toml = write_dca1000_recording(tmp_path, [_cube(0), _cube(1)], RADAR, scale=SCALE)
    rec = _quiet(Recording.from_toml, toml)
    frames = _quiet(list, rec.frames())
    assert [f.timestamp for f in frames] == [0.0, 0.1]
    for k, f in enumerate(frames):
        ra = f.ra_map
        assert ra.velocity is not None and ra.velocity_std is not None
        cell = _peak_cell(ra)
        assert ra.range_axis[cell[0]] == pytest.approx(6.0, abs=RADAR.range_resolution)
        assert abs(ra.velocity[cell] - 1.3) < RADAR.velocity_resolution / 2
        # the simulator's map of the same cube (model noise, amplitudes in √W): same peak, the same velocity
        # but for int16 rounding (½ count against ≈ 6 counts of noise), and σ from the measured noise
        # agrees with σ from the thermal model within the median's scatter
        sim = doppler_ra_maps(_cube(k), RADAR)
        assert _peak_cell(ra) == np.unravel_index(np.argmax(sim.peak_power), ra.shape)
        assert ra.velocity[cell] == pytest.approx(sim.velocity[cell], abs=0.2 * sim.velocity_std[cell])
        assert ra.velocity_std[cell] == pytest.approx(sim.velocity_std[cell], rel=0.05)
    # without Doppler: the chirp-averaged map of before, no velocity
    assert _quiet(list, rec.frames(doppler=False))[0].ra_map.velocity is None


@pytest.mark.parametrize("factor", [1e-6, 1e6])
def test_velocity_sigma_does_not_follow_the_amplitude_scale(tmp_path, factor):
    cube = _cube(3)
    ref = _npy_recording(tmp_path, cube, name="ref").doppler_ra_map(0)
    data = _npy_recording(tmp_path, cube * factor, name="data").doppler_ra_map(0)     # the samples scaled
    setting = _npy_recording(tmp_path, cube, scale=factor, name="setting").doppler_ra_map(0)  # [recording] scale
    cell = _peak_cell(ref)
    assert 0 < ref.velocity_std[cell] < RADAR.velocity_resolution
    # cells with an echo (η well above 1); in noise cells (σ of tens of m/s) single-precision rounding of
    # η = power/σ_cell − 1 ≈ 0 moves σ by up to 1e-3
    echo = ref.velocity_std < RADAR.velocity_resolution
    assert echo.sum() >= 5
    for ra in (data, setting):
        np.testing.assert_allclose(ra.velocity_std[echo], ref.velocity_std[echo], rtol=1e-4)
        np.testing.assert_allclose(ra.velocity[echo], ref.velocity[echo], rtol=0, atol=1e-5)
        np.testing.assert_allclose(ra.velocity_std, ref.velocity_std, rtol=1e-2)
    # the thermal model's σ would have moved by the factor (η ∝ factor²): 1e±6 in σ
    model = doppler_ra_maps(cube * factor, RADAR).velocity_std[cell]
    assert not model == pytest.approx(ref.velocity_std[cell], rel=0.5)


def test_measured_noise_floor_matches_the_thermal_noise_of_a_noise_only_cube():
    cube = add_chirp_noise(np.zeros((RADAR.n_samples, RADAR.n_chirps, RADAR.n_channels), complex), RADAR,
                           np.random.default_rng(7))
    model, measured = doppler_ra_maps(cube, RADAR), doppler_ra_maps(cube, RADAR, noise="measured")
    # 64·16·8 cells: the median's relative scatter is ≈ 1.2/√8000 ≈ 1.4 %
    assert measured.noise_floor == pytest.approx(model.noise_floor, rel=0.05)
    with pytest.raises(Exception, match="noise must be"):
        doppler_ra_maps(cube, RADAR, noise="thermal")


def test_frames_without_a_frame_period_warn_and_name_the_setting(tmp_path):
    radar = RADAR.model_copy(update={"frame_period": None})
    toml = write_dca1000_recording(tmp_path, [_cube(0, radar), _cube(1, radar)], radar, scale=SCALE)
    rec = _quiet(Recording.from_toml, toml)
    with pytest.warns(FramePeriodWarning, match=r"frame_period.*0.0064 s apart"):
        frames = list(rec.frames())
    assert frames[1].timestamp == pytest.approx(radar.n_chirps * radar.n_tx * radar.chirp_period)
    _quiet(list, rec.frames(max_frames=1))  # one frame: no timestamps to get wrong


def test_doppler_needs_three_chirps(tmp_path):
    radar = RADAR.model_copy(update={"n_chirps": 2})
    toml = write_dca1000_recording(tmp_path, [_cube(0, radar)], radar, scale=SCALE)
    rec = _quiet(Recording.from_toml, toml)
    assert not rec.has_doppler and _quiet(list, rec.frames())[0].ra_map.velocity is None
    with pytest.raises(ConfigError, match="n_chirps ≥ 3"):
        list(rec.frames(doppler=True))
    from xnlos_core.registry import get_registry

    backend = get_registry().create("backend", "adc", {"recording": str(toml), "doppler": True})
    with pytest.raises(ConfigError, match="n_chirps = 2"):
        backend.check_source()


@pytest.mark.parametrize("slope, sample_rate", [(70e12, 2e6), (100e12, 6.25e6), (33.3e12, 12.5e6), (29.982e12, 10e6)])
def test_range_axis_ends_at_max_range_with_every_bin(tmp_path, slope, sample_rate):
    """The default max_range is the last unambiguous bin, (N − 1)·c/(2B): the map has N bins and its
    axis ends there (the quotient max_range/ΔR rounds to 126.99999999999999 for these profiles)."""
    n = 128
    table = {"recording": {"file": "x.bin", "format": "dca1000"},
             "chirp": {"slope": slope, "sample_rate": sample_rate, "n_samples": n},
             "radar": {"n_tx": 1, "n_rx": 4, "n_chirps": 4}}
    radar, _ = recording_radar(table, "t.toml", tmp_path)
    dr = SPEED_OF_LIGHT / (2 * slope * n / sample_rate)  # closed form c/(2B), B = S·N/f_s
    assert radar.max_range == pytest.approx((n - 1) * dr, rel=1e-12)
    assert radar.n_range_bins == n
    assert radar.range_axis[-1] == pytest.approx(radar.max_range, rel=1e-12)
    np.testing.assert_allclose(np.diff(radar.range_axis), dr, rtol=1e-12)


def test_range_bins_never_exceed_the_samples():
    r = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, max_range=64 * SPEED_OF_LIGHT / (2 * 384e6))
    assert r.n_range_bins == 64  # bin N is range N·ΔR, folded onto bin 0 by the FFT
    assert RadarConfig(max_range=100.0).n_range_bins == 401 and RadarConfig(max_range=99.9).n_range_bins == 400
    assert RadarConfig(max_range=100.0).range_axis[-1] == pytest.approx(400 * RadarConfig().range_resolution)
