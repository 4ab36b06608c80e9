"""Paths in a pipeline resolve against the config file: plugin path parameters
(ConfigPath), radar presets and built-in scenes by name, a shipped config copied elsewhere."""
import shutil
import tomllib
from pathlib import Path

import pytest

from xnlos_core.app.cli import main
from xnlos_core.config import load_pipeline, parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.io import save_frame
from xnlos_core.pipeline import Pipeline
from xnlos_core.radar import PRESET_DIR, RadarConfig, load_radar, radar_presets
from xnlos_core.registry import get_registry
from xnlos_core.scene import load_scene
from xnlos_core.testing import small_pipeline_table

ROOT = Path(__file__).resolve().parents[2]


def _toml(table) -> str:
    """A flat-enough TOML writer for the small pipeline tables used here."""
    import json

    def val(v):
        if isinstance(v, bool):
            return "true" if v else "false"
        if isinstance(v, dict):
            return "{ " + ", ".join(f"{k} = {val(x)}" for k, x in v.items()) + " }"
        return json.dumps(v)

    top = [f"{k} = {val(v)}" for k, v in table.items() if not isinstance(v, dict)]
    tabs = [f"[{k}]\n" + "\n".join(f"{kk} = {val(vv)}" for kk, vv in v.items())
            for k, v in table.items() if isinstance(v, dict)]
    return "\n".join(top + tabs) + "\n"


@pytest.mark.parametrize(("kind", "name", "key", "extra"), [
    ("backend", "dataset", "path", {}), ("backend", "npz", "directory", {}), ("backend", "replay", "file", {}),
    ("backend", "adc", "recording", {}), ("detector", "unet", "checkpoint", {"device": "cpu"})])
def test_path_params_resolve_against_base_dir(tmp_path, kind, name, key, extra):
    reg = get_registry()
    got = reg.create(kind, name, {key: "sub/x", **extra}, base_dir=tmp_path).params
    assert getattr(got, key) == str(tmp_path / "sub" / "x")
    absolute = str(tmp_path.parent / "elsewhere")  # absolute: kept as written (old behaviour)
    assert getattr(reg.create(kind, name, {key: absolute, **extra}, base_dir=tmp_path).params, key) == absolute
    # without a config (a plugin built in Python) nothing is resolved: relative to the working directory
    assert getattr(reg.create(kind, name, {key: "sub/x", **extra}).params, key) == "sub/x"
    with pytest.raises(ConfigError, match=rf"\[{kind}\.params\.{key}\].*outside the config roots"):
        reg.create(kind, name, {key: "../../../../../../../../../etc/passwd", **extra}, base_dir=tmp_path)


def test_checkpoint_keywords_and_optional_paths_pass_unchanged(tmp_path):
    reg = get_registry()
    for word in ("default", "none"):
        assert reg.create("detector", "unet", {"checkpoint": word}, base_dir=tmp_path).params.checkpoint == word
    assert reg.create("backend", "replay", {"file": "a.blf"}, base_dir=tmp_path).params.dbc is None
    assert reg.create("backend", "replay", {"file": "a.blf", "dbc": "r.dbc"},
                      base_dir=tmp_path).params.dbc == str(tmp_path / "r.dbc")


def test_a_relative_symlink_out_of_the_roots_is_refused(tmp_path, monkeypatch):
    cfg_dir, outside = tmp_path / "cfg", tmp_path / "outside"
    cfg_dir.mkdir(), outside.mkdir()
    (cfg_dir / "frames").symlink_to(outside)
    monkeypatch.chdir(cfg_dir)
    with pytest.raises(ConfigError, match="outside the config roots"):
        get_registry().create("backend", "npz", {"directory": "frames"}, base_dir=cfg_dir)


def test_npz_pipeline_runs_from_another_working_directory(tmp_path, monkeypatch):
    """A config beside its frames folder runs wherever `xnlos` is started (was: relative to the cwd)."""
    proj, elsewhere = tmp_path / "proj", tmp_path / "elsewhere"
    elsewhere.mkdir()
    table = small_pipeline_table(radar={"n_samples": 128, "max_range": 30.0, "n_azimuth_bins": 31},
                                 run={"frames": 2, "figure": False})
    for k, frame in enumerate(Pipeline(parse_pipeline(table, "t")).frames()):
        save_frame(proj / "frames" / f"{k:03d}.npz", frame)
    del table["forward_model"], table["scene"]
    table["backend"] = {"name": "npz", "params": {"directory": "frames"}}
    cfg = proj / "replay_npz.toml"
    cfg.write_text(_toml(table))
    monkeypatch.chdir(elsewhere)
    assert main(["check", str(cfg), "-q"]) == 0
    results = list(Pipeline(load_pipeline(cfg)).run())
    assert [r.frame.index for r in results] == [0, 1]


