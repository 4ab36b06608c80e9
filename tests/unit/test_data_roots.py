"""A recording kept outside the project: a symlink out of the config roots is refused with a message
that names the way to allow it (XNLOS_CONFIG_ROOTS), which the user's environment, not a config, sets."""
from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from hardware.recording import Recording
from hardware.testing import write_dca1000_recording
from xnlos_core.errors import ConfigError
from xnlos_core.files import ROOTS_ENV, config_roots
from xnlos_core.param_paths import PathContext, resolve_param_path
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.doppler import add_chirp_noise, chirp_sequence_cube

RADAR = RadarConfig(n_samples=64, bandwidth=384e6, chirp_duration=6.4e-6, n_chirps=4, n_tx=2, n_rx=4,
                    max_range=20.0, n_azimuth_bins=31)


@pytest.fixture
def linked(tmp_path, monkeypatch):
    """(project folder holding capture.toml and a link capture_Raw_0.bin → the data disk, data disk)."""
    monkeypatch.delenv(ROOTS_ENV, raising=False)
    disk, project, cwd = tmp_path / "disk", tmp_path / "project", tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)  # the working directory is a config root too: one that holds neither
    cube = add_chirp_noise(chirp_sequence_cube(RADAR, [6.0], [0.1], [1e-5], [0.0]), RADAR, np.random.default_rng(0))
    write_dca1000_recording(disk, [cube], RADAR, scale=1e-7)
    project.mkdir()
    (project / "capture.toml").write_text((disk / "capture.toml").read_text())
    (project / "capture_Raw_0.bin").symlink_to(disk / "capture_Raw_0.bin")
    return project, disk


def test_a_link_out_of_the_roots_is_refused_naming_the_setting(linked):
    project, _ = linked
    with pytest.raises(ConfigError, match=rf"outside the config roots.*symbolic link.*{ROOTS_ENV}"):
        Recording.from_toml(project / "capture.toml")
    with pytest.raises(ValueError, match=rf"symbolic link.*{ROOTS_ENV}"):
        resolve_param_path("capture_Raw_0.bin", PathContext(project))


def test_the_users_data_roots_allow_it(linked, monkeypatch):
    project, disk = linked
    monkeypatch.setenv(ROOTS_ENV, os.pathsep.join(["", str(disk)]))
    assert disk.resolve() in config_roots(project)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = Recording.from_toml(project / "capture.toml")
    assert rec.n_frames == 1 and rec.path == (disk / "capture_Raw_0.bin").resolve()
    assert resolve_param_path("capture_Raw_0.bin", PathContext(project)) == str(rec.path)


def test_a_fifo_in_a_data_root_is_still_refused(linked, monkeypatch):
    project, disk = linked
    monkeypatch.setenv(ROOTS_ENV, str(disk))
    (disk / "capture_Raw_0.bin").unlink()
    os.mkfifo(disk / "capture_Raw_0.bin")
    with pytest.raises(ConfigError, match="FIFO"):
        Recording.from_toml(project / "capture.toml")


def test_a_plain_path_outside_is_refused_without_the_link_advice(linked):
    project, disk = linked
    toml = project / "capture.toml"
    toml.write_text(toml.read_text().replace('file = "capture_Raw_0.bin"', f'file = "{disk / "capture_Raw_0.bin"}"'))
    with pytest.raises(ConfigError, match="outside the config roots") as err:
        Recording.from_toml(toml)
    assert "symbolic link" not in str(err.value)
