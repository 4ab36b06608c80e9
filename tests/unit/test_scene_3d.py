"""The 3-D scene view: one vertical quad per wall at the wall's plan end points and height, boxes
of the objects' heights, the radar at its mounting height, paths drawn through the points given,
the ground only when the scene has one, and the PNG written."""
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from xnlos_core.app.plot.scene_3d import DEFAULT_RADAR_HEIGHT, draw_scene_3d, scene_3d_figure
from xnlos_core.errors import InputError
from xnlos_core.scene import GroundSpec, load_scene

matplotlib = pytest.importorskip("matplotlib")
matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

CONFIGS = Path(__file__).parents[2] / "configs"


def _verts(pc) -> np.ndarray:
    """(N, 3) [m] vertices a Poly3DCollection holds (its faces, (F, 4, 3), one after another)."""
    return np.asarray(pc._faces, float).reshape(-1, 3)


def _axes():
    fig = plt.figure()
    return fig, fig.add_subplot(projection="3d")


@pytest.fixture
def corner():
    return load_scene({"builtin": "corner"}, "t")


def test_each_wall_is_one_quad_at_its_plan_end_points_and_height(corner):
    corner = corner.model_copy(update={"walls": [corner.walls[0].model_copy(update={"height": 7.5}),
                                                 *corner.walls[1:]]})
    fig, ax = _axes()
    art = draw_scene_3d(ax, corner, radar_height=1.2)
    assert len(art.walls) == len(corner.walls) == 3
    for pc, w in zip(art.walls, corner.walls):
        v = _verts(pc)
        (x0, y0), (x1, y1), h = w.start, w.end, w.height
        np.testing.assert_allclose(v, [[x0, y0, 0], [x1, y1, 0], [x1, y1, h], [x0, y0, h]], atol=1e-12)
        assert pc.get_gid() == w.name
    assert _verts(art.walls[0])[:, 2].max() == 7.5 and _verts(art.walls[1])[:, 2].max() == 3.0
    assert art.ground is None  # the corner scene has no ground
    plt.close(fig)


def test_radar_marker_objects_and_paths_where_given(corner):
    fig, ax = _axes()
    path = np.array([[0.0, 0.0, 1.2], [25.0, 0.0, 1.5], [22.0, -14.0, 0.8], [25.0, 0.0, 1.5], [0.0, 0.0, 1.2]])
    art = draw_scene_3d(ax, corner, radar_height=1.2, paths=[path, path[:2]])
    np.testing.assert_array_equal(np.ravel(art.radar.get_data_3d()), [0.0, 0.0, 1.2])
    assert len(art.paths) == 2
    np.testing.assert_array_equal(np.column_stack(art.paths[0].get_data_3d()), path)
    np.testing.assert_array_equal(np.column_stack(art.paths[1].get_data_3d()), path[:2])
    (car,) = corner.objects
    (box,) = art.objects
    v = _verts(box)
    assert len(v) == 24  # 6 faces of 4 corners
    np.testing.assert_allclose(np.unique(v[:, 2]), [0.0, car.height])
    np.testing.assert_allclose(np.unique(np.round(v[:, :2], 9), axis=0),
                               np.unique(np.round(car.footprint(0.0), 9), axis=0))
    # the scattering centre: the radar height capped at the car's height (1.2 < 1.5)
    np.testing.assert_allclose(np.ravel(art.centres[0].get_data_3d()), [*car.center, 1.2])
    plt.close(fig)


def test_the_ground_is_drawn_only_with_a_ground_and_covers_the_scene(corner):
    fig, ax = _axes()
    grounded = corner.model_copy(update={"ground": GroundSpec(reflection=-1.0)})
    art = draw_scene_3d(ax, grounded)
    v = _verts(art.ground)
    assert np.all(v[:, 2] == 0)
    walls = np.array([p for w in corner.walls for p in (w.start, w.end)])
    assert v[:, 0].min() < walls[:, 0].min() and v[:, 0].max() > walls[:, 0].max()
    assert v[:, 1].min() < walls[:, 1].min() and v[:, 1].max() > walls[:, 1].max()
    np.testing.assert_array_equal(np.ravel(art.radar.get_data_3d()), [0.0, 0.0, DEFAULT_RADAR_HEIGHT])
    plt.close(fig)


def test_bad_paths_and_heights_are_refused_by_name(corner):
    fig, ax = _axes()
    with pytest.raises(InputError, match=r"paths\[1\]: expected a \(K, 3\)"):
        draw_scene_3d(ax, corner, paths=[np.zeros((2, 3)), np.zeros((3, 2))])
    with pytest.raises(InputError, match=r"paths\[0\].*non-finite"):
        draw_scene_3d(ax, corner, paths=[np.array([[0, 0, 0], [np.nan, 0, 0]])])
    with pytest.raises(InputError, match="radar_height"):
        draw_scene_3d(ax, corner, radar_height=-1.0)
    plt.close(fig)


def test_the_osm_demo_scene_is_drawn_wall_by_wall_and_written(tmp_path):
    from xnlos_core.config import load_pipeline
    from xnlos_core.pipeline import Pipeline

    config = CONFIGS / "pipelines" / "osm_intersection.toml"
    scene = Pipeline(load_pipeline(config), source=str(config)).scene
    fig, ax = _axes()
    art = draw_scene_3d(ax, scene)
    planar = scene.planar_walls()
    assert len(art.walls) == len(planar) > 0
    for pc, w in zip(art.walls, planar):
        v = _verts(pc)
        np.testing.assert_allclose(v[:2, :2], [w.start, w.end], atol=1e-12)
        np.testing.assert_allclose(v[2:, 2], w.height)
    plt.close(fig)
    out = scene_3d_figure(scene, tmp_path / "scene.png", radar_height=1.0)
    assert out.stat().st_size > 0
    with Image.open(out) as img:
        assert img.format == "PNG" and min(img.size) > 100
        assert np.asarray(img.convert("L")).std() > 5  # something is drawn, not a blank page
    assert not [p for p in tmp_path.iterdir() if p.name != "scene.png"]  # no temporary left behind