def test_shipped_replay_config_copied_with_its_recording_checks_elsewhere(tmp_path, monkeypatch, capsys):
    """configs/pipelines/replay.toml copied into another project tree with its recording: the
    recording path is taken from the config's folder, not from the working directory."""
    proj = tmp_path / "proj"
    cfg = proj / "configs" / "pipelines" / "replay.toml"
    cfg.parent.mkdir(parents=True)
    shutil.copy(ROOT / "configs" / "pipelines" / "replay.toml", cfg)
    rec = proj / "demo-out" / "can_hil.blf"
    rec.parent.mkdir()
    rec.write_bytes(b"")  # check does not read it; the path it resolves to is the point
    monkeypatch.chdir(proj)  # from here "../../demo-out/…" read relative to the cwd would be outside proj
    assert main(["check", str(cfg)]) == 0
    assert "valid" in capsys.readouterr().out
    assert Pipeline(load_pipeline(cfg)).stages["backend"].params.file == str(rec.resolve())


@pytest.mark.parametrize("name", ["corner.toml", "corner_tracking.toml", "swin_corner.toml", "can_hil.toml"])
def test_shipped_pipelines_check_when_copied_with_their_scene(tmp_path, monkeypatch, name):
    """The shipped pipelines name the radar preset (no ../radar path), so a copy needs only the
    files it names itself: here the scene file, at the same relative place."""
    src = tomllib.loads((ROOT / "configs" / "pipelines" / name).read_text())
    assert src["radar"].get("preset") == "xband_default"
    dst = tmp_path / "copy" / "configs" / "pipelines" / name
    dst.parent.mkdir(parents=True)
    shutil.copy(ROOT / "configs" / "pipelines" / name, dst)
    if "file" in src.get("scene", {}):
        (tmp_path / "copy" / "configs" / "scenes").mkdir()
        shutil.copy(ROOT / "configs" / "scenes" / "corner.toml", tmp_path / "copy" / "configs" / "scenes")
    monkeypatch.chdir(tmp_path / "copy")
    assert main(["check", str(dst), "-q"]) == 0


def test_radar_preset_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert "xband_default" in radar_presets()
    assert load_radar({"preset": "xband_default"}, "t", tmp_path) == RadarConfig()
    assert load_radar({"preset": "xband_default", "n_tx": 2}, "t", tmp_path).n_tx == 2
    with pytest.raises(ConfigError, match=r"\[radar.preset\] unknown preset 'xband'; shipped presets: automotive_77ghz, xband_default"):
        load_radar({"preset": "xband"}, "t", tmp_path)
    with pytest.raises(ConfigError, match="unknown preset"):
        load_radar({"preset": "../defaults/radar/xband_default"}, "t", tmp_path)  # a name, never a path


def test_shipped_preset_in_the_package_matches_configs_radar_and_is_package_data():
    def fields(p):
        return tomllib.loads(p.read_text())["radar"]

    assert fields(PRESET_DIR / "xband_default.toml") == fields(ROOT / "configs" / "radar" / "xband_default.toml")
    pkg_data = tomllib.loads((ROOT / "pyproject.toml").read_text())["tool"]["setuptools"]["package-data"]
    assert "defaults/radar/*.toml" in pkg_data["xnlos_core"]
    assert PRESET_DIR.parent.name == "defaults" and PRESET_DIR.parent.parent.name == "xnlos_core"


def test_builtin_scene_by_name_from_any_folder(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert load_scene({"builtin": "corner"}, "t", tmp_path).name == "corner"
    with pytest.raises(ConfigError, match="unknown scene 'corner.toml'"):
        load_scene({"builtin": "corner.toml"}, "t", tmp_path)


@pytest.mark.parametrize(("name", "dataset"), [("table2.toml", "default"), ("tracking.toml", "sequences64")])
def test_ablations_read_the_dataset_their_simulate_command_writes(monkeypatch, name, dataset):
    """Each ablation names `xnlos simulate … --out out/data/<dataset>` (run from the project root); its
    dataset path, taken from the config's own folder, is that same place."""
    monkeypatch.chdir(ROOT)
    cfg = ROOT / "configs" / "ablations" / name
    assert f"--out out/data/{dataset}" in cfg.read_text()
    path = Pipeline(load_pipeline(cfg)).stages["backend"].params.path
    assert path == str((ROOT / "out" / "data" / dataset).resolve())


def test_eval_dataset_option_is_relative_to_the_working_directory(tmp_path, monkeypatch):
    from xnlos_core.app.evaluation import with_dataset

    monkeypatch.chdir(tmp_path)
    table = {"backend": {"name": "dataset", "params": {"path": "../../out/data/sequences", "split": "test"}}}
    t, _ = with_dataset(table, dataset="out/data/sequences_large", split="val")
    assert t["backend"]["params"] == {"path": str(tmp_path / "out/data/sequences_large"), "split": "val"}
    assert table["backend"]["params"]["path"] == "../../out/data/sequences"  # the config's own table is untouched
