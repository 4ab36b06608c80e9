""""No code from a config": a config names registered components and installed entry
points only; it never imports a module or calls a function it spells (`xnlos check` included)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from pydantic import BaseModel, ConfigDict

import xnlos_core.registry as registry_module
from sims.dataset import load_dataset_config, parse_dataset_config, resolve
from sims.dataset.shard import run_shard_job
from xnlos_core import SceneGenerator, hookimpl
from xnlos_core.app.cli import main
from xnlos_core.config import load_pipeline
from xnlos_core.errors import ConfigError, PluginError
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import PluginManager, get_registry
from xnlos_core.scene import Scene
from xnlos_core.testing import check_scene_generator

ROOT = Path(__file__).resolve().parents[2]

# The reproduction of the issue, verbatim: it ran `touch SOMEFILE` during `xnlos check`.
PAYLOAD = """\
name = "evil"
n_maps = 2
shard_size = 2
generator = "subprocess:call"
generator_params = { shell = true }
families = ["touch SOMEFILE"]
[forward_model]
name = "image"
"""

EVIL_MODULE = "from pathlib import Path\nPath('SOMEFILE').touch()\n"

PIPELINE = """\
name = "plugins-load"
[scene]
builtin = "corner"
[forward_model]
name = "image"
[detector]
name = "nlos_cfar"
[wall_estimator]
name = "lsq"
[reconstructor]
name = "mirror"
[plugins]
"""

# configs/datasets/default.toml's resolved digest before scene generators became components; the
# shipped models record their dataset's manifest hash, so it must not change.
DEFAULT_DIGEST = "916761dd2f664933162bb23384e1228a71cda36c574745ae99d6040a0dd93e14"


def _cli(args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    """``python -m xnlos_core ARGS`` in ``cwd`` (on sys.path there, as for a user) with this checkout."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")])}
    return subprocess.run([sys.executable, "-m", "xnlos_core", *args], cwd=cwd, env=env, capture_output=True,
                          text=True)


# --- the dataset loader ---------------------------------------------------------------------------

def test_issue_payload_is_refused_by_check_and_runs_nothing(tmp_path, monkeypatch, capsys):
    path = tmp_path / "evil.toml"
    path.write_text(PAYLOAD)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError) as err:
        resolve(load_dataset_config(path), str(path))
    msg = str(err.value)
    assert str(path) in msg and "[generator]" in msg and "'subprocess:call'" in msg
    assert "registered scene generators" in msg and "sims.generators:generate_scene" in msg
    assert main(["check", str(path)]) == 2
    err_text = capsys.readouterr().err
    assert "evil.toml" in err_text and "[generator]" in err_text
    assert not (tmp_path / "SOMEFILE").exists()


def test_issue_payload_through_the_xnlos_check_process(tmp_path):
    (tmp_path / "evil.toml").write_text(PAYLOAD)
    out = _cli(["check", "evil.toml"], tmp_path)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "evil.toml: [generator]" in out.stderr and "cannot name code to import or call" in out.stderr
    assert not (tmp_path / "SOMEFILE").exists()


@pytest.mark.parametrize("generator_line", ["", 'generator = "sims.generators:generate_scene"\n'])
def test_without_the_generator_key_families_and_params_must_be_registered(tmp_path, monkeypatch, capsys,
                                                                          generator_line):
    """Dropping (or aliasing) `generator` leaves families and generator_params: neither reaches code."""
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "evil.toml"
    path.write_text(PAYLOAD.replace('generator = "subprocess:call"\n', generator_line))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "evil.toml: [families] unknown scene generator 'touch SOMEFILE'; registered scene generators: " \
           "corner_split, crossroads" in err
    path.write_text(PAYLOAD.replace('generator = "subprocess:call"\n', generator_line)
                    .replace('["touch SOMEFILE"]', '["crossroads"]'))
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "evil.toml: [generator_params.shell] unknown key" in err and "hidden_distance" in err
    assert not (tmp_path / "SOMEFILE").exists()


