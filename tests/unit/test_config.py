import pytest

from xnlos_core import ConfigError, PluginError
from xnlos_core.config import expand_sweep, load_pipeline, parse_pipeline
from xnlos_core.pipeline import Pipeline
from xnlos_core.testing import small_pipeline_table


def write(tmp_path, text, name="p.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


BASE = """
[scene]
builtin = "corner"
[forward_model]
name = "image"
[detector]
name = "cfar"
[wall_estimator]
name = "lsq"
[reconstructor]
name = "mirror"
"""


def test_misspelt_top_level_key_names_file_and_suggests(tmp_path):
    p = write(tmp_path, BASE + "[runn]\nframes = 2\n")
    with pytest.raises(ConfigError, match=r"p.toml: \[runn\] unknown key; did you mean 'run'\?"):
        load_pipeline(p)


def test_misspelt_plugin_param_names_key_and_allowed(tmp_path):
    p = write(tmp_path, BASE.replace('name = "cfar"', 'name = "cfar"\nparams = { pfaa = 1e-3 }'))
    cfg = load_pipeline(p)
    with pytest.raises(ConfigError, match=r"p.toml: \[detector.params.pfaa\] unknown key; did you mean 'pfa'\?"):
        Pipeline(cfg, source=str(p))


def test_out_of_range_param_names_bound(tmp_path):
    p = write(tmp_path, BASE.replace('name = "cfar"', 'name = "cfar"\nparams = { pfa = 2.0 }'))
    with pytest.raises(ConfigError, match=r"\[detector.params.pfa\] Input should be less than 1 \(got 2.0\)"):
        Pipeline(load_pipeline(p), source=str(p))


def test_unknown_plugin_lists_registered(tmp_path):
    p = write(tmp_path, BASE.replace('name = "lsq"', 'name = "ransac9"'))
    with pytest.raises(PluginError, match="unknown wall_estimator 'ransac9'; registered wall_estimators: (.*, )?lsq"):
        Pipeline(load_pipeline(p), source=str(p))


def test_radar_out_of_range(tmp_path):
    p = write(tmp_path, BASE + "[radar]\nmax_range = 500.0\n")
    with pytest.raises(ConfigError, match=r"max_range=500.0 m exceeds the unambiguous range"):
        Pipeline(load_pipeline(p), source=str(p))
    p = write(tmp_path, BASE + "[radar]\nn_tx = 0\n")
    with pytest.raises(ConfigError, match=r"\[radar.n_tx\] Input should be greater than or equal to 1"):
        Pipeline(load_pipeline(p), source=str(p))


def test_source_must_be_exactly_one(tmp_path):
    with pytest.raises(ConfigError, match="exactly one of \\[forward_model\\] or \\[backend\\]"):
        parse_pipeline({k: v for k, v in small_pipeline_table().items() if k != "forward_model"}, "x.toml")


def test_invalid_toml_names_line(tmp_path):
    p = write(tmp_path, "seed = = 1\n")
    with pytest.raises(ConfigError, match="p.toml: invalid TOML"):
        load_pipeline(p)


def test_unknown_builtin_scene_lists_known(table):
    table["scene"] = {"builtin": "nowhere"}
    with pytest.raises(ConfigError, match="built-in scenes: corner"):
        Pipeline(parse_pipeline(table, "t.toml"))


def test_sweep_grid_product_and_name_swap_drops_params():
    t = small_pipeline_table(detector={"name": "nlos_cfar", "params": {"wall_margin": 1.0}})
    t["sweep"] = {"detector.name": ["cfar", "nlos_cfar"], "seed": [1, 2, 3]}
    points = expand_sweep(t)
    assert len(points) == 6
    assert points[0][0] == {"detector.name": "cfar", "seed": 1}
    assert points[0][1]["detector"]["params"] == {}  # cfar does not take nlos_cfar's wall_margin
    assert points[3][1]["detector"]["params"] == {"wall_margin": 1.0}
    assert "sweep" not in points[0][1]
    for _, tbl in points:
        parse_pipeline(tbl, "t")


def test_sweep_rejects_unknown_roots_and_empty_lists():
    t = small_pipeline_table()
    t["sweep"] = {"detectr.name": ["cfar"]}
    with pytest.raises(ConfigError, match="'detectr' is not a pipeline key"):
        expand_sweep(t, "s.toml")
    t["sweep"] = {"seed": []}
    with pytest.raises(ConfigError, match="non-empty list"):
        expand_sweep(t, "s.toml")


def test_shipped_configs_are_valid():
    from pathlib import Path

    from xnlos_core.app.cli import main

    root = Path(__file__).parents[2]
    for p in sorted((root / "configs").rglob("*.toml")):
        if "radar" in p.parts or "scenes" in p.parts:
            continue
        assert main(["check", str(p)]) == 0, p


def test_frame_interval_in_milliseconds_warns():
    import warnings

    from xnlos_core.errors import PipelineWarning

    with pytest.warns(PipelineWarning, match=r"frame_interval = 200 s .* write 0.2"):
        parse_pipeline(small_pipeline_table(run={"frame_interval": 200}), "t")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        parse_pipeline(small_pipeline_table(run={"frame_interval": 0.2}), "t")


def test_shipped_pipeline_configs_have_distinct_names():
    # a run's name is its label in summaries and sweeps; two shipped pipelines with one name mix up
    from pathlib import Path

    from xnlos_core.files import load_toml

    root = Path(__file__).resolve().parents[2] / "configs"
    names: dict[str, list[str]] = {}
    for path in sorted([*root.glob("pipelines/*.toml"), *root.glob("ablations/*.toml")]):
        table = load_toml(path)
        if isinstance(table.get("name"), str):
            names.setdefault(table["name"], []).append(str(path.relative_to(root)))
    assert {n: p for n, p in names.items() if len(p) > 1} == {}
