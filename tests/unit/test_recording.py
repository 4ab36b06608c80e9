"""Raw recordings in (#1): DCA1000 .bin and cube files → RA maps; warnings for known mistakes."""
from __future__ import annotations

import warnings

import numpy as np
import pytest

from hardware.raw_formats import decode_dca1000, encode_dca1000
from hardware.recording import Recording, recording_radar
from hardware.recording_checks import RecordingWarning
from hardware.testing import write_dca1000_recording
from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.chain import ra_map_from_cube

# a TI-like profile at X band: S = 30 MHz/µs, f_s = 10 MHz, N = 128 → B = 384 MHz, ΔR = 0.39 m
RADAR = RadarConfig(n_samples=128, bandwidth=384e6, chirp_duration=12.8e-6, n_chirps=4, n_tx=2, n_rx=4,
                    max_range=40.0, n_azimuth_bins=31)
TARGETS = dict(range_m=[5.221, 17.3], azimuth=[0.25, -0.3], amplitude=[2e-3, 8e-4 * np.exp(1j)],
               radial_velocity=[0.0, 0.0])
SCALE = 1e-7  # √W per count: the strong echo spans ≈ 20000 counts


def _cubes(radar=RADAR, frames=2, targets=TARGETS):
    clean = chirp_sequence_cube(radar, **targets)
    return [add_chirp_noise(clean, radar, np.random.default_rng(k)) for k in range(frames)]


def _peak(ra):
    k = np.unravel_index(np.argmax(ra.power), ra.shape)
    return float(ra.range_axis[k[0]]), float(ra.azimuth_axis[k[1]])