def test_a_tampered_manifest_or_job_runs_no_code(tmp_path, monkeypatch, capsys, simulate_tiny, dataset_cfg):
    """`xnlos simulate --repair DIR` reads the config from DIR/manifest.json; workers from the job."""
    out = tmp_path / "ds"
    simulate_tiny(dataset_cfg(n_maps=4, shard_size=4), out, workers=1, progress=False)
    man = json.loads((out / "manifest.json").read_text())
    evil = {**man["config"], "generator": "subprocess:call", "generator_params": {"shell": True},
            "families": {"touch SOMEFILE": 1.0}}
    (out / "manifest.json").write_text(json.dumps({**man, "config": evil}))
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--repair", str(out), "-q"]) == 2
    assert "manifest.json: [config.generator]" in capsys.readouterr().err
    with pytest.raises(ConfigError, match=r"dataset job x.npz: \[config.generator\]"):
        run_shard_job({"config": evil, "digest": "0", "shard": "x.npz", "split": "train",
                       "scenes": [(0, 1, "touch SOMEFILE")]})
    assert not (tmp_path / "SOMEFILE").exists()


def test_the_default_dataset_keeps_its_digest():
    if "raytrace" not in get_registry().names("forward_model"):
        pytest.skip("the default dataset needs the raytrace forward model")
    path = ROOT / "configs/datasets/default.toml"
    cfg = load_dataset_config(path)
    assert resolve(cfg, str(path)).digest() == DEFAULT_DIGEST
    legacy = cfg.model_copy(update={"generator": "sims.generators:generate_scene"})
    assert resolve(legacy, str(path)).digest() == DEFAULT_DIGEST  # the deprecated alias is a no-op


# --- scene generators are components ----------------------------------------------------------------

class _Stripes(SceneGenerator):
    """A third party's family: one wall at a seeded distance."""

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        distance: float = 20.0

    def generate(self, seed: int) -> Scene:
        x = self.params.distance + np.random.default_rng(seed).uniform(-1, 1)
        return Scene.model_validate({"name": f"stripes-{seed}", "walls": [{"start": [x, 5.0], "end": [x, -5.0]}]})


class _ThirdParty:
    @hookimpl
    def xnlos_register_components(self, registry):
        registry.add("scene_generator", "stripes", _Stripes)


def test_a_plugin_adds_a_family_and_the_builtins_are_components():
    from sims.generators import generate_scene

    mgr = PluginManager()
    mgr.register(_ThirdParty(), name="stripes", provider="stripes-dist 1.0")
    cfg = parse_dataset_config({"families": {"stripes": 1.0, "crossroads": 2.0}, "generator_params": {},
                                "family_overrides": {"stripes": {"distance": 30.0}},
                                "forward_model": {"name": "image"}}, "third.toml")
    assert resolve(cfg, "third.toml", mgr.registry).weights() == {"stripes": 1.0, "crossroads": 2.0}
    with pytest.raises(ConfigError, match=r"third.toml: \[families\] unknown scene generator 'stripes'"):
        resolve(cfg, "third.toml")  # not in the process-wide registry
    check_scene_generator(mgr.registry.create("scene_generator", "stripes", {"distance": 30.0}))
    built = get_registry().create("scene_generator", "crossroads", {"hidden_distance": [20, 30]})
    assert built.generate(4) == generate_scene("crossroads", 4, hidden_distance=[20, 30])


def test_training_families_are_registered_scene_generators():
    """[data.generate] families of a training config name scene_generator components, as a dataset's do."""
    from plugins.detectors.train_config import scene_generators
    from plugins.detectors.train_config import GenerateConfig
    from sims.generators import generate_scene

    gens = scene_generators(GenerateConfig(families=["crossroads", "t_junction"]))
    assert gens[1].generate(4) == generate_scene("t_junction", 4)
    with pytest.raises(ConfigError, match=r"train.toml: \[families\] unknown scene_generator 'mars'; registered "
                                          r"scene_generators: .*crossroads"):
        scene_generators(GenerateConfig(families=["mars"]), "train.toml")


