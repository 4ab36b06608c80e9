"""The shipped scenes' 2-D maps are those of the model before 3-D propagation, with ``dimensions`` "2d",
with "auto" (which picks 2-D on them: no ground, every scatterer at the radar's height) and, without a
ground, with "3d" (vertical walls: the 3-D terms vanish)."""
import numpy as np
import pytest

from sims.image import ImageForwardModel
from sims.raytrace.model import RaytraceForwardModel
from xnlos_core.radar import RadarConfig
from xnlos_core.registry import get_registry
from xnlos_core.scene import generated_scene, load_scene

# (Σ|A|², Σ|A|·w) of each RA map A, w ~ U(0, 1) from seed 1, from the models before the 3-D terms
# existed (default radar, default parameters, rng seed 0; families drawn with seed 0)
REFERENCE = {
    ("corner", "image"): (3.633790231400897e-12, 3.722282021730656e-05),
    ("corner", "raytrace"): (3.333995716018253e-12, 3.775479821080499e-05),
    ("corner_split", "image"): (5.411520651705726e-11, 0.00011580435087085741),
    ("crossroads", "image"): (5.035246715045675e-11, 8.961241371871652e-05),
    ("curved_wall", "image"): (5.552260106393614e-13, 2.0407417657373245e-05),
    ("hidden_car_approach", "image"): (1.706083562907629e-11, 6.150217268613503e-05),
    ("hidden_cyclist", "image"): (1.707024341411093e-11, 6.140497401904729e-05),
    ("hidden_pedestrian", "image"): (5.0326277059442645e-11, 8.967148701397262e-05),
    ("parking_lot", "image"): (7.011018115463814e-10, 0.00031094248843967703),
    ("residential_street", "image"): (6.095834062603727e-12, 3.407615968307116e-05),
    ("t_junction", "image"): (1.2109818999326631e-11, 4.340078175064245e-05),
    ("t_junction", "raytrace"): (9.544750365815868e-12, 3.968918945496013e-05),
    ("hidden_pedestrian", "raytrace"): (2.3537843723524893e-11, 6.90351106069662e-05),
}
MODELS = {"image": ImageForwardModel, "raytrace": RaytraceForwardModel}
RADAR = RadarConfig()


def _scene(name: str):
    if name == "corner":
        return load_scene({"builtin": "corner"}, "test", ".")
    return generated_scene({"family": name, "seed": 0}, "test", ".", registry=get_registry())


def _fingerprint(name: str, model: str, dimensions: str) -> tuple[tuple[float, float], str]:
    frame = MODELS[model]({"dimensions": dimensions}).simulate(_scene(name), RADAR, np.random.default_rng(0))
    a = np.abs(frame.ra_map.data).astype(np.float64)
    w = np.random.default_rng(1).uniform(size=a.shape)
    return (float((a**2).sum()), float((a * w).sum())), frame.meta["components"]["dimensions"]


@pytest.mark.parametrize("name, model", sorted(REFERENCE))
def test_auto_picks_2d_and_keeps_the_map(name, model):
    got, why = _fingerprint(name, model, "auto")
    assert why.startswith("2d:"), why
    np.testing.assert_allclose(got, REFERENCE[name, model], rtol=1e-6)


@pytest.mark.parametrize("dimensions", ["2d", "3d"])
@pytest.mark.parametrize("name, model", [("corner", "image"), ("t_junction", "raytrace")])
def test_2d_and_groundless_3d_keep_the_map(name, model, dimensions):
    got, why = _fingerprint(name, model, dimensions)
    assert why.startswith(dimensions)
    np.testing.assert_allclose(got, REFERENCE[name, model], rtol=1e-6)
