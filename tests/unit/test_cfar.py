"""CA-CFAR detector: threshold law, peak localisation, edge cases, registration."""
import numpy as np
import pytest

from plugins.detectors.cfar import CFARDetector
from scipy import ndimage

from plugins.detectors.peaks import box_sum, cfar_scale, cfar_threshold, ring_kernel, ring_sum
from xnlos_core import UNCLASSIFIED, ConfigError, Frame, InputError, RadarConfig, RAMap
from xnlos_core.config import parse_pipeline
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import PluginManager
from xnlos_core.testing import small_pipeline_table

pytestmark = pytest.mark.kernels  # numerically sensitive: `make test-kernels` runs it under several BLAS kernels

RADAR = RadarConfig()
H, W = RADAR.n_range_bins, RADAR.n_azimuth_bins


def noise(rng, shape=(H, W), power=1.0):
    return np.sqrt(power / 2) * (rng.standard_normal(shape) + 1j * rng.standard_normal(shape))


def gaussian_peak(row, col, amp, width=(1.5, 2.0)):
    """Complex amplitude of a Gaussian peak centred at fractional bin (row, col)."""
    rr, aa = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    return amp * np.exp(-((rr - row) ** 2 / width[0] ** 2 + (aa - col) ** 2 / width[1] ** 2) / 4)


def frame(data):
    return Frame(RAMap.from_radar(data, RADAR))


def test_scale_formula_matches_monte_carlo():
    # For exponential noise, P(X > a/N · S) with S ~ Gamma(N) must equal pfa.
    rng = np.random.default_rng(1)
    pfa, n = 1e-3, 16
    a = float(cfar_scale(n, pfa))
    assert a == pytest.approx(n * (pfa ** (-1 / n) - 1))
    x = rng.exponential(size=2_000_000)
    s = rng.gamma(n, size=x.size)
    rate = np.mean(x > a / n * s)
    assert rate == pytest.approx(pfa, rel=0.1)


def test_false_alarm_rate_of_threshold_map_including_edges():
    rng = np.random.default_rng(2)
    p = np.abs(noise(rng, (400, 400), power=3.0)) ** 2
    pfa = 1e-2
    thr, _, n = cfar_threshold(p, (1, 1), (4, 3), pfa)
    assert n.min() < n.max()  # border cells really use fewer training cells
    assert np.mean(p > thr) == pytest.approx(pfa, rel=0.1)
    edge = np.zeros(p.shape, bool)
    edge[:5] = edge[-5:] = True
    edge[:, :4] = edge[:, -4:] = True
    assert np.mean(p[edge] > thr[edge]) == pytest.approx(pfa, rel=0.25)


def test_single_peak_found_with_sub_bin_accuracy():
    rng = np.random.default_rng(3)
    row, col = 120.3, 70.6
    det = CFARDetector().detect(frame(noise(rng) + gaussian_peak(row, col, 300.0, width=(0.8, 0.8))))
    assert len(det) >= 1
    assert np.all(det.label == UNCLASSIFIED)
    r_true = np.interp(row, np.arange(H), RADAR.range_axis)
    a_true = np.interp(col, np.arange(W), RADAR.azimuth_axis)
    dr = RADAR.range_axis[1] - RADAR.range_axis[0]
    da = RADAR.azimuth_axis[1] - RADAR.azimuth_axis[0]
    assert abs(det.range[0] - r_true) < 0.1 * dr  # strongest first
    assert abs(det.azimuth[0] - a_true) < 0.1 * da
    assert 0.9 < det.confidence[0] < 1.0
    assert np.all((det.confidence >= 0) & (det.confidence < 1))
    assert det.range_std[0] == pytest.approx(RADAR.range_resolution / np.sqrt(12))
    assert det.azimuth_std[0] > 0


def test_noiseless_gaussian_peak_is_exact():
    det = CFARDetector().detect(frame(gaussian_peak(200.25, 40.4, 1.0) + 1e-6))
    assert len(det) == 1
    assert det.range[0] == pytest.approx(np.interp(200.25, np.arange(H), RADAR.range_axis), abs=1e-6)
    assert det.azimuth[0] == pytest.approx(np.interp(40.4, np.arange(W), RADAR.azimuth_axis), abs=1e-8)


