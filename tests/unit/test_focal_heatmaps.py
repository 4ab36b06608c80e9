"""Eq. 8 focal loss on hand-computed cases, Gaussian targets, and sub-bin peak refinement."""
from __future__ import annotations

import math

import numpy as np
import pytest
import torch

from plugins.detectors.decode import dense_peaks, grid_peaks
from plugins.detectors.focal import binary_focal_loss, heatmap_focal_loss
from plugins.detectors.heatmaps import binary_cells, gaussian_heatmap, grid_targets, peak_cells
from xnlos_core.radar import RadarConfig
from xnlos_core.types import GroundTruth, RAMap


def logit(c):
    c = torch.as_tensor(c, dtype=torch.float64)
    return torch.log(c) - torch.log1p(-c)


def test_focal_loss_matches_eq8_by_hand():
    c = [0.8, 0.3, 0.1, 0.6]
    y = [1.0, 0.5, 0.0, 1.0]
    # positives: (1 − c)² log c; negatives: (1 − Y)⁴ c² log(1 − c); N = 2 positives
    by_hand = -(0.2**2 * math.log(0.8) + 0.5**4 * 0.3**2 * math.log(0.7) + 0.1**2 * math.log(0.9)
                + 0.4**2 * math.log(0.6)) / 2
    got = heatmap_focal_loss(logit(c), torch.tensor(y))
    assert got.item() == pytest.approx(by_hand, rel=1e-6)


def test_focal_loss_without_positives_is_the_negative_sum():
    c, y = [0.3, 0.1, 0.05], [0.5, 0.0, 0.99]
    by_hand = -(0.5**4 * 0.3**2 * math.log(0.7) + 0.1**2 * math.log(0.9) + 0.01**4 * 0.05**2 * math.log(0.95))
    got = heatmap_focal_loss(logit(c), torch.tensor(y))
    assert torch.isfinite(got) and got.item() == pytest.approx(by_hand, rel=1e-6)
    assert heatmap_focal_loss(torch.full((2, 4, 4), -30.0), torch.zeros(2, 4, 4)).item() == pytest.approx(0, abs=1e-20)


def test_focal_loss_is_finite_at_saturated_logits_and_has_gradients():
    z = torch.tensor([-200.0, 200.0, 200.0, -200.0], requires_grad=True)
    y = torch.tensor([1.0, 0.0, 1.0, 0.3])
    loss = heatmap_focal_loss(z, y)
    loss.backward()
    assert torch.isfinite(loss) and torch.all(torch.isfinite(z.grad))
    assert loss.item() == pytest.approx(200.0 / 2 + 200.0 / 2 * 1.0, rel=1e-3)  # −log σ(−200) ≈ 200 each, N = 2


def test_binary_focal_loss_by_hand():
    c, y = [0.7, 0.2], [1.0, 0.0]
    by_hand = -(0.25 * 0.3**2 * math.log(0.7) + 0.75 * 0.2**2 * math.log(0.8)) / 1
    assert binary_focal_loss(logit(c), torch.tensor(y)).item() == pytest.approx(by_hand, rel=1e-6)


def test_gaussian_targets_are_exactly_one_at_ground_truth_cells():
    peaks = np.array([[10.3, 5.0, 0], [20.0, 12.4, 1], [0.0, 0.0, 0], [20.6, 12.0, 1]])
    y = gaussian_heatmap(peaks, (31, 17), sigma=(0.7, 1.0))
    assert y.dtype == np.float32 and y.shape == (2, 31, 17)
    for r, a, k in peaks:
        assert y[int(k), int(round(r)), int(round(a))] == 1.0
    assert y.max() == 1.0 and y.min() >= 0.0
    assert np.count_nonzero(y == 1.0) == 4
    assert y[0, 10, 6] == pytest.approx(math.exp(-0.5 * (0.3 / 0.7) ** 2 - 0.5), rel=1e-6)


def test_peak_cells_convert_bev_points_with_the_map_axes():
    radar = RadarConfig(n_samples=128, max_range=30.0, n_azimuth_bins=31)
    ra = RAMap.from_radar(np.zeros((radar.n_range_bins, radar.n_azimuth_bins), np.complex64), radar)
    r, a = ra.range_axis[40], ra.azimuth_axis[7]
    gt = GroundTruth(los_points=[[r * np.cos(a), r * np.sin(a)]], mnlos_points=[[100.0, 0.0]], hidden_points=[[1, 1]])
    cells = peak_cells(ra, gt, thin=False)
    np.testing.assert_allclose(cells, [[40, 7, 0]], atol=1e-9)  # the mNLOS point beyond 30 m is dropped
    assert gaussian_heatmap(cells, ra.shape, (0.7, 1.0))[0, 40, 7] == 1.0


