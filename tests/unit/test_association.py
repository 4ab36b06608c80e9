"""Wall association (plugins/mirror/association.py): ray anchoring across several walls, the
fallback and unanchored reporting, LOS support, and the local-wall mirror being an involution."""
import logging

import numpy as np
import pytest

from xnlos_core.wall import mirror
from plugins.mirror.association import anchor_points, crossing_parameters, wall_support
from plugins.mirror.mirror import MirrorReconstructor
from plugins.mirror.residual.features import build_inputs, reflection_frames
from xnlos_core import MNLOS, Detections, InputError, WallPosterior
from xnlos_core.geometry import mirror_reflect

pytestmark = pytest.mark.kernels  # numerically sensitive: `make test-kernels` runs it under several BLAS kernels


def two_walls():
    a = WallPosterior.line(np.array([-1.0, 0.0]), 20.0, extent=np.array([[20.0, 2.0], [20.0, 12.0]]))  # x = 20
    b = WallPosterior.line(np.array([0.0, 1.0]), 8.0, extent=np.array([[5.0, -8.0], [15.0, -8.0]]))  # y = −8
    return [a, b]


def test_line_mirror_there_and_back_is_identity():
    rng = np.random.default_rng(0)
    for _ in range(20):
        phi, b = rng.uniform(-np.pi, np.pi), rng.uniform(1, 50)
        n = np.array([np.cos(phi), np.sin(phi)])
        virt = -(b + rng.uniform(0.1, 30)) * n + rng.uniform(-20, 20) * np.array([-n[1], n[0]])
        hp = MirrorReconstructor().reconstruct(Detections.from_points(virt[None], MNLOS), [WallPosterior.line(n, b)])
        assert np.allclose(mirror_reflect(hp.mean, n, b), virt, atol=1e-9 * (b + np.abs(virt).sum()))


def test_arc_mirror_there_and_back_is_identity():
    arc = WallPosterior.arc(np.array([-1.0, 0.0]), 20.0, 0.05, anchor=np.array([20.0, 0.0]))  # bulges to the radar
    virt = np.array([[26.0, -3.0], [30.0, 4.0], [24.0, 1.0]])
    o, hit = mirror("arc", arc.mean, virt, arc.anchor)
    assert hit.all()
    q, nq = reflection_frames(virt, [arc], np.zeros(3, dtype=int))
    back = o - 2 * np.sum((o - q) * nq, -1)[:, None] * nq  # across the same local tangent
    assert np.allclose(back, virt, atol=1e-9)
    assert np.allclose(build_inputs(virt, [arc], np.zeros(3, int), np.empty((0, 2)), [np.empty(0, int)], 4)["mirror"],
                       o, atol=1e-9)  # the network's ô is Eq. 7 across the local wall


def test_anchoring_picks_the_crossed_wall_and_reports_the_unanchored(caplog):
    walls = two_walls()
    # (30, −20) lies nearer the x = 20 line, but its ray crosses the y = −8 segment first;
    # (−10, 5) is behind the radar: crosses nothing and lies behind no wall.
    pts = np.array([[30.0, 10.0], [10.0, -15.0], [30.0, -20.0], [-10.0, 5.0]])
    with caplog.at_level(logging.INFO, logger="plugins.mirror.association"):
        a = anchor_points(pts, walls, margin=2.0, fallback="nearest")
    assert a.wall_index.tolist() == [0, 1, 1, -1]
    assert a.via.tolist() == ["ray", "ray", "ray", "none"]
    assert a.unanchored.tolist() == [3]
    assert "indices [3]" in caplog.text
    t = crossing_parameters(pts, walls, 2.0)
    assert np.isfinite(t[2]).tolist() == [False, True]


def test_a_crossing_inside_an_observed_extent_beats_a_margin_crossing():
    # The ray into a side street passes 1 m beyond the near building's corner (x = 6, y = 8): within
    # the 2 m margin of that facade, crossed first, but only the far facade (x = 18) is crossed where
    # it was seen. Without the seen far facade the margin crossing still anchors the point.
    near = WallPosterior.line(np.array([0.0, -1.0]), 8.0, extent=np.array([[0.0, 8.0], [6.0, 8.0]]))  # y = 8
    far = WallPosterior.line(np.array([-1.0, 0.0]), 18.0, extent=np.array([[18.0, 10.0], [18.0, 30.0]]))  # x = 18
    pts = np.array([[25.0, 28.6]])  # crosses y = 8 at x = 7.0, x = 18 at y = 20.6
    assert np.isfinite(crossing_parameters(pts, [near, far], 2.0)).all()
    assert crossing_parameters(pts, [near, far], 2.0)[0, 0] < crossing_parameters(pts, [near, far], 2.0)[0, 1]
    assert anchor_points(pts, [near, far], 2.0).wall_index.tolist() == [1]
    assert anchor_points(pts, [near], 2.0).wall_index.tolist() == [0]
    assert anchor_points(pts, [near, far], 0.0).wall_index.tolist() == [1]


def test_fallback_nearest_vs_drop():
    walls = two_walls()
    pts = np.array([[30.0, 40.0]])  # ray misses both extents; behind the x = 20 line only
    assert anchor_points(pts, walls, 0.0, "nearest").wall_index.tolist() == [0]
    assert anchor_points(pts, walls, 0.0, "nearest").via.tolist() == ["nearest"]
    dropped = anchor_points(pts, walls, 0.0, "drop")
    assert dropped.wall_index.tolist() == [-1] and dropped.unanchored.tolist() == [0]
    with pytest.raises(InputError, match="fallback"):
        anchor_points(pts, walls, 0.0, "closest")
    with pytest.raises(InputError, match=r"\(K, 2\)"):
        anchor_points(np.zeros((3, 3)), walls)
    assert anchor_points(pts, [], 0.0).unanchored.tolist() == [0]


def test_wall_support_selects_each_walls_los_points():
    walls = two_walls()
    los = np.array([[20.2, 5.0], [19.7, 11.0], [10.0, -8.3], [14.0, -7.6], [20.0, 40.0], [2.0, 2.0]])
    sup = wall_support(los, walls, distance=0.5, margin=1.0)
    assert sup[0].tolist() == [0, 1]  # (20, 40) is on the line but far outside the extent
    assert sup[1].tolist() == [2, 3]


def test_the_view_runs_from_the_bounce_point_to_the_hidden_point():
    wall = WallPosterior.line(np.array([-1.0, 0.0]), 20.0)  # x = 20
    virt = np.array([[26.0, -3.0], [30.0, 4.0]])
    hp = MirrorReconstructor().reconstruct(Detections.from_points(virt, MNLOS), [wall])
    for o, o_v, u in zip(hp.mean, virt, hp.view):
        q = o_v * 20.0 / o_v[0]  # where the ray radar → o' meets the wall
        assert np.isclose(np.linalg.norm(u), 1.0) and np.allclose(u, (o - q) / np.linalg.norm(o - q))
