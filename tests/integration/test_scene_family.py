"""[scene] family = NAME: a registered scene generator builds the pipeline's scene."""
import pytest

from xnlos_core.app.cli import main
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import get_registry
from xnlos_core.scene import load_scene
from xnlos_core.testing import small_pipeline_table

SMALL_RADAR = {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 31}


def _table(scene):
    return small_pipeline_table(radar=SMALL_RADAR, scene=scene)


def test_pipeline_runs_on_a_generated_t_junction():
    scene = {"family": "t_junction", "seed": 3, "overrides": {"cross_width": [8.0, 8.0]}}
    pipe = Pipeline(parse_pipeline(_table(scene), "t"))
    assert pipe.scene.meta["family"] == "t_junction" and pipe.scene.meta["seed"] == 3
    assert pipe.scene.meta["drawn"]["cross_width"] == 8.0  # the override reached the generator
    expected = get_registry().create("scene_generator", "t_junction", {"cross_width": [8.0, 8.0]}).generate(3)
    assert pipe.scene.walls == expected.walls and pipe.scene.objects == expected.objects
    (res,) = list(pipe.run())
    assert res.frame.ground_truth is not None and len(res.frame.ground_truth.los_points) > 0  # its walls echo


def test_seed_picks_the_draw_and_defaults_to_zero():
    reg = get_registry()
    a = load_scene({"family": "t_junction"}, "t", registry=reg)
    assert a.meta["seed"] == 0
    assert load_scene({"family": "t_junction", "seed": 0}, "t", registry=reg).walls == a.walls
    assert load_scene({"family": "t_junction", "seed": 1}, "t", registry=reg).walls != a.walls
    with pytest.raises(ConfigError, match=r"\[scene.family\] a generated scene is built by a pipeline"):
        load_scene({"family": "t_junction"}, "t")


@pytest.mark.parametrize(("scene", "message"), [
    ({"family": "t_junctoin"},
     r"\[scene.family\] unknown scene_generator 't_junctoin' \(did you mean 't_junction'\?\); registered .*t_junction"),
    ({"family": "t_junction", "overrides": {"cross_widht": [8.0, 9.0]}},
     r"\[scene.overrides.cross_widht\] unknown key; did you mean 'cross_width'"),
    ({"family": "t_junction", "overrides": {"cross_width": [1.0, 2.0]}}, r"\[scene.overrides.cross_width"),
    ({"family": "t_junction", "seed": -1}, r"\[scene.seed\] expected an integer"),
    ({"family": "t_junction", "builtin": "corner"}, r"give one of 'builtin', 'file' or 'family'"),
    ({"family": "t_junction", "walls": []}, r"takes only family, seed, overrides; remove walls"),
])
def test_bad_family_tables_are_refused_by_check(tmp_path, scene, message):
    with pytest.raises(ConfigError, match=message):
        Pipeline(parse_pipeline(_table(scene), "t"))


def test_xnlos_check_validates_a_family_scene(tmp_path, capsys):
    cfg = tmp_path / "tj.toml"
    cfg.write_text('[radar]\npreset = "xband_default"\nn_samples = 256\nmax_range = 60.0\nn_azimuth_bins = 31\n'
                   '[scene]\nfamily = "crossroads"\nseed = 2\n[forward_model]\nname = "image"\n'
                   '[detector]\nname = "nlos_cfar"\n')
    assert main(["check", str(cfg)]) == 0
    assert "valid" in capsys.readouterr().out
    cfg.write_text(cfg.read_text().replace('seed = 2\n', 'seed = 2\noverrides = { n_hidden = 0.5 }\n'))
    assert main(["check", str(cfg)]) == 2
    assert "[scene.overrides.n_hidden]" in capsys.readouterr().err