def test_min_range_skips_leakage():
    rng = np.random.default_rng(4)
    data = noise(rng) + gaussian_peak(1.0, 60, 1e4) + gaussian_peak(100, 30, 300.0)
    det = CFARDetector().detect(frame(data))
    assert det.range.min() > 1.0
    assert len(CFARDetector({"min_range": 0.0}).detect(frame(data))) > len(det) - 1


def test_empty_map_gives_empty_detections():
    det = CFARDetector().detect(frame(np.zeros((H, W))))
    assert len(det) == 0 and det.position.shape == (0, 2)
    rng = np.random.default_rng(5)
    assert len(CFARDetector({"pfa": 1e-12}).detect(frame(noise(rng)))) == 0


def test_nan_map_rejected_by_ramap():
    data = np.zeros((H, W), complex)
    data[3, 4] = np.nan
    with pytest.raises(InputError, match="NaN"):
        RAMap.from_radar(data, RADAR)


def test_params_validated():
    with pytest.raises(ConfigError, match="pfa"):
        CFARDetector({"pfa": 1.5})
    with pytest.raises(ConfigError, match="train_cells"):
        CFARDetector({"train_cells": (0, 0)})
    with pytest.raises(ConfigError, match="Allowed keys"):
        CFARDetector({"pfaa": 1e-3})


def test_ring_sums_equal_the_direct_correlation_over_60_decades():
    # the O(H·W) ring sums must match ndimage.correlate with the ring kernel to rounding,
    # also next to 1e30 peaks on a 1e-30 floor (where a running-sum difference would cancel).
    rng = np.random.default_rng(26)
    for _ in range(40):
        h, w = rng.integers(2, 40, 2)
        x = 10.0 ** rng.uniform(-30, 30, (h, w))
        guard, train = tuple(rng.integers(0, 6, 2)), tuple(rng.integers(1, 9, 2))
        ref = ndimage.correlate(x, ring_kernel(guard, train), mode="constant", cval=0.0)
        np.testing.assert_allclose(ring_sum(x, guard, train), ref, rtol=1e-12, atol=0)


def test_box_sum_matches_explicit_windows():
    rng = np.random.default_rng(27)
    for _ in range(100):
        n = int(rng.integers(1, 25))
        lo = int(rng.integers(-30, 30))
        hi = lo + int(rng.integers(0, 30))
        x = rng.random((2, n))
        ref = [[x[r, max(0, i + lo):max(0, min(n, i + hi + 1))].sum() for i in range(n)] for r in range(2)]
        np.testing.assert_allclose(box_sum(x, lo, hi, axis=1), ref, rtol=1e-12, atol=0)
        np.testing.assert_allclose(box_sum(x.T, lo, hi, axis=0), np.transpose(ref), rtol=1e-12, atol=0)


