"""Dataset-speed changes that must not change a number: per-radar caches equal a
fresh computation and hand out copies; cell_power's row grouping equals np.unique(axis=0)."""
import numpy as np
from scipy.signal import get_window

from xnlos_core.signal.antenna import azimuth_weights, steering_vector
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import WallSpec
from xnlos_core.signal.chain import beam_weights, processing_gain


def _radar(**kw):
    return RadarConfig(n_tx=2, n_rx=4, n_samples=64, max_range=15.0, **kw)


def test_azimuth_weights_cached_equal_fresh_window_and_writable_copies():
    radar = _radar(azimuth_window="taylor")
    want = get_window("taylor", radar.n_channels, fftbins=False)
    w = azimuth_weights(radar)
    assert np.array_equal(w, want) and w.flags.writeable
    w[:] = -1.0  # a caller scribbling on its copy
    assert np.array_equal(azimuth_weights(radar), want)
    assert np.array_equal(azimuth_weights(radar, "hann"), get_window("hann", radar.n_channels, fftbins=False))


def test_beam_weights_cached_equal_closed_form_and_writable_copies():
    radar = _radar()
    w = get_window(radar.azimuth_window, radar.n_channels, fftbins=False)
    want = (w / w.sum())[:, None] * steering_vector(radar, radar.azimuth_axis).conj()
    got = beam_weights(radar)
    assert np.array_equal(got, want) and got.flags.writeable
    got *= 0
    assert np.array_equal(beam_weights(radar), want)


def test_processing_gain_cached_per_radar():
    a, b = _radar(range_window="boxcar", azimuth_window="boxcar"), _radar(range_window="hann")
    assert processing_gain(a) == a.n_samples * a.n_channels  # boxcar: G_p = N·M exactly
    wr, wa = get_window("hann", b.n_samples, fftbins=False), get_window(b.azimuth_window, b.n_channels, fftbins=False)
    assert processing_gain(b) == wr.sum() ** 2 / (wr**2).sum() * wa.sum() ** 2 / (wa**2).sum()
    assert processing_gain(a) == a.n_samples * a.n_channels  # b did not overwrite a's entry


def test_wall_segment_cached_values_and_read_only():
    w = WallSpec(name="w", start=(0.0, 5.0), end=(4.0, 5.0))
    s = w.segment()
    assert np.array_equal(s.start, [0.0, 5.0]) and np.array_equal(s.end, [4.0, 5.0]) and s.name == "w"
    assert not s.start.flags.writeable
    other = WallSpec(name="w", start=(0.0, 6.0), end=(4.0, 6.0)).segment()
    assert np.array_equal(other.start, [0.0, 6.0]) and np.isclose(other.offset, 6.0)
    assert np.array_equal(w.segment().start, [0.0, 5.0])


def test_row_groups_match_unique_rows():
    """sims.render._row_groups (packed 1-D keys) groups rows exactly as np.unique(axis=0) does, so
    cell_power's per-group sums (np.bincount in path order) are unchanged; huge ranges fall back."""
    from sims.render import _row_groups

    rng = np.random.default_rng(7)
    key = np.column_stack([rng.integers(0, 3, 400), rng.integers(-4, 6, 400), rng.integers(0, 50, 400),
                           rng.integers(-20, 20, 400)])
    want = np.unique(key, axis=0, return_inverse=True)[1].reshape(-1)
    got = _row_groups(key)
    w = rng.random(400)
    assert np.array_equal(np.bincount(got, weights=w)[got], np.bincount(want, weights=w)[want])
    assert len(np.unique(got)) == len(np.unique(want))
    assert all(len(np.unique(got[want == g])) == 1 for g in np.unique(want))
    big = key.copy()
    big[:, 2] *= 2**40  # the packed key would overflow int64: np.unique(axis=0) path
    assert np.array_equal(_row_groups(big), np.unique(big, axis=0, return_inverse=True)[1].reshape(-1))
