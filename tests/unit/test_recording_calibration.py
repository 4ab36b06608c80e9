"""Per-channel gain and phase calibration of a recording: values given in [recording] calibration, or
estimated from a synthetic corner-reflector capture with known channel errors."""
from __future__ import annotations

import numpy as np
import pytest

from hardware.calibration import calibration_gains, calibration_table, estimate_calibration
from hardware.recording import Recording
from xnlos_core.errors import ConfigError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.antenna import beam_metrics
from xnlos_core.signal.chain import dechirp

RADAR = RadarConfig(n_samples=128, max_range=30.0, n_tx=2, n_rx=4, n_chirps=2, n_azimuth_bins=181)
REFLECTOR = (12.0, np.radians(10.0))  # range [m], azimuth [rad]
rng = np.random.default_rng(7)
AMP = np.r_[1.0, rng.uniform(0.6, 1.4, RADAR.n_channels - 1)]
PHASE = np.r_[0.0, rng.uniform(-70.0, 70.0, RADAR.n_channels - 1)]  # [deg], channel 0 the reference
ERRORS = AMP * np.exp(1j * np.radians(PHASE))
ERRORS = ERRORS / np.sqrt(np.mean(np.abs(ERRORS) ** 2))  # the estimate's normalisation


def _capture(folder, errors, calibration=None, noise=1e-3, seed=0):
    """A corner reflector at REFLECTOR, each channel multiplied by ``errors``, written as a .npy cube
    (sample, chirp, channel) with its TOML description; returns the opened Recording."""
    r, az = REFLECTOR
    clean = dechirp(RADAR, np.array([2 * r]), np.array([az]), np.array([1.0 + 0j]))  # (n_samples, n_channels)
    g = np.random.default_rng(seed)
    cube = np.repeat((clean * errors)[:, None, :], RADAR.n_chirps, axis=1)
    cube = cube + noise * (g.standard_normal(cube.shape) + 1j * g.standard_normal(cube.shape))
    folder.mkdir(exist_ok=True)
    np.save(folder / "cap.npy", cube.astype(np.complex64))
    cal = "" if calibration is None else f"calibration = {calibration_table(calibration)}\n"
    (folder / "cap.toml").write_text(
        '[recording]\nfile = "cap.npy"\nformat = "npy"\naxes = ["sample", "chirp", "channel"]\n' + cal +
        "[radar]\nn_samples = 128\nmax_range = 30.0\nn_tx = 2\nn_rx = 4\nn_chirps = 2\nn_azimuth_bins = 181\n")
    return Recording.from_toml(folder / "cap.toml")


def _sidelobe_db(rec: Recording) -> float:
    """Highest level outside the main lobe at the reflector's range bin, relative to its peak [dB]."""
    ra = rec.ra_map(0)
    row = np.abs(ra.data[np.argmin(np.abs(ra.range_axis - REFLECTOR[0]))]) ** 2
    null = beam_metrics(RADAR)["first_null"]
    outside = np.abs(np.sin(ra.azimuth_axis) - np.sin(REFLECTOR[1])) > np.sin(null)
    return float(10 * np.log10(row[outside].max() / row.max()))


def test_estimated_errors_match_and_calibrated_sidelobes_fall(tmp_path):
    raw = _capture(tmp_path / "raw", ERRORS)
    est = estimate_calibration(raw, azimuth=REFLECTOR[1])
    assert np.abs(np.degrees(np.angle(est / ERRORS))).max() < 0.5  # [deg]
    np.testing.assert_allclose(np.abs(est), np.abs(ERRORS), rtol=0.01)
    ideal = _sidelobe_db(_capture(tmp_path / "ideal", np.ones(RADAR.n_channels)))
    calibrated = _capture(tmp_path / "cal", ERRORS, calibration=est)
    assert _sidelobe_db(calibrated) == pytest.approx(ideal, abs=0.5)
    assert _sidelobe_db(raw) > ideal + 6.0  # the errors raise the sidelobes; calibration takes them back
    peak = calibrated.ra_map(0)
    i, j = np.unravel_index(np.argmax(np.abs(peak.data)), peak.shape)
    assert abs(peak.azimuth_axis[j] - REFLECTOR[1]) <= np.radians(1.0)
    # estimating on a calibrated recording gives the channels' own errors again
    np.testing.assert_allclose(estimate_calibration(calibrated, azimuth=REFLECTOR[1]), est, rtol=0, atol=1e-4)


def test_range_bin_and_direction_can_be_given(tmp_path):
    raw = _capture(tmp_path / "raw", ERRORS)
    k = int(np.argmin(np.abs(RADAR.range_axis - REFLECTOR[0])))
    np.testing.assert_allclose(estimate_calibration(raw, azimuth=REFLECTOR[1], range_bin=k),
                               estimate_calibration(raw, azimuth=REFLECTOR[1]), atol=1e-12)
    # a wrong azimuth calibrates the reflector onto it: a linear phase across the array, not the errors
    off = estimate_calibration(raw, azimuth=0.0)
    assert np.abs(np.angle(off / ERRORS)).max() > 0.5


def test_given_calibration_is_checked():
    assert calibration_gains([[2.0, 90.0]], 1) == pytest.approx([2j])
    with pytest.raises(ConfigError, match="expected 8 .amplitude, phase_deg. pairs"):
        calibration_gains([[1.0, 0.0]] * 7, 8)
    with pytest.raises(ConfigError, match="amplitudes must be finite and > 0"):
        calibration_gains([[0.0, 0.0]] * 8, 8)
    assert calibration_table([1j, -2.0]) == [[1.0, 90.0], [2.0, 180.0]]


def test_a_recording_with_the_wrong_number_of_gains_is_refused(tmp_path):
    with pytest.raises(ConfigError, match=r"cap.toml: \[recording\] calibration: expected 8"):
        _capture(tmp_path / "bad", ERRORS, calibration=ERRORS[:4])


def test_calibrate_command_prints_the_line_to_paste(tmp_path, capsys):
    from xnlos_core.app.cli import main

    raw = _capture(tmp_path / "raw", ERRORS)
    assert main(["calibrate", str(raw.source), "--azimuth", "10"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("# corner reflector at 11.99 m (range bin 48)") and "azimuth 10°" in out[0]
    assert out[1] == f"calibration = {calibration_table(estimate_calibration(raw, azimuth=REFLECTOR[1]))}"
