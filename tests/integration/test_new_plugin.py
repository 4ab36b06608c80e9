"""``xnlos new-plugin KIND NAME`` writes a package that passes the conformance kit as generated, runs in
a pipeline, and whose own tests pass under pytest."""
from __future__ import annotations

import importlib
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import numpy as np
import pytest

from xnlos_core.app.cli import main
from xnlos_core.app.new_plugin import KINDS_WITH_TEMPLATE
from xnlos_core.config import parse_pipeline
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import PluginManager
from xnlos_core.testing import check_component, small_pipeline_table

ROOT = Path(__file__).resolve().parents[2]
pytestmark = pytest.mark.filterwarnings("ignore::xnlos_core.errors.XnlosWarning")  # toy pipelines, e.g. one wall


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    """{kind: package folder} of a package per kind with a template, written by the command line."""
    out = tmp_path_factory.mktemp("new_plugins")
    for kind in KINDS_WITH_TEMPLATE:
        assert main(["new-plugin", kind, f"kit_{kind}", "--out", str(out)]) == 0
    return {kind: out / f"kit_{kind}" for kind in KINDS_WITH_TEMPLATE}


@pytest.fixture
def imported(generated):
    """Import a generated package by kind (its folder on sys.path), forgotten again afterwards."""
    added = []

    def load(kind):
        sys.path.insert(0, str(generated[kind]))
        added.append(kind)
        return importlib.import_module(f"kit_{kind}")

    yield load
    for kind in added:
        sys.path.remove(str(generated[kind]))
        sys.modules.pop(f"kit_{kind}", None)


def pipeline_table(kind: str) -> dict:
    """A small corner pipeline with the generated component in its stage (a class-agnostic detector
    runs detection-only; a tracker follows the hidden points over three frames)."""
    name = f"kit_{kind}"
    if kind == "detector":
        table = small_pipeline_table(detector={"name": name})
        del table["wall_estimator"], table["reconstructor"]
        return table
    if kind == "tracker":
        return small_pipeline_table(tracker={"name": name}, run={"frames": 3, "figure": False})
    return small_pipeline_table(**{kind: {"name": name}})


@pytest.mark.parametrize("kind", KINDS_WITH_TEMPLATE)
def test_generated_plugin_passes_the_kit_and_runs_in_a_pipeline(kind, generated, imported):
    module = imported(kind)
    report = check_component(module)
    base = {"detector": "Detector", "wall_estimator": "WallEstimator", "reconstructor": "Reconstructor",
            "tracker": "Tracker"}[kind]
    assert [r.check for r in report] == [f"is a {base}", "params", f"{kind.replace('_', ' ')} contract"]
    assert all(r.component == f"{kind}:kit_{kind}" and r.steps for r in report)

    manager = PluginManager()  # the installed plugins, and the generated module registered by hand
    manager.register(module, name=f"kit_{kind}")
    config = parse_pipeline(pipeline_table(kind), f"kit_{kind}")
    results = list(Pipeline(config, registry=manager.registry).run())
    assert len(results) == config.run.frames
    gt = results[-1].frame.ground_truth
    if kind == "detector":
        assert all(len(r.detections) > 0 for r in results)
    elif kind == "wall_estimator":  # one line through all LOS points: along one of the scene's walls
        (wall,) = results[0].walls
        assert any(abs(float(wall.normal @ w.normal)) > np.cos(np.radians(5)) and abs(wall.offset - w.offset) < 1.5
                   for w in gt.walls), (wall.normal, wall.offset)
    elif kind == "reconstructor":  # the hidden car, mirrored across the wall its echo bounced off
        hidden = results[0].hidden
        d = np.linalg.norm(hidden.mean[:, None] - gt.hidden_points[None], axis=-1).min(axis=1)
        assert len(hidden) > 0 and d.max() < 0.5, d
    else:  # tracks on the hidden car
        tracks = results[-1].tracks
        assert len(tracks) > 0 and np.linalg.norm(tracks.position - gt.hidden_points.mean(axis=0), axis=1).max() < 4.0


def test_generated_packages_own_tests_pass_under_pytest(generated, tmp_path):
    for root in generated.values():
        project = tomllib.loads((root / "pyproject.toml").read_text())
        name = root.name
        assert project["project"]["entry-points"]["xnlos.plugins"] == {name: name}
        assert project["tool"]["pytest"]["ini_options"]["pythonpath"] == ["."]
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(ROOT), *map(str, generated.values())]))
    (tmp_path / "pytest.ini").write_text("[pytest]\n")
    out = subprocess.run([sys.executable, "-m", "pytest", "-v", "-p", "no:cacheprovider", "--import-mode=importlib",
                          "-c", str(tmp_path / "pytest.ini"), "--rootdir", str(tmp_path),
                          *(str(root / "tests") for root in generated.values())],
                         capture_output=True, text=True, env=env, cwd=tmp_path, timeout=300)
    assert out.returncode == 0, out.stdout[-3000:] + out.stderr[-2000:]
    for kind in KINDS_WITH_TEMPLATE:
        assert f"test_conformance[{kind}:kit_{kind}-params] PASSED" in out.stdout, out.stdout[-3000:]
    assert f"{3 * len(KINDS_WITH_TEMPLATE)} passed" in out.stdout


def test_new_plugin_refuses_what_it_cannot_write(generated, tmp_path, capsys):
    cases = {("backend", "my_backend"): "templates exist for detector, wall_estimator, reconstructor, tracker",
             ("detector", "My-Detector"): "lower-case Python identifier",
             ("detector", "json"): "can already be imported",
             ("detector", "cfar"): "a detector named 'cfar' is already registered",
             ("reconstructor", "kit_reconstructor"): "exists"}
    for (kind, name), message in cases.items():
        out = generated[kind].parent if name == "kit_reconstructor" else tmp_path
        assert main(["new-plugin", kind, name, "--out", str(out)]) == 2
        err = capsys.readouterr().err
        assert message in err and "Traceback" not in err, err
    assert not any(tmp_path.iterdir())
