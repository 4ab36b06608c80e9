"""Chamfer distance, F1 with one-to-one matching, dense and reconstruction metrics (hand-computed)."""
import math

import numpy as np
import pytest

from xnlos_core import LOS, MNLOS, UNCLASSIFIED, Detections, GroundTruth, HiddenPoints, InputError
from xnlos_core.geometry import cartesian_to_polar
from xnlos_core.metrics import chamfer_distance, dense_metrics, f1_score, match_points, reconstruction_metrics

E = np.empty((0, 2))


def test_chamfer_hand_computed():
    pred = [[0.0, 0.0], [1.0, 0.0]]
    gt = [[0.0, 0.0], [0.0, 2.0]]
    # pred→gt: 0², 1² → 0.5;  gt→pred: 0², 2² → 2.0
    assert chamfer_distance(pred, gt) == pytest.approx(2.5)
    assert chamfer_distance(gt, pred) == pytest.approx(2.5)
    assert chamfer_distance(pred, pred) == 0.0


def test_chamfer_empty_conventions():
    assert chamfer_distance(E, E) == 0.0
    assert chamfer_distance(E, [[1.0, 2.0]]) == math.inf
    assert chamfer_distance([[1.0, 2.0]], []) == math.inf


def test_f1_hand_computed():
    pred = [[0.0, 0.0], [1.0, 0.0]]
    gt = [[0.0, 0.0], [0.0, 2.0]]
    s = f1_score(pred, gt, radius=1.5)  # only gt (0,0) is within reach: one pair
    assert (s["tp"], s["fp"], s["fn"]) == (1, 1, 1)
    assert s["precision"] == s["recall"] == s["f1"] == pytest.approx(0.5)
    assert f1_score(pred, pred, 0.1)["f1"] == 1.0


def test_matching_is_one_to_one_and_maximal():
    # Greedy nearest-first would pair (1,0)–(0.6,0) and leave (0,0) alone; the optimum pairs both.
    pred = [[0.0, 0.0], [1.0, 0.0]]
    gt = [[0.6, 0.0], [1.95, 0.0]]
    p, g = match_points(pred, gt, 1.0)
    assert sorted(zip(p.tolist(), g.tolist())) == [(0, 0), (1, 1)]
    s = f1_score([[0.0, 0.0], [0.1, 0.0], [0.2, 0.0]], [[0.05, 0.0]], 1.0)  # one gt, three claims
    assert (s["tp"], s["fp"], s["fn"]) == (1, 2, 0)
    assert s["precision"] == pytest.approx(1 / 3) and s["recall"] == 1.0 and s["f1"] == pytest.approx(0.5)


def test_f1_empty_conventions():
    both = f1_score(E, E, 1.0)
    assert both == {"precision": 1.0, "recall": 1.0, "f1": 1.0, "tp": 0, "fp": 0, "fn": 0}
    no_pred = f1_score(E, [[0.0, 0.0], [5.0, 0.0]], 1.0)
    assert no_pred == {"precision": 1.0, "recall": 0.0, "f1": 0.0, "tp": 0, "fp": 0, "fn": 2}
    no_gt = f1_score([[0.0, 0.0]], E, 1.0)
    assert no_gt == {"precision": 0.0, "recall": 1.0, "f1": 0.0, "tp": 0, "fp": 1, "fn": 0}


def test_bad_inputs():
    with pytest.raises(InputError, match="radius"):
        f1_score([[0.0, 0.0]], [[0.0, 0.0]], 0.0)
    with pytest.raises(InputError, match="pred"):
        chamfer_distance([[0.0, np.nan]], [[0.0, 0.0]])
    with pytest.raises(InputError, match="shape"):
        chamfer_distance([0.0, 1.0, 2.0], [[0.0, 0.0]])


def make_detections(points, labels):
    r, a = cartesian_to_polar(np.asarray(points, float))
    return Detections(r, a, np.asarray(labels, np.int8), np.ones(len(r)))


def test_dense_metrics_per_class_macro_and_all():
    gt = GroundTruth(los_points=[[10.0, 0.0], [20.0, 0.0]], mnlos_points=[[30.0, 5.0]],
                     hidden_points=[[20.0, 5.0]])
    det = make_detections([[10.0, 0.1], [30.0, 5.0], [20.0, 0.0]], [LOS, MNLOS, UNCLASSIFIED])
    m = dense_metrics(det, gt, radius=0.5)
    assert m["los"]["tp"] == 1 and m["los"]["fn"] == 1 and m["los"]["f1"] == pytest.approx(2 / 3)
    assert m["los"]["cd"] == pytest.approx(0.01 + (0.01 + 100.01) / 2)
    assert m["mnlos"]["f1"] == 1.0 and m["mnlos"]["cd"] == pytest.approx(0.0, abs=1e-20)
    assert m["macro"]["f1"] == pytest.approx((2 / 3 + 1) / 2)
    assert m["macro"]["cd"] == pytest.approx((m["los"]["cd"] + m["mnlos"]["cd"]) / 2)
    assert m["all"]["f1"] == 1.0 and m["all"]["tp"] == 3  # UNCLASSIFIED counts only here
    assert m["n_unclassified"] == 1 and m["classified"] is False


def test_dense_metrics_unclassified_detector():
    gt = GroundTruth(los_points=[[10.0, 0.0]], mnlos_points=[[30.0, 5.0]], hidden_points=[[20.0, 5.0]])
    det = make_detections([[10.0, 0.0], [30.0, 5.0]], [UNCLASSIFIED, UNCLASSIFIED])
    m = dense_metrics(det, gt, radius=0.5)
    assert m["los"]["f1"] == 0.0 and m["los"]["cd"] == math.inf
    assert m["all"]["f1"] == 1.0 and m["all"]["cd"] == pytest.approx(0.0, abs=1e-20)