def test_only_scene_generators_register_as_scene_generators():
    class NotOne:
        @hookimpl
        def xnlos_register_components(self, registry):
            registry.add("scene_generator", "call", type("Call", (), {"Params": None}))

    with pytest.raises(PluginError, match="must subclass xnlos_core.interfaces.SceneGenerator"):
        PluginManager(autoload=False).register(NotOne(), name="not_one")


def test_kit_catches_a_scene_generator_on_the_global_rng():
    class Global(_Stripes):
        def generate(self, seed: int) -> Scene:
            x = 20.0 + np.random.uniform(-1, 1)
            return Scene.model_validate({"name": "g", "walls": [{"start": [x, 5.0], "end": [x, -5.0]}]})

    with pytest.raises(AssertionError, match="drew from a global RNG"):
        check_scene_generator(Global())

    class NotAScene(_Stripes):
        def generate(self, seed: int):
            return {"walls": []}

    with pytest.raises(AssertionError, match="must return a Scene, got dict"):
        check_scene_generator(NotAScene())


# --- [plugins] load -----------------------------------------------------------------------------------

def test_plugins_load_of_a_module_is_refused_by_check(tmp_path, monkeypatch, capsys):
    (tmp_path / "evil_mod.py").write_text(EVIL_MODULE)
    monkeypatch.syspath_prepend(str(tmp_path))  # importable: only the config's word is refused
    monkeypatch.chdir(tmp_path)
    path = tmp_path / "pipe.toml"
    path.write_text(PIPELINE + 'load = ["evil_mod"]\n')
    with pytest.raises(ConfigError) as err:
        Pipeline(load_pipeline(path), source=str(path))
    msg = str(err.value)
    assert f"{path}: [plugins.load] 'evil_mod' is not an installed xnlos plugin" in msg
    assert "xnlos-sims (xnlos)" in msg and "xnlos -p MODULE" in msg
    assert main(["check", str(path)]) == 2 and "[plugins.load]" in capsys.readouterr().err
    assert "evil_mod" not in sys.modules and not (tmp_path / "SOMEFILE").exists()


def test_plugins_load_of_a_module_through_the_xnlos_check_process(tmp_path):
    (tmp_path / "evil_mod.py").write_text(EVIL_MODULE)  # in the working directory: on sys.path
    (tmp_path / "pipe.toml").write_text(PIPELINE + 'load = ["evil_mod"]\n')
    out = _cli(["check", "pipe.toml"], tmp_path)
    assert out.returncode == 2 and "Traceback" not in out.stderr
    assert "pipe.toml: [plugins.load] 'evil_mod' is not an installed xnlos plugin" in out.stderr
    assert not (tmp_path / "SOMEFILE").exists()


def test_plugins_load_names_installed_entry_points(tmp_path):
    path = tmp_path / "pipe.toml"
    path.write_text(PIPELINE + 'autoload = false\nload = ["xnlos-sims", "xnlos-detectors", "xnlos-estimators", '
                               '"xnlos-mirror"]\n')
    p = Pipeline(load_pipeline(path), source=str(path))
    # the dataset backend comes with xnlos-sims; the hardware backends (xnlos-hardware) stay out
    assert p.registry.names("detector") and p.registry.names("backend") == ["dataset"]
    path.write_text(PIPELINE + 'autoload = false\nload = ["xnlos"]\n')  # a distribution: all its entry points
    assert "npz" in Pipeline(load_pipeline(path), source=str(path)).registry.names("backend")


def test_the_command_line_switch_still_imports_a_module(monkeypatch, capsys):
    """`xnlos -p MODULE` is the user's own act (like `pytest -p`); a repeated -p is harmless."""
    monkeypatch.setattr(registry_module, "_MANAGER", PluginManager())
    assert main(["-p", "tiny_scenes", "-p", "tiny_scenes", "plugins", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {r["name"] for r in rows if r["kind"] == "scene_generator"} >= {"corner_a", "crossroads"}
