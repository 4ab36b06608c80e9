"""Recording layouts told from the data: every plausible setup mistake named (typed error or a warning
naming the setting), and ``xnlos recording inspect`` identifying every supported DCA1000 layout."""
from __future__ import annotations

import itertools
import tomllib
import warnings

import numpy as np
import pytest

from hardware.layout.candidates import TIE_DB, Layout
from hardware.layout.inspect import inspect_file, report_text
from hardware.layout.scores import encoding_evidence, periodicity, spectrum_stats
from hardware.raw_formats import decode_dca1000, encode_dca1000, offset_binary_words, signed_words
from hardware.recording import Recording
from hardware.recording_checks import RecordingWarning, check_unsigned
from hardware.testing import static_scene_cubes, write_dca1000_recording
from xnlos_core.errors import ConfigError
from xnlos_core.radar import RadarConfig

# 64 samples, 8 chirp loops, 2 TX × 4 RX; ΔR = 0.39 m, max_range 12 m (real sampling allowed)
RADAR = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, n_chirps=8, n_tx=2, n_rx=4,
                    n_azimuth_bins=31, max_range=12.0)
SCALE = 1e-7  # √W per count: the strongest echo ≈ 10 000 counts


@pytest.fixture(scope="module")
def cubes():
    return static_scene_cubes(RADAR, frames=2, seed=3)


def _layouts():
    for lanes, sampling, enc in itertools.product((2, 4), ("complex", "real"), ("twos_complement", "offset_binary")):
        variants = itertools.product(("iq", "qi"), ("lanes", "samples")) if sampling == "complex" else [("iq", "lanes")]
        for order, inter in variants:
            yield Layout(lanes, sampling, order, inter, enc, RADAR.n_samples)


# --- words ------------------------------------------------------------------------------------------

@pytest.mark.parametrize("lanes", [2, 4])
@pytest.mark.parametrize("order,inter", list(itertools.product(("iq", "qi"), ("lanes", "samples"))))
def test_iq_orders_round_trip(lanes, order, inter):
    rng = np.random.default_rng(2)
    c = rng.integers(-3000, 3000, (16, 6, 4)) + 1j * rng.integers(-3000, 3000, (16, 6, 4))
    np.testing.assert_array_equal(decode_dca1000(encode_dca1000(c, "complex", lanes, order, inter), 16, 6, 4,
                                                 "complex", lanes, order, inter), c)


def test_iq_interleave_and_order_place_the_words():
    words = np.array([1, 2, 10, 20], dtype="<i2")
    assert list(decode_dca1000(words, 2, 1, 1, "complex", 2, "iq", "samples")[:, 0, 0]) == [1 + 2j, 10 + 20j]
    assert list(decode_dca1000(words, 2, 1, 1, "complex", 2, "qi", "lanes")[:, 0, 0]) == [10 + 1j, 20 + 2j]


def test_offset_binary_words_decode_and_why_adc_offset_was_wrong():
    v = np.array([-32768, -5, 0, 7, 32767])
    w = offset_binary_words(v)  # the codes u = v + 32768 as stored, read back as signed int16
    np.testing.assert_array_equal(signed_words(w, "offset_binary"), v)
    np.testing.assert_array_equal(signed_words(w.view(np.uint16), "offset_binary"), v)
    # subtracting 32768 from the signed reading is right for negative values only, 65536 off otherwise
    np.testing.assert_array_equal(w.astype(int) - 32768 - v, [0, 0, -65536, -65536, -65536])


def test_statistics_on_known_signals():
    rng = np.random.default_rng(0)
    small = np.rint(rng.normal(0, 200, 4096)).astype("<i2")
    assert encoding_evidence(small) < -30 and encoding_evidence(offset_binary_words(small)) > 30
    period = rng.normal(0, 1, 100)
    r = periodicity(np.tile(period, 20) + 0.01 * rng.normal(0, 1, 2000), 300)
    assert r[100] > 0.99 and r[200] > 0.99 and abs(r[37]) < 0.3
    n = np.arange(64)
    tone = np.exp(2j * np.pi * 5 * n / 64)[:, None, None] + 0.01 * rng.normal(0, 1, (64, 4, 2))
    st = spectrum_stats(tone, True)
    assert st.peak_db > 30 and st.symmetry < 0.05 and st.near_far_db > 20
    mirrored = spectrum_stats(np.conj(tone), True)  # Q and I exchanged: every range mirrored
    assert mirrored.near_far_db < -20 and mirrored.peak_db == pytest.approx(st.peak_db)
    assert spectrum_stats(tone.real + 0j, True).symmetry > 0.9  # real words read as complex: images at −f


