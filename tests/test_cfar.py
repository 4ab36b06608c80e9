"""CA-CFAR detector: threshold law, peak localisation, edge cases, registration."""
import numpy as np
import pytest

from plugins.detectors.cfar import CFARDetector
from plugins.detectors.peaks import cfar_scale, cfar_threshold
from xnlos_core import UNCLASSIFIED, ConfigError, Frame, InputError, RadarConfig, RAMap
from xnlos_core.registry import PluginManager

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


def test_detect_requires_frame():
    with pytest.raises(InputError, match="Frame"):
        CFARDetector().detect(np.zeros((H, W)))


@pytest.mark.parametrize("module, kind, names", [
    ("plugins.detectors.plugin", "detector", ["cfar", "further_than_cfar", "nlos_cfar", "rtn", "swin_unet", "unet"]),
    ("plugins.mirror.plugin", "reconstructor", ["mirror"]),
    ("plugins.residual_mirror.plugin", "reconstructor", ["residual_mirror"]),
    ("estimators.plugin", "wall_estimator", ["casadi_map", "emcee", "lsq"]),
    ("estimators.plugin", "tracker", ["nearest"]),
    ("hardware.plugin", "backend", ["can", "npz", "replay"]),
    ("plugins.dataset_backend.plugin", "backend", ["dataset"]),
    ("sims.plugin", "forward_model", ["image", "raytrace"]),
])
def test_plugin_modules_register(module, kind, names):
    pm = PluginManager(autoload=False)
    pm.load_module(module)
    assert pm.registry.names(kind) == names