def test_reconstruction_metrics_and_object_error_m():
    gt = GroundTruth(mnlos_points=[[0.0, -10.0], [1.0, -10.0], [10.0, -20.0]],
                     hidden_points=[[0.0, 10.0], [1.0, 10.0], [10.0, 20.0]],
                     mnlos_object=[0, 0, 1], object_names=("car", "bike"))
    pred = np.array([[0.0, 10.2], [1.0, 10.2], [50.0, 50.0]])
    hp = HiddenPoints(pred, np.zeros((3, 2, 2)), np.arange(3), np.zeros(3))
    m = reconstruction_metrics(hp, gt, radius=0.5)
    assert (m["tp"], m["fp"], m["fn"]) == (2, 1, 1)
    assert m["f1"] == pytest.approx(2 / 3)
    pg = (0.04 + 0.04 + (40**2 + 30**2)) / 3
    gp = (0.04 + 0.04 + (9**2 + 9.8**2)) / 3
    assert m["cd"] == pytest.approx(pg + gp)
    assert m["object_error_m"]["car"] == pytest.approx(0.2)
    assert math.isnan(m["object_error_m"]["bike"])  # (50, 50) is farther than 3·radius from it
    empty = reconstruction_metrics(HiddenPoints.empty(), gt, radius=0.5)
    assert empty["f1"] == 0.0 and empty["cd"] == math.inf
    assert all(math.isnan(v) for v in empty["object_error_m"].values())
    assert reconstruction_metrics(pred[:2], gt, 0.5)["object_error_m"]["car"] == pytest.approx(0.2)


def test_ground_truth_keeps_point_snr_through_thinning_and_selection():
    from xnlos_core.metrics import thin_to_resolution
    from xnlos_core.radar import RadarConfig

    radar = RadarConfig()
    gt = GroundTruth(los_points=[[10.0, 0.0], [10.01, 0.0], [20.0, 5.0]], mnlos_points=[[30.0, 5.0], [30.01, 5.0]],
                     hidden_points=[[20.0, 5.0], [20.0, 5.01]], los_snr_db=[12.0, 30.0, 5.0],
                     mnlos_snr_db=[float("nan"), 15.0])
    thin = thin_to_resolution(gt, radar)
    assert len(thin.los_points) == 2 and sorted(thin.los_snr_db.tolist()) == [5.0, 30.0]  # a cell keeps its max
    assert thin.mnlos_snr_db.tolist() == [15.0]  # NaN (unknown) does not mask a known value
    sel = gt.above_snr(10.4)
    assert len(sel.los_points) == 2 and len(sel.mnlos_points) == 2  # unknown SNR (NaN) is kept
    assert len(GroundTruth(los_points=[[1.0, 0.0]]).los_snr_db) == 1  # absent → NaN per point
    with pytest.raises(InputError, match="GroundTruth.mnlos_snr_db"):
        GroundTruth(mnlos_points=[[1.0, 0.0]], hidden_points=[[0.0, 1.0]], mnlos_snr_db=[1.0, 2.0])


def test_scene_metrics_score_the_complete_reflected_cloud():
    from xnlos_core.metrics import scene_metrics

    gt = GroundTruth(los_points=[[10.0, 0.0], [12.0, 0.0]], mnlos_points=[[30.0, 5.0]], hidden_points=[[20.0, -5.0]])
    det = Detections.from_points(np.array([[10.2, 0.0], [30.0, 5.0]]), np.array([LOS, MNLOS]))
    hidden = HiddenPoints(np.array([[20.0, -4.0]]), np.zeros((1, 2, 2)), np.array([1]), np.array([0]))
    m = scene_metrics(det, hidden, gt, radius=0.5)
    # prediction {(10.2, 0), (20, -4)} vs truth {(10, 0), (12, 0), (20, -5)}: one match within 0.5 m
    assert (m["tp"], m["fp"], m["fn"]) == (1, 1, 2)
    assert m["f1"] == pytest.approx(2 * 0.5 * (1 / 3) / (0.5 + 1 / 3))
    # Chamfer: pred→gt mean of 0.04 and 1; gt→pred mean of 0.04, 3.24, 1 (squared distances)
    assert m["cd"] == pytest.approx((0.04 + 1.0) / 2 + (0.04 + 3.24 + 1.0) / 3)
    empty = scene_metrics(Detections.empty(), np.empty((0, 2)),
                          GroundTruth(), radius=1.0)
    assert empty["f1"] == 1.0 and empty["cd"] == 0.0


def test_thinning_grid_shift_moves_cell_boundaries_only():
    from xnlos_core.metrics import resolution_cell, thin_to_resolution
    from xnlos_core.radar import RadarConfig
    from xnlos_core.types import GroundTruth

    radar = RadarConfig()
    dr, _ = resolution_cell(radar)
    r = 20.0 + dr * np.array([0.1, 0.4, 0.6, 0.9])        # two points in each half of one range cell
    los = np.stack([r, np.zeros_like(r)], 1)
    gt = GroundTruth(los, np.empty((0, 2)), np.empty((0, 2)), np.empty(0, np.int64), (), ())
    assert len(thin_to_resolution(gt, radar).los_points) == 1
    assert len(thin_to_resolution(gt, radar, (0.5, 0.0)).los_points) == 2
    np.testing.assert_allclose(thin_to_resolution(gt, radar, (1.0, 1.0)).los_points,
                               thin_to_resolution(gt, radar).los_points)