# --- inspect ----------------------------------------------------------------------------------------

@pytest.mark.parametrize("truth", list(_layouts()), ids=lambda l: f"{l.lanes}-{l.sampling}-{l.encoding}-{l.iq_order}-"
                                                            f"{l.iq_interleave}")
def test_inspect_identifies_every_supported_layout(tmp_path, cubes, truth):
    radar = RADAR
    write_dca1000_recording(tmp_path, cubes, radar, scale=SCALE, lanes=truth.lanes, sampling=truth.sampling,
                            encoding=truth.encoding, iq_order=truth.iq_order, iq_interleave=truth.iq_interleave)
    part = tmp_path / "part.toml"  # a partial description: receivers, TX and loops only
    part.write_text("[radar]\nn_tx = 2\nn_rx = 4\nn_chirps = 8\n[chirp]\nn_samples = 64\n", encoding="utf-8")
    ins = inspect_file(tmp_path / "capture_Raw_0.bin", part)
    assert ins.best.layout == truth and ins.told and ins.margin >= TIE_DB
    text = report_text(ins, "capture_Raw_0.bin")
    assert "cannot tell" not in text and "→ 2 frame(s)" in text
    pasted = tomllib.loads(text[text.index("[recording]"):])
    assert pasted["recording"]["lanes"] == truth.lanes and pasted["recording"]["encoding"] == truth.encoding
    assert pasted["chirp"]["n_samples"] == truth.n_samples


def test_inspect_says_cannot_tell_on_noise(tmp_path, capsys):
    from xnlos_core.app.cli import main

    rng = np.random.default_rng(11)
    np.rint(rng.normal(0, 300, 2 * 8 * 2 * 4 * 64 * 2)).astype("<i2").tofile(tmp_path / "noise.bin")
    (tmp_path / "part.toml").write_text("[radar]\nn_tx = 2\nn_rx = 4\n", encoding="utf-8")
    assert main(["recording", "inspect", str(tmp_path / "noise.bin"), "--radar", str(tmp_path / "part.toml")]) == 0
    out = capsys.readouterr().out
    assert "cannot tell" in out and "runner-up" in out and "[recording]" not in out


# --- every mistake named ----------------------------------------------------------------------------

def _swap_tx(c):
    return np.concatenate([c[:, :, 4:], c[:, :, :4]], axis=2)


# (id, how the data is written, what the description says instead, expected warning text or error)
MISTAKES = [
    ("lanes 4 read as 2", {"lanes": 4}, {"recording": {"lanes": 2}}, r"recording\.lanes = 4"),
    ("lanes 2 read as 4", {}, {"recording": {"lanes": 4}}, r"recording\.lanes = 2"),
    ("I/Q pairs per sample", {"iq_interleave": "samples"}, {"recording": {"iq_interleave": "lanes"}},
     r"recording\.iq_interleave = 'samples'"),
    ("Q before I", {"iq_order": "qi"}, {"recording": {"iq_order": "iq"}}, r"recording\.iq_order = 'qi'"),
    ("real on complex data", {}, {"recording": {"sampling": "real"}}, r"recording\.sampling"),
    ("n_rx = 2, whole frames", {}, {"radar": {"n_rx": 2}}, r"radar\.n_rx"),
    ("n_samples halved", {}, {"chirp": {"n_samples": 32}, "radar": {"max_range": 5.0}}, r"chirp\.n_samples"),
    ("channel order rx-major", {}, {"recording": {"channel_order": "rx_major"}}, r"channel_order"),
    ("tx_order swapped", {"swap_tx": True}, {}, r"chirp\.tx_order = \[1, 0\]"),
    ("offset-binary .bin", {"encoding": "offset_binary"}, {"recording": {"encoding": "twos_complement"}},
     r"recording\.encoding = 'offset_binary'"),
    ("adc_offset 32768 on .bin", {"encoding": "offset_binary"},
     {"recording": {"encoding": "twos_complement", "adc_offset": 32768}}, ConfigError),
    ("n_tx = 1, n_rx = 8", {}, {"radar": {"n_tx": 1, "n_rx": 8}}, r"velocity comes out × n_tx"),
]


