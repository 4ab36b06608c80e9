"""Shared fixtures: a small fast pipeline table and the installed third-party plugin."""
from __future__ import annotations

import copy
import importlib.metadata as md
import subprocess
import sys
from pathlib import Path

import pytest

HERE = Path(__file__).parent

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
