"""NLOS-CFAR: CFAR peaks labelled mNLOS behind a known relay wall, else LOS."""
import numpy as np
import pytest

from plugins.detectors.nlos_cfar import NLOSCFARDetector, behind_walls
from xnlos_core import LOS, MNLOS, ConfigError, Frame, GroundTruth, InputError, RadarConfig, RAMap, WallSegment

RADAR = RadarConfig()
H, W = RADAR.n_range_bins, RADAR.n_azimuth_bins
WALL = WallSegment(np.array([15.0, 10.0]), np.array([35.0, -10.0]), "facade")  # line x + y = 25


def ra_with_points(points, amp=300.0, seed=0):
    """Noise plus a narrow Gaussian peak at each Cartesian point [m]."""
    rng = np.random.default_rng(seed)
    data = (rng.standard_normal((H, W)) + 1j * rng.standard_normal((H, W))) / np.sqrt(2)
    rr, aa = np.meshgrid(np.arange(H), np.arange(W), indexing="ij")
    for x, y in points:
        row = np.hypot(x, y) / RADAR.range_resolution
        col = np.interp(np.arctan2(y, x), RADAR.azimuth_axis, np.arange(W))
        data += amp * np.exp(-((rr - row) ** 2 + (aa - col) ** 2) / 2.0)
    return RAMap.from_radar(data, RADAR)


POINTS = {"los_front": (10.0, -5.0), "on_wall": (25.0, 0.0), "behind": (35.0, 5.0), "behind2": (30.0, 12.0)}
EXPECTED = {"los_front": LOS, "on_wall": LOS, "behind": MNLOS, "behind2": MNLOS}


def label_at(det, xy):
    i = np.argmin(np.linalg.norm(det.position - np.asarray(xy), axis=1))
    assert np.linalg.norm(det.position[i] - xy) < 0.5, "peak not detected"
    return det.label[i]


def test_behind_ground_truth_wall_is_mnlos():
    ra = ra_with_points(POINTS.values())
    frame = Frame(ra, ground_truth=GroundTruth(walls=(WALL,)))
    det = NLOSCFARDetector().detect(frame)
    for name, xy in POINTS.items():
        assert label_at(det, xy) == EXPECTED[name], name


def test_config_walls_give_same_labels():
    ra = ra_with_points(POINTS.values())
    det = NLOSCFARDetector({"wall_source": "config", "walls": [[15, 10, 35, -10]]}).detect(Frame(ra))
    for name, xy in POINTS.items():
        assert label_at(det, xy) == EXPECTED[name], name


def test_margin_keeps_points_on_the_wall_los():
    on = np.array([[25.3, 0.0], [26.0, 0.0]])  # 0.3 m / 1 m beyond the wall along the ray
    segs = [(WALL.start, WALL.end)]
    assert behind_walls(on, segs, 0.5).tolist() == [False, True]
    assert behind_walls(on, segs, 0.0).tolist() == [True, True]
    assert behind_walls(np.array([[40.0, 30.0]]), segs, 0.5).tolist() == [False]  # ray misses the segment
    assert behind_walls(np.empty((0, 2)), segs, 0.5).shape == (0,)


def test_missing_ground_truth_is_a_clear_error():
    with pytest.raises(InputError, match="wall_source='ground_truth'.*no ground truth"):
        NLOSCFARDetector().detect(Frame(ra_with_points([(10.0, 0.0)])))


def test_config_source_needs_walls():
    with pytest.raises(ConfigError, match="walls"):
        NLOSCFARDetector({"wall_source": "config"})
    with pytest.raises(ConfigError, match="start ≠ end"):
        NLOSCFARDetector({"wall_source": "config", "walls": [[1, 1, 1, 1]]})


def test_params_inherit_cfar_fields():
    d = NLOSCFARDetector({"pfa": 1e-3, "guard_cells": (1, 1), "wall_margin": 1.0})
    assert d.params.pfa == 1e-3 and d.params.wall_margin == 1.0


def test_empty_map_needs_no_walls():
    frame = Frame(RAMap.from_radar(np.zeros((H, W)), RADAR))
    assert len(NLOSCFARDetector().detect(frame)) == 0