@pytest.mark.parametrize("train", [(128, 128), (160, 160)])
def test_large_training_windows_that_fit_the_map(train):
    # (128, 128) took 63 s per frame and (160, 160) raised MemoryError (a direct
    # correlation with a (2·163+1)² kernel). On a map they fit, the threshold is the closed form:
    # a constant map of power 1 has mean 1, so thr = a(N) with N the ring's cells inside the map.
    guard = (3, 4)
    side = 2 * (train[0] + max(guard)) + 1
    thr, mean, n = cfar_threshold(np.ones((side, side)), guard, train, 1e-5)
    full = (2 * (guard[0] + train[0]) + 1) * (2 * (guard[1] + train[1]) + 1) - (2 * guard[0] + 1) * (2 * guard[1] + 1)
    c = side // 2
    assert n[c, c - (side // 2 - guard[1] - train[1])] == full  # a cell whose whole ring lies inside
    np.testing.assert_allclose(mean, 1.0, rtol=1e-12)
    np.testing.assert_allclose(thr, cfar_scale(n, 1e-5), rtol=1e-12)
    assert n[0, 0] == (guard[0] + train[0] + 1) * (guard[1] + train[1] + 1) - (guard[0] + 1) * (guard[1] + 1)


@pytest.mark.parametrize("train", [(128, 128), (160, 160), (3, 57)])
def test_window_larger_than_the_map_is_a_clear_error(train):
    # The default radar's map is 401 × 121: an azimuth window 2·(train + 4) + 1 > 121 does not fit.
    with pytest.raises(InputError, match=rf"train_cells = \({train[0]}, {train[1]}\).*121 azimuth bins.*"
                                         r"train_cells\[1\] \+ guard_cells\[1\] ≤ 60 "
                                         r"\(train_cells\[1\] ≤ 56 with guard_cells\[1\] = 4\)"):
        CFARDetector({"train_cells": train}).detect(frame(np.ones((H, W))))
    CFARDetector({"train_cells": (3, 56)}).detect(frame(np.ones((H, W))))  # 2·(56 + 4) + 1 = 121 fits


@pytest.mark.filterwarnings("ignore::xnlos_core.errors.PipelineWarning")  # cfar in front of the wall stages, on purpose
@pytest.mark.parametrize("name", ["cfar", "nlos_cfar"])
def test_check_refuses_a_window_the_radar_map_cannot_hold(name):
    # `xnlos check` builds the Pipeline, which checks the detector against the radar's map size
    # (small_pipeline_table's radar: 241 × 121 bins), so check refuses what run would.
    t = small_pipeline_table(detector={"name": name, "params": {"train_cells": [160, 160]}})
    with pytest.raises(ConfigError, match=r"<t>: \[detector\] (nlos_)?cfar: train_cells = \(160, 160\).*"
                                          r"must be ≤ 241, so train_cells\[0\] \+ guard_cells\[0\] ≤ 120 "
                                          r"\(train_cells\[0\] ≤ 117"):
        Pipeline(parse_pipeline(t, "<t>"), source="<t>")
    t["detector"]["params"]["train_cells"] = [8, 8]
    Pipeline(parse_pipeline(t, "<t>"), source="<t>")


def test_xnlos_check_and_run_refuse_the_window_alike(tmp_path, capsys):
    # train_cells (160, 160) passed `xnlos check` and then ran out of memory in `run`.
    from xnlos_core.app.cli import main

    p = tmp_path / "big_window.toml"
    p.write_text("[radar]\nn_samples = 256\nmax_range = 60.0\nn_azimuth_bins = 121\n[scene]\nbuiltin = 'corner'\n"
                 "[forward_model]\nname = 'image'\n[detector]\nname = 'cfar'\nparams = { train_cells = [160, 160] }\n"
                 "[wall_estimator]\nname = 'lsq'\n[reconstructor]\nname = 'mirror'\n[run]\nframes = 1\nfigure = false\n")
    for cmd in (["check", str(p)], ["run", str(p), "--out", str(tmp_path / "o"), "-q"]):
        assert main(cmd) == 2
        err = capsys.readouterr().err
        assert "big_window.toml" in err and "train_cells = (160, 160)" in err and "241 range bins" in err, err
    assert not (tmp_path / "o" / "results.jsonl").exists()


def test_detect_requires_frame():
    with pytest.raises(InputError, match="Frame"):
        CFARDetector().detect(np.zeros((H, W)))


@pytest.mark.parametrize("module, kind, names", [
    ("plugins.detectors.plugin", "detector", ["cfar", "further_than_cfar", "nlos_cfar", "oracle", "rtn", "swin_unet", "unet"]),
    ("plugins.mirror.plugin", "reconstructor", ["mirror"]),
    ("plugins.mirror.residual.plugin", "reconstructor", ["residual_mirror"]),
    ("estimators.plugin", "wall_estimator", ["casadi_map", "emcee", "laplace_is", "lsq"]),
    ("estimators.plugin", "tracker", ["kalman", "nearest", "sindy"]),
    ("estimators.plugin", "nlos_solver", ["fk", "lct"]),
    ("hardware.plugin", "backend", ["adc", "can", "npz", "replay"]),
    ("sims.plugin", "forward_model", ["image", "raytrace"]),
    ("sims.plugin", "backend", ["dataset"]),
    ("sims.plugin", "transient_model", ["spad"]),
])
def test_plugin_modules_register(module, kind, names):
    pm = PluginManager(autoload=False)
    pm.load_module(module)
    assert pm.registry.names(kind) == names