@pytest.mark.parametrize("written,described,expected", [m[1:] for m in MISTAKES], ids=[m[0] for m in MISTAKES])
def test_every_mistake_is_named(tmp_path, cubes, written, described, expected):
    written = dict(written)
    data = [_swap_tx(c) for c in cubes] if written.pop("swap_tx", False) else cubes
    toml = write_dca1000_recording(tmp_path, data, RADAR, scale=SCALE, **written)
    table = tomllib.loads(toml.read_text(encoding="utf-8"))
    for name, fields in described.items():
        table[name].update(fields)
    if isinstance(expected, type):
        with pytest.raises(expected, match="encoding = 'offset_binary'"):
            Recording.from_table(table, str(toml), tmp_path).check(0)
        return
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        rec = Recording.from_table(table, str(toml), tmp_path)
        rec.check(0)
    texts = [str(w.message) for w in caught if issubclass(w.category, RecordingWarning)]
    assert any(__import__("re").search(expected, t) for t in texts), texts
    # no warning advises a remedy the statistics contradict: remove_dc only for a real DC offset
    assert not any("set recording.remove_dc" in t for t in texts), texts


def test_a_correct_description_passes_quietly(tmp_path, cubes):
    for lanes, order in ((2, "iq"), (4, "qi")):
        toml = write_dca1000_recording(tmp_path / f"{lanes}{order}", cubes, RADAR, scale=SCALE, lanes=lanes,
                                       iq_order=order)
        with warnings.catch_warnings():
            warnings.simplefilter("error", RecordingWarning)
            Recording.from_toml(toml).check(0)


def test_offset_binary_bin_decodes_to_the_twos_complement_map(tmp_path, cubes):
    a = write_dca1000_recording(tmp_path / "a", cubes, RADAR, scale=SCALE)
    b = write_dca1000_recording(tmp_path / "b", cubes, RADAR, scale=SCALE, encoding="offset_binary")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        ra, rb = Recording.from_toml(a).check(0), Recording.from_toml(b).check(0)
    np.testing.assert_array_equal(ra.data, rb.data)


def test_unsigned_check_runs_on_complex_arrays():
    rng = np.random.default_rng(4)
    z = (rng.integers(0, 4096, (64, 8)) + 1j * rng.integers(0, 4096, (64, 8))).astype(np.complex64)
    with pytest.warns(RecordingWarning, match=r"every real and imaginary part is ≥ 0.*adc_offset = \d+ \(the median"):
        assert check_unsigned(z, "reader output", "dca1000")
    with warnings.catch_warnings():
        warnings.simplefilter("error", RecordingWarning)
        assert not check_unsigned(z - (2048 + 2048j), "reader output")


def test_leakage_advice_follows_the_data(tmp_path):
    from xnlos_core.signal.doppler import chirp_sequence_cube

    radar = RADAR
    base = static_scene_cubes(radar, 1, seed=5, amplitude=1e-4)[0]
    leak = base + chirp_sequence_cube(radar, [1.5 * radar.range_resolution], [0.0], [1e-3], [0.0])
    dc = base + 1e-3  # a DC offset on every sample
    for cube, remedy, other in ((leak, "background recording", "set recording.remove_dc"),
                                (dc, "set recording.remove_dc = true", "TX→RX leakage")):
        toml = write_dca1000_recording(tmp_path / remedy[:5], [cube], radar, scale=SCALE)
        with pytest.warns(RecordingWarning, match="strongest cell") as got:
            Recording.from_toml(toml).check(0)
        text = next(str(w.message) for w in got if "strongest cell" in str(w.message))
        assert remedy in text and other not in text
