"""Scene schema: curved walls as facets, object classes, meshes."""
import math

import numpy as np
import pytest

from sims.image import ImageForwardModel
from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import MeshSpec, ObjectSpec, Scene, WallSpec


@pytest.mark.parametrize("radius", [12.0, -12.0, 7.5])
def test_arc_vertices_lie_on_the_circle_and_bulge_to_the_signed_side(radius):
    w = WallSpec(start=(20.0, -7.0), end=(20.0, 7.0), radius=radius, facet_length=0.4)
    v = w.vertices()
    np.testing.assert_allclose(v[0], w.start, atol=1e-9)
    np.testing.assert_allclose(v[-1], w.end, atol=1e-9)
    mid = v[len(v) // 2]
    # start→end points along +y; its left is −x: radius > 0 bulges towards the radar at x < 20
    assert (mid[0] < 20.0) == (radius > 0)
    chord = math.dist(w.start, w.end)
    sag = abs(radius) - math.sqrt(radius**2 - (chord / 2) ** 2)
    assert abs(mid[0] - 20.0) == pytest.approx(sag, rel=0.02)
    seg = np.linalg.norm(np.diff(v, axis=0), axis=1)
    assert seg.max() <= 0.4 + 1e-9 and len(w.facets()) == len(v) - 1


def test_radius_below_half_chord_is_refused():
    with pytest.raises(ValueError, match="half the chord"):
        WallSpec(start=(0.0, 0.0), end=(10.0, 0.0), radius=4.0)


def test_image_model_mirrors_in_every_facet_of_a_curved_wall():
    wall = WallSpec(start=(25.0, -8.0), end=(25.0, 8.0), radius=30.0, reflectivity=0.6, backscatter_db=-80)
    scene = Scene(walls=[wall], objects=[ObjectSpec(shape="point", center=(10.0, 0.0), kind="car")])
    f = ImageForwardModel({"noise": False}).simulate(scene, RadarConfig(), np.random.default_rng(0))
    assert len(f.ground_truth.walls) == len(wall.facets())
    assert f.meta["n_mnlos_paths"] >= 1


def test_image_model_refuses_meshes():
    scene = Scene(meshes=[MeshSpec(file="x.stl", material="concrete")])
    with pytest.raises(InputError, match="raytrace"):
        ImageForwardModel().simulate(scene, RadarConfig(), np.random.default_rng(0))
