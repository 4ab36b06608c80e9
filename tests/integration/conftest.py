"""Fixtures of the integration tests: the tiny scene plugin and tiny datasets built once per session,
eval and sweep configs, the CAN fault matrix with its expected outcomes, and the third-party demo
plugin installed into a temporary directory (never into the running environment)."""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tiny_scenes  # tests/plugins (pytest's `pythonpath`): the user-plugin way of adding scene generators

TESTS = Path(__file__).resolve().parents[1]
TINY_RADAR = {"n_samples": 128, "max_range": 30.0, "n_azimuth_bins": 31}


# --- the tiny scene generators (corner_a, corner_b, corner_c) and datasets made of them -----------

@pytest.fixture(scope="session")
def tiny_plugin():
    """The tiny scene plugin module (``FAMILIES``, ``tiny_scene``, ``tiny_manager``, ``tiny_registry``)."""
    return tiny_scenes


@pytest.fixture(scope="session")
def tiny_plugin_env() -> dict[str, str]:
    """The environment in which a subprocess ``xnlos -p tiny_scenes ...`` finds the tiny plugin."""
    path = os.pathsep.join(p for p in (str(TESTS / "plugins"), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}


@pytest.fixture
def tiny_cli(monkeypatch):
    """In-process ``main([...])`` and every registry lookup see the tiny scene generators (as after
    ``xnlos -p tiny_scenes``); the process-wide manager is restored afterwards."""
    import xnlos_core.registry as registry_module

    monkeypatch.setattr(registry_module, "_MANAGER", tiny_scenes.tiny_manager())


def _dataset_table(**over) -> dict:
    t = {"name": "tiny", "seed": 7, "n_maps": 12, "shard_size": 2, "families": list(tiny_scenes.FAMILIES),
         "radar": dict(TINY_RADAR), "forward_model": {"name": "image"},
         "split": {"train": 0.5, "val": 0.25, "test": 0.25}}
    t.update(over)
    return t


def _dataset_cfg(**over):
    from sims.dataset import parse_dataset_config

    return parse_dataset_config(_dataset_table(**over), "tiny.toml")


def _simulate_tiny(config, out, **kw):
    from sims.dataset import simulate_dataset

    return simulate_dataset(config, out, registry=tiny_scenes.tiny_registry(), **kw)


def _simulate(out: Path, **over) -> Path:
    _simulate_tiny(_dataset_cfg(**over), out, workers=1, progress=False)
    return out


@pytest.fixture(scope="session")
def simulate_tiny():
    """``simulate_tiny(config, out, **kw)``: ``sims.dataset.simulate_dataset`` with the tiny scene
    generators registered."""
    return _simulate_tiny


@pytest.fixture(scope="session")
def dataset_table():
    """``dataset_table(**over)``: a tiny dataset config table (12 maps of 31 × 97 bins, shards of 2,
    the three tiny families, split 50/25/25), each keyword replacing one top-level key."""
    return _dataset_table


@pytest.fixture(scope="session")
def dataset_cfg():
    """``dataset_cfg(**over)``: :func:`dataset_table` parsed into a DatasetConfig."""
    return _dataset_cfg


@pytest.fixture(scope="session")
def shard_hashes():
    """``shard_hashes(out)``: {shard name: sha256} from the dataset's manifest."""
    from sims.dataset import read_manifest

    return lambda out: {s["name"]: s["sha256"] for s in read_manifest(out)["shards"]}


@pytest.fixture(scope="session")
def reference_dataset(tmp_path_factory) -> Path:
    """An uninterrupted inline run of the tiny config (12 maps). Read only: copy it to change it."""
    return _simulate(tmp_path_factory.mktemp("ref"))


@pytest.fixture(scope="session")
def small_dataset(tmp_path_factory) -> Path:
    """A 4-map tiny dataset (one shard per split and more), for the `dataset` backend. Read only."""
    return _simulate(tmp_path_factory.mktemp("small"), n_maps=4)


@pytest.fixture(scope="session")
def tiny_dataset(tmp_path_factory) -> Path:
    """8 tiny maps (4 test maps), image forward model: the dataset `xnlos eval` runs on. Read only."""
    return _simulate(tmp_path_factory.mktemp("ds"), n_maps=8, split={"train": 0.25, "val": 0.25, "test": 0.5})


# The classical stages (CFAR peaks classified against the wall, total least squares, Eq. 7 mirror).
CLASSICAL_STAGES = """[detector]
name = "nlos_cfar"
[wall_estimator]
name = "lsq"
[reconstructor]
name = "mirror"
"""


@pytest.fixture(scope="session")
def eval_config():
    """``eval_config(tmp_path, dataset, extra="")``: write an eval pipeline on ``dataset``'s test split
    (nlos_cfar → lsq → mirror) plus ``extra`` TOML to tmp_path/eval.toml and return its path."""
    def write(tmp_path: Path, dataset: Path, extra: str = "") -> Path:
        p = tmp_path / "eval.toml"
        p.write_text(f'name = "tiny-eval"\n[backend]\nname = "dataset"\n'
                     f'params = {{ path = "{dataset}", split = "test" }}\n' + CLASSICAL_STAGES + extra)
        return p

    return write


@pytest.fixture(scope="session")
def sweep_toml() -> str:
    """A one-frame corner pipeline with a `[sweep]` over two detectors (cfar, nlos_cfar)."""
    return ("""
name = "tiny-sweep"
seed = 2
[radar]
n_samples = 256
max_range = 60.0
n_azimuth_bins = 121
[scene]
builtin = "corner"
[forward_model]
name = "image"
""" + CLASSICAL_STAGES + """[run]
frames = 1
figure = false
[sweep]
"detector.name" = ["cfar", "nlos_cfar"]
""")


# --- the CAN link -------------------------------------------------------------------------------

def _fault_matrix() -> dict:
    """Fault case → (faults, delivered sequence numbers, lost (seq, kind), exact link counters).
    Built afresh for each test: a Fault rule fires once."""
    from hardware.faults import Fault

    return {
        "drop_cf": ([Fault("drop", 2, "cf", 3)], [0, 1, 3, 4, 5, 6], [(2, "incomplete")], {"transfer_errors": 1}),
        "drop_header": ([Fault("drop", 2, "header")], [0, 1, 3, 4, 5, 6], [(2, "incomplete")], {"transfer_errors": 0}),
        "drop_first_frame": ([Fault("drop", 2, "ff")], [0, 1, 3, 4, 5, 6], [(2, "incomplete")], {}),
        "duplicate_cf": ([Fault("duplicate", 2, "cf", 3)], [0, 1, 3, 4, 5, 6], [(2, "incomplete")],
                         {"transfer_errors": 1}),
        "duplicate_header": ([Fault("duplicate", 2, "header")], [0, 1, 2, 3, 4, 5], [], {"frames_duplicate": 0}),
        "duplicate_first_frame": ([Fault("duplicate", 2, "ff")], [0, 1, 2, 3, 4, 5], [], {"transfer_errors": 1}),
        "reorder_cf": ([Fault("reorder", 2, "cf", 3)], [0, 1, 3, 4, 5, 6], [(2, "incomplete")],
                       {"transfer_errors": 1}),
        "reorder_header_past_payload": ([Fault("reorder", 2, "last"), Fault("reorder", 3, "header")],
                                        [0, 1, 2, 3, 4, 5], [], {}),
        "corrupt_cf": ([Fault("corrupt", 2, "cf", 3)], [0, 1, 3, 4, 5, 6], [(2, "corrupted")],
                       {"transfer_errors": 0}),
        "corrupt_header": ([Fault("corrupt", 2, "header")], [0, 1, 3, 4, 5, 6], [(2, "incomplete")],
                           {"e2e_errors": 1}),
        "checksum_mismatch": ([Fault("checksum", 2, "header")], [0, 1, 3, 4, 5, 6], [(2, "corrupted")], {}),
        "absurd_header_size": ([Fault("oversize", 2, "header")], [0, 1, 3, 4, 5, 6], [(2, "corrupted")], {}),
        "truncated_transfer": ([Fault("truncate", 2, "cf", 3)], [0, 1, 3, 4, 5, 6], [(2, "incomplete")],
                               {"transfer_errors": 1}),
        "truncated_last_frame": ([Fault("truncate", 5, "cf", 1)], [0, 1, 2, 3, 4, 6], [(5, "incomplete")], {}),
        "error_frame": ([Fault("error_frame", 2, "cf", 3)], [0, 1, 2, 3, 4, 5], [], {"error_frames": 1}),
        "several": ([Fault("drop", 1, "cf", 0), Fault("checksum", 3, "header"), Fault("duplicate", 4, "header")],
                    [0, 2, 4, 5, 6, 7], [(1, "incomplete"), (3, "corrupted")], {}),
    }


FAULT_CASES = tuple(_fault_matrix())


def pytest_generate_tests(metafunc):
    """A test taking ``fault_case`` runs once per case of the fault matrix, unless it parametrizes
    ``fault_case`` itself (test_can_consumer picks a few)."""
    if "fault_case" not in metafunc.fixturenames:
        return
    own = {n.strip() for m in metafunc.definition.iter_markers("parametrize")
           for n in (m.args[0].split(",") if isinstance(m.args[0], str) else m.args[0])}
    if "fault_case" not in own:
        metafunc.parametrize("fault_case", FAULT_CASES)


@pytest.fixture
def fault_matrix() -> dict:
    """:func:`_fault_matrix`, fresh Fault objects for this test."""
    return _fault_matrix()


@pytest.fixture(scope="session")
def emulated_reference():
    """``emulated_reference(seed, k, interval=0.05, radar=small_radar(), adc=False)``: frame ``k`` that the
    emulator seeded ``seed`` sends for the corner scene (image model, noise from child ``k`` of the
    seed), computed here independently of the link; with ``adc`` the (ADC cube, frame) pair."""
    from hardware.testing import small_radar
    from xnlos_core.registry import get_registry
    from xnlos_core.scene import load_scene

    scene, small = load_scene({"builtin": "corner"}, "test"), small_radar()

    def reference(seed, k, interval=0.05, radar=None, adc=False):
        fm = get_registry().create("forward_model", "image")
        rng = np.random.default_rng(np.random.SeedSequence(seed).spawn(k + 1)[k])
        if adc:
            return fm.simulate_adc(scene, radar or small, rng, timestamp=k * interval, index=k)
        return fm.simulate(scene, radar or small, rng, timestamp=k * interval, index=k)

    return reference


# --- the third-party demo plugin ------------------------------------------------------------------

@pytest.fixture(scope="session")
def thirdparty_env(tmp_path_factory) -> dict[str, str]:
    """An environment whose Python sees tests/thirdparty_plugin as an installed distribution: pip
    installs it (built offline from a copy of its source, so the tree stays clean) into a temporary
    ``--target`` directory that goes on PYTHONPATH. importlib.metadata finds its dist-info and so its
    ``xnlos.plugins`` entry point there, as in site-packages; the running environment is untouched."""
    import importlib.metadata as md

    def installed() -> set[tuple[str, str]]:
        return {(d.metadata["Name"], d.version) for d in md.distributions()}

    base = tmp_path_factory.mktemp("thirdparty")
    src, target = base / "src", base / "site"
    shutil.copytree(TESTS / "thirdparty_plugin", src)
    before = installed()
    subprocess.run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--no-build-isolation",
                    "--no-index", "--disable-pip-version-check", "--target", str(target), str(src)],
                   check=True, capture_output=True)
    assert installed() == before, "pip --target changed the environment running the tests"
    path = os.pathsep.join(p for p in (str(target), os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path, "XNLOS_TEST_PLUGIN_TARGET": str(target)}
