"""Shared fixtures: a small fast pipeline table and the installed third-party plugin."""
from __future__ import annotations

import copy
import importlib.metadata as md
import os
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

HERE = Path(__file__).parent

# Fuzz budget. `make test` runs every `fuzz`-marked test briefly (hypothesis' default 100 examples,
# or the `fuzz_cases` fixture's 200 generated cases); `make fuzz` sets XNLOS_FUZZ=long and runs only
# those tests, ≥ 10,000 cases each. Tests must not pin max_examples, so the profile decides.
FUZZ_LONG = os.environ.get("XNLOS_FUZZ") == "long"
settings.register_profile("xnlos-fuzz-long", max_examples=10_000, deadline=None,
                          suppress_health_check=[HealthCheck.too_slow])
if FUZZ_LONG:
    settings.load_profile("xnlos-fuzz-long")


@pytest.fixture
def fuzz_cases() -> int:
    """How many generated cases a hand-rolled fuzz loop runs: 200 in `make test`, 10,000 in `make fuzz`."""
    return 10_000 if FUZZ_LONG else 200

SMALL_RADAR = {"n_samples": 256, "max_range": 60.0, "n_azimuth_bins": 121}


def small_table(**over) -> dict:
    """A fast pipeline table on the built-in corner scene (60 m, 1° azimuth bins)."""
    t = {
        "name": "small", "seed": 5, "radar": dict(SMALL_RADAR), "scene": {"builtin": "corner"},
        "forward_model": {"name": "image"}, "detector": {"name": "nlos_cfar"},
        "wall_estimator": {"name": "lsq"}, "reconstructor": {"name": "mirror"},
        "run": {"frames": 1, "figure": False},
    }
    for k, v in over.items():
        t[k] = copy.deepcopy(v)
    return t


@pytest.fixture
def table():
    return small_table()


@pytest.fixture(scope="session")
def thirdparty_installed():
    """Install tests/thirdparty_plugin into this venv (the way a user installs a plugin)."""
    try:
        md.distribution("xnlos-thirdparty-demo")
    except md.PackageNotFoundError:
        cmd = [sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", str(HERE / "thirdparty_plugin")]
        try:
            import setuptools  # noqa: F401  (build offline when the venv can)
            cmd.insert(5, "--no-build-isolation")
        except ImportError:
            pass
        subprocess.run(cmd, check=True)
    return "xnlos-thirdparty-demo"