@pytest.mark.parametrize("offset", [(-0.4, 0.3), (0.0, 0.0), (0.25, -0.45)])
def test_gaussian_refinement_recovers_sub_bin_offsets(offset):
    sigma = (0.7, 1.0)
    peaks = np.array([[15 + offset[0], 8 + offset[1], 1]])
    y = gaussian_heatmap(peaks, (32, 16), sigma).astype(np.float64)
    z = np.log(np.clip(y, 1e-12, None)) - np.log1p(-np.clip(y, None, 1 - 1e-9))
    fr, fc, k, conf = dense_peaks(z, 0.5, (3, 3), True, 10, "gaussian", sigma)
    assert k.tolist() == [1]
    np.testing.assert_allclose([fr[0], fc[0]], peaks[0, :2], atol=1e-6)


def test_plateaus_give_one_peak_and_classes_suppress_each_other():
    z = np.full((2, 9, 9), -10.0)
    z[0, 3:6, 3:6] = 5.0    # a flat LOS plateau
    z[1, 4, 4] = 4.0         # a weaker mNLOS peak at the same place
    z[1, 8, 0] = 3.0
    fr, fc, k, conf = dense_peaks(z, 0.5, (3, 3), True, 10, "parabolic", (1, 1))
    assert k.tolist() == [0, 1] and (round(fr[1]), round(fc[1])) == (8, 0)


def test_binary_and_grid_targets_round_trip_through_the_grid_decoder():
    peaks = np.array([[5.2, 3.9, 0], [12.0, 8.6, 1]])
    cells = binary_cells(peaks, (16, 12))
    assert cells[0, 5, 4] == 1 and cells[1, 12, 9] == 1 and cells.sum() == 2
    g = grid_targets(peaks, (16, 12), (2, 2))
    out = np.where(g[:2] > 0, 20.0, -20.0)
    pos = np.log(np.clip(g[2:], 1e-9, 1 - 1e-9)) - np.log1p(-np.clip(g[2:], 1e-9, 1 - 1e-9))
    fr, fc, k, conf = grid_peaks(np.concatenate([out, pos]), (2, 2), 0.5, True, 10)
    order = np.argsort(k)
    np.testing.assert_allclose(np.stack([fr[order], fc[order]], 1), peaks[:, :2], atol=1e-6)


def test_window_one_keeps_every_cell_above_threshold_one_class_per_cell():
    z = np.random.default_rng(0).normal(0.0, 2.0, (2, 12, 10))
    fr, fc, k, conf = dense_peaks(z, 0.7, (1, 1), False, 10_000, "none", (1, 1))
    assert len(k) == int((z > np.log(0.7 / 0.3)).sum()) and np.all(np.diff(conf) <= 0)
    fr, fc, k, conf = dense_peaks(z, 0.7, (1, 1), True, 10_000, "none", (1, 1))
    r, a = fr.astype(int), fc.astype(int)
    assert len(set(zip(r, a))) == len(k) == int((z.max(0) > np.log(0.7 / 0.3)).sum())
    assert np.all(z[k, r, a] == z.max(0)[r, a])


def test_resolution_cell_suppression_keeps_the_strongest_peak_of_each_cell():
    from plugins.detectors.learned import detections_from_output
    from plugins.detectors.tasks import make_head
    from xnlos_core.metrics import resolution_cell, resolution_groups

    radar = RadarConfig()
    ra = RAMap(np.zeros((40, 41), np.complex64), 10.0 + 0.25 * np.arange(40), np.radians(np.linspace(-20, 20, 41)), radar)
    z = np.full((2, 40, 41), -10.0)
    z[0, 20, 5:36] = np.linspace(0.5, 3.0, 31)            # an LOS ridge along azimuth (a wall face-on)
    z[1, 30, 18:21] = [1.0, 2.0, 1.5]                      # one mNLOS blob
    head = make_head({"kind": "dense", "target": "gaussian", "sigma": [0.7, 1.0]})
    every = detections_from_output(z, head, ra, 0.5, (1, 1), True, 1000)
    one = detections_from_output(z, head, ra, 0.5, (1, 1), True, 1000, cells=True)
    assert len(every) == 34 and np.all(np.diff(one.confidence) <= 0)
    g_every = resolution_groups(every.position, radar)
    g_one = resolution_groups(one.position, radar)
    assert len(np.unique(g_one)) == len(one) == len(np.unique(g_every)) < len(every)
    for g, c in zip(g_one, one.confidence):   # the kept peak is the most confident of its cell
        assert c == every.confidence[g_every == g].max()
    _, daz = resolution_cell(radar)
    assert np.ptp(one.azimuth[one.label == 0]) > 5 * daz   # the whole ridge, one point per cell along it
    assert (one.label == 1).sum() == 1