def _quiet(fn, *a, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        return fn(*a, **kw)


@pytest.mark.parametrize("sampling", ["complex", "real"])
@pytest.mark.parametrize("lanes", [2, 4])
def test_dca1000_lane_orders_round_trip(sampling, lanes):
    rng = np.random.default_rng(1)
    c = rng.integers(-3000, 3000, (16, 6, 4)) + (1j * rng.integers(-3000, 3000, (16, 6, 4)) if sampling == "complex" else 0)
    words = encode_dca1000(c, sampling, lanes)
    assert words.dtype == np.dtype("<i2")
    np.testing.assert_array_equal(decode_dca1000(words, 16, 6, 4, sampling, lanes), c)


def test_two_lane_complex_order_is_two_i_then_two_q():
    # the DCA1000 / xWR16xx order: I(n), I(n+1), Q(n), Q(n+1), one receiver's samples after the other's
    words = np.array([1, 2, 10, 20, 3, 4, 30, 40], dtype="<i2")
    z = decode_dca1000(words, 4, 1, 1, "complex", 2)
    np.testing.assert_array_equal(z[:, 0, 0], [1 + 10j, 2 + 20j, 3 + 30j, 4 + 40j])


def test_acceptance_synthetic_dca1000_reproduces_the_simulators_map(tmp_path):
    """A simulated frame written as a DCA1000 .bin, imported, gives the simulator's RA map."""
    cubes = _cubes()
    toml = write_dca1000_recording(tmp_path, cubes, RADAR, scale=SCALE)
    rec = _quiet(Recording.from_toml, toml)
    assert rec.n_frames == 2
    assert rec.radar.bandwidth == pytest.approx(RADAR.bandwidth) and rec.radar.n_range_bins == RADAR.n_range_bins
    for i, cube in enumerate(cubes):
        ref = ra_map_from_cube(cube.mean(axis=1), RADAR)
        got = _quiet(rec.check, i)
        # int16 quantisation (½ count in I and Q) is the only difference: 1e-3 of the peak
        assert np.abs(got.data - ref.data).max() < 1e-3 * np.abs(ref.data).max()
        assert _peak(got) == _peak(ref)
        assert _peak(got)[0] == pytest.approx(5.221, abs=RADAR.range_resolution / 2)


def test_adc_backend_yields_one_frame_per_frame_of_the_file(tmp_path):
    from xnlos_core.registry import get_registry
    from xnlos_core.testing import check_component

    radar = RADAR.model_copy(update={"frame_period": 0.05})
    toml = write_dca1000_recording(tmp_path, _cubes(frames=3), radar, scale=SCALE)
    backend = get_registry().create("backend", "adc", {"recording": str(toml), "start": 1})
    assert backend.n_frames == 2
    frames = _quiet(list, backend.frames())
    assert [f.index for f in frames] == [1, 2]
    assert frames[1].timestamp - frames[0].timestamp == pytest.approx(0.05)
    check_component("backend", "adc", {"recording": str(toml)})


def test_real_only_sampling_and_tx_order(tmp_path):
    radar = RADAR.model_copy(update={"max_range": 20.0})
    cubes = _cubes(radar, frames=1)
    # TDM slots fire TX 1 then TX 0: the file holds slot order, the description says so
    swapped = [np.concatenate([c[:, :, 4:], c[:, :, :4]], axis=2) for c in cubes]
    toml = write_dca1000_recording(tmp_path, swapped, radar, scale=SCALE, sampling="real", chirp={"tx_order": [1, 0]})
    rec = _quiet(Recording.from_toml, toml)
    ref = ra_map_from_cube(cubes[0].mean(axis=1), radar)
    got = rec.ra_map(0)
    assert _peak(got) == _peak(ref)
    # the analytic signal reproduces the complex map up to edge effects of the Hilbert transform
    assert np.abs(got.data - ref.data).max() < 0.05 * np.abs(ref.data).max()


def test_npy_and_npz_cubes(tmp_path):
    cube = _cubes(frames=1)[0]
    iq = np.stack([np.rint(cube.real / SCALE), np.rint(cube.imag / SCALE)], axis=-1).astype(np.int16)
    np.save(tmp_path / "c.npy", np.moveaxis(iq, 2, 0)[None])  # (frame, channel, sample, chirp, 2)
    np.savez(tmp_path / "c.npz", frames=cube[None].astype(np.complex64))
    ref = ra_map_from_cube(cube.mean(axis=1), RADAR)
    common = {"radar": {k: v for k, v in RADAR.model_dump().items() if v is not None}}
    a = _quiet(Recording.from_table, {"recording": {"file": "c.npy", "format": "npy", "scale": SCALE, "sample_format": "iq",
                                              "axes": ["frame", "channel", "sample", "chirp"]}, **common},
               "t.toml", tmp_path)
    b = _quiet(Recording.from_table, {"recording": {"file": "c.npz", "format": "npz", "key": "frames"}, **common},
               "t.toml", tmp_path)
    for rec in (a, b):
        assert rec.n_frames == 1 and _peak(rec.ra_map(0)) == _peak(ref)
        assert np.abs(rec.ra_map(0).data - ref.data).max() < 1e-3 * np.abs(ref.data).max()


def test_hdf5_cube(tmp_path):
    import h5py

    cube = _cubes(frames=1)[0]
    with h5py.File(tmp_path / "c.h5", "w") as f:
        f["adc"] = cube[None].astype(np.complex64)  # (frame, sample, chirp, channel)
    common = {"radar": {k: v for k, v in RADAR.model_dump().items() if v is not None}}
    rec = _quiet(Recording.from_table, {"recording": {"file": "c.h5", "format": "hdf5", "key": "adc"}, **common},
                 "t.toml", tmp_path)
    ref = ra_map_from_cube(cube.mean(axis=1), RADAR)
    assert rec.n_frames == 1 and _peak(rec.ra_map(0)) == _peak(ref)
    assert np.abs(rec.ra_map(0).data - ref.data).max() < 1e-3 * np.abs(ref.data).max()
    with pytest.raises(InputError, match="no dataset 'frames'"):
        Recording.from_table({"recording": {"file": "c.h5", "format": "hdf5", "key": "frames"}, **common},
                             "t.toml", tmp_path).ra_map(0)


# --- warnings ---------------------------------------------------------------------------------------

@pytest.mark.filterwarnings("ignore:.*strongest cell")
def test_unsigned_samples_warn_and_the_map_peaks_at_dc(tmp_path):
    cube = _cubes(frames=1)[0]
    counts = np.rint(cube / SCALE / 16)  # a 12-bit ADC …
    u = (np.stack([counts.real, counts.imag], axis=-1) + 2048).astype(np.uint16)  # … stored offset-binary
    np.save(tmp_path / "u.npy", u)
    table = {"recording": {"file": "u.npy", "format": "npy", "sample_format": "iq", "axes": ["sample", "chirp", "channel"],
                           "scale": 16 * SCALE}, "radar": {k: v for k, v in RADAR.model_dump().items() if v is not None}}
    rec = Recording.from_table(table, "t.toml", tmp_path)
    with pytest.warns(RecordingWarning, match="unsigned") as rec_w:
        ra = rec.check(0)
    leak = [str(w.message) for w in rec_w if "strongest cell" in str(w.message)]
    assert leak and "recording.adc_offset" in leak[0] and "set recording.remove_dc" not in leak[0]
    assert _peak(ra)[0] == 0.0 and 10 * np.log10(ra.power.max() / np.median(ra.power)) > 30
    table["recording"]["adc_offset"] = 2048  # the fix: no warning, the target is back
    fixed = _quiet(Recording.from_table(table, "t.toml", tmp_path).check, 0)
    assert _peak(fixed)[0] == pytest.approx(5.221, abs=RADAR.range_resolution / 2)


@pytest.mark.filterwarnings("ignore:.*strongest cell")
def test_int16_words_all_non_negative_warn(tmp_path):
    toml = write_dca1000_recording(tmp_path, _cubes(frames=1), RADAR, scale=SCALE)
    rec = Recording.from_toml(toml)
    raw = np.abs(rec.raw_frame(0))
    raw.tofile(rec.path)
    with pytest.warns(RecordingWarning, match="≥ 0"):
        rec.check(0)


def test_bandwidth_from_the_ramp_time_warns_with_the_range_error(tmp_path):
    table = {"chirp": {"slope": 30e12, "sample_rate": 10e6, "n_samples": 128, "ramp_time": 15.8e-6, "idle_time": 5e-6},
             "radar": {"n_tx": 2, "n_rx": 4, "n_chirps": 4}}
    radar, _ = _quiet(recording_radar, table, "t.toml", tmp_path)  # the ramp alone sets the chirp period
    assert radar.bandwidth == pytest.approx(384e6) and radar.chirp_duration == pytest.approx(12.8e-6)
    assert radar.chirp_interval == pytest.approx(20.8e-6)
    table["radar"]["bandwidth"] = 30e12 * 15.8e-6  # the mistake: B from the ramp
    with pytest.warns(RecordingWarning, match=r"S·N/f_s = 384.0 MHz.*474.0 MHz = S·ramp_time.*4.05 m"):
        radar, _ = recording_radar(table, "t.toml", tmp_path)
    assert radar.bandwidth == pytest.approx(384e6)
    table["chirp"]["ramp_time"] = 10e-6
    with pytest.raises(ConfigError, match="shorter than the sampling window"):
        recording_radar(table, "t.toml", tmp_path)


def test_near_range_leakage_warns(tmp_path):
    cube = _cubes(frames=1)[0] + chirp_sequence_cube(RADAR, [0.2], [0.0], [8e-3], [0.0])
    toml = write_dca1000_recording(tmp_path, [cube], RADAR, scale=SCALE * 4)
    rec = _quiet(Recording.from_toml, toml)
    with pytest.warns(RecordingWarning, match="leakage"):
        rec.check(0)


def test_single_receiver_warns(tmp_path):
    radar = RADAR.model_copy(update={"n_tx": 1, "n_rx": 1})
    toml = write_dca1000_recording(tmp_path, _cubes(radar, frames=1), radar, scale=SCALE)
    with pytest.warns(RecordingWarning, match="azimuth cannot be resolved"):
        rec = Recording.from_toml(toml)
    ra = rec.ra_map(0)
    assert np.ptp(ra.power[np.argmax(ra.power.max(axis=1))]) < 1e-6 * ra.power.max()  # flat in azimuth


def test_wrong_channel_order_hints(tmp_path):
    toml = write_dca1000_recording(tmp_path, _cubes(frames=1), RADAR, scale=SCALE,
                                   recording={"channel_order": "rx_major"})
    rec = _quiet(Recording.from_toml, toml)
    with pytest.warns(RecordingWarning, match="channel_order"):
        rec.check(0)


def test_truncated_capture_warns_and_drops_the_partial_frame(tmp_path):
    toml = write_dca1000_recording(tmp_path, _cubes(frames=2), RADAR, scale=SCALE)
    data = tmp_path / "capture_Raw_0.bin"
    data.write_bytes(data.read_bytes()[:-100])
    with pytest.warns(RecordingWarning, match="partial frame is dropped"):
        assert Recording.from_toml(toml).n_frames == 1


def test_docs_recipe_runs_as_written(tmp_path, monkeypatch):
    """The raw-recording recipe of docs/recordings.md: its TOML and Python, verbatim, on a synthetic capture."""
    import re
    from pathlib import Path

    text = (Path(__file__).parents[2] / "docs" / "recordings.md").read_text(encoding="utf-8")
    part = text[text.index("<!-- recipe: raw-recording"):]
    toml_src = re.search(r"```toml\n(.*?)```", part, re.S).group(1)
    py_src = next(b for b in re.findall(r"```python\n(.*?)```", part, re.S) if "Recording.from_toml" in b)
    (tmp_path / "capture.toml").write_text(toml_src, encoding="utf-8")
    import tomllib

    radar, _ = recording_radar(tomllib.loads(toml_src), "capture.toml", tmp_path)
    cube = chirp_sequence_cube(radar, [5.221], [0.2], [1e-3], [0.0])
    write_dca1000_recording(tmp_path / "sim", [add_chirp_noise(cube, radar, np.random.default_rng(0))], radar,
                            scale=1e-7, name="capture")
    (tmp_path / "sim" / "capture_Raw_0.bin").rename(tmp_path / "capture_Raw_0.bin")
    monkeypatch.chdir(tmp_path)
    ns: dict = {}
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        exec(compile(py_src, "docs/recordings.md recipe", "exec"), ns)
    assert (tmp_path / "capture.png").stat().st_size > 1000
    assert _peak(ns["ra"])[0] == pytest.approx(5.221, abs=radar.range_resolution / 2)
