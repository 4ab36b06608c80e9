"""Fixtures shared by tests/unit and tests/integration: the fuzz budget, a small pipeline table and
tiny learned-detector checkpoints. Test modules never import one another (pytest runs with
``--import-mode=importlib``); what several of them need is a fixture here or in
tests/integration/conftest.py."""
from __future__ import annotations

import os

import pytest
from hypothesis import HealthCheck, settings

from xnlos_core.testing import small_pipeline_table

# Fuzz budget. `make test` runs every `fuzz`-marked test briefly (50 generated cases from the
# `fuzz_cases` fixture; hypothesis' default profile otherwise); `make fuzz` sets XNLOS_FUZZ=long and
# runs only those tests, ≥ 10,000 cases each. Tests must not pin max_examples, so the profile decides.
FUZZ_LONG = os.environ.get("XNLOS_FUZZ") == "long"
settings.register_profile("xnlos-fuzz-long", max_examples=10_000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
if FUZZ_LONG:
    settings.load_profile("xnlos-fuzz-long")


@pytest.fixture(autouse=True)
def _torch_threads_not_load_driven(monkeypatch):
    """Tests run with torch's thread count left as set: the per-frame count that follows the load of the
    machine (xnlos_core.core_share) would make a test's outcome depend on what else runs. Its own
    tests use fakes (tests/unit/test_core_share.py)."""
    from xnlos_core import core_share

    monkeypatch.setattr(core_share, "_governor", False)


@pytest.fixture
def fuzz_cases() -> int:
    """How many generated cases a hand-rolled fuzz loop runs: 50 in `make test`, 10,000 in `make fuzz`."""
    return 10_000 if FUZZ_LONG else 50


@pytest.fixture
def table() -> dict:
    """A fast pipeline table on the built-in corner scene (:func:`xnlos_core.testing.small_pipeline_table`)."""
    return small_pipeline_table()


# Hyper-parameters of untrained learned detectors small enough to build in milliseconds.
TINY_HPARAMS = {
    "swin_unet": dict(embed_dim=8, depths=(2, 2), heads=(2, 2), window=(4, 4), patch=(2, 2), stem_channels=4,
                      head_channels=8),
    "unet": dict(base_channels=4, levels=2), "further_than_cfar": dict(base_channels=4, levels=1),
    "rtn": dict(base_channels=4)}


@pytest.fixture
def tiny_hparams() -> dict[str, dict]:
    """Per learned detector, the tiny hyper-parameters :func:`tiny_checkpoint` builds (a fresh copy)."""
    return {k: dict(v) for k, v in TINY_HPARAMS.items()}


@pytest.fixture
def tiny_checkpoint():
    """``tiny_checkpoint(path, name, seed=0, extra_meta=None, **hparams)`` saves an untrained ``name``
    detector (tiny hyper-parameters, ``hparams`` overriding; torch seeded with ``seed``) as a checkpoint
    at ``path`` and returns the network."""
    import torch

    from plugins.training.checkpoint import save_checkpoint
    from plugins.detectors.nets import architectures
    from plugins.detectors.tasks import default_head

    def save(path, name, seed=0, extra_meta=None, **hparams):
        arch = architectures()[name]
        hp = arch.HParams(**{**TINY_HPARAMS[name], **hparams})
        torch.manual_seed(seed)
        net = arch.module(hp)
        meta = {"architecture": name, "hparams": hp.model_dump(mode="json"),
                "head": default_head(name, hp, (0.7, 1.0)).describe(), "decode": {"threshold": 0.5, "window": [1, 3]},
                **(extra_meta or {})}
        save_checkpoint(path, net, meta)
        return net

    return save


@pytest.fixture(scope="session")
def benchmark_module():
    """Import a script of benchmarks/ (not a package) by its path: ``benchmark_module("forecast_quality")``.
    benchmarks/ is on sys.path while the script loads, as when it runs, for its sibling imports
    (e.g. ``tracking_case``)."""
    import importlib.util
    import sys
    from pathlib import Path

    folder = Path(__file__).resolve().parents[1] / "benchmarks"

    def load(name: str):
        spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
        mod = importlib.util.module_from_spec(spec)
        sys.path.insert(0, str(folder))
        try:
            spec.loader.exec_module(mod)
        finally:
            sys.path.remove(str(folder))
        return mod

    return load
