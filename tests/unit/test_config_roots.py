"""Config paths resolve against the config file wherever the user stands: the config's project (the
nearest xnlos.toml / pyproject.toml above it) is a root, so a shipped config checks from its own folder
and by absolute path from anywhere; other folders are allowed only by the user (--root,
XNLOS_CONFIG_ROOTS, [paths] roots of the project's xnlos.toml), and a path out of every root is still
refused with the reason and the ways to allow it."""
from pathlib import Path

import pytest

from xnlos_core.app.cli import main
from xnlos_core.errors import ConfigError
from xnlos_core.files import ROOTS_ENV, config_roots, project_root, resolve_config_path

ROOT = Path(__file__).resolve().parents[2]
CORNER = ROOT / "configs" / "pipelines" / "corner.toml"


def test_shipped_config_checks_from_its_folder_and_by_absolute_path(monkeypatch, tmp_path, capsys):
    monkeypatch.chdir(CORNER.parent)
    assert main(["check", "corner.toml"]) == 0
    monkeypatch.chdir(tmp_path)
    assert main(["check", str(CORNER)]) == 0
    assert "valid" in capsys.readouterr().out


@pytest.fixture
def lab(tmp_path, monkeypatch):
    """A project (xnlos.toml) whose config names a radar preset kept in a shared folder outside it."""
    monkeypatch.setenv(ROOTS_ENV, "")  # recorded, so what `--root` adds to it is undone after the test
    shared = tmp_path / "shared"
    shared.mkdir()
    (shared / "radar.toml").write_text("n_azimuth_bins = 31\n")
    project = tmp_path / "project"
    (project / "configs").mkdir(parents=True)
    (project / "xnlos.toml").write_text("")
    monkeypatch.chdir(tmp_path / "project" / "configs")
    return project, shared


def _resolve(project):
    return resolve_config_path("../../shared/radar.toml", source="c.toml", key="radar.preset",
                               base_dir=project / "configs")


def test_outside_the_roots_is_refused_naming_the_ways_to_allow_it(lab):
    project, _ = lab
    assert project_root(project / "configs") == project.resolve()
    with pytest.raises(ConfigError, match=r"outside the config roots .*--root DIR.*XNLOS_CONFIG_ROOTS.*\[paths\]"):
        _resolve(project)


def test_the_user_allows_a_shared_folder(lab, monkeypatch):
    project, shared = lab
    monkeypatch.setenv(ROOTS_ENV, str(shared))
    assert _resolve(project) == (shared / "radar.toml").resolve()
    monkeypatch.setenv(ROOTS_ENV, "")
    (project / "xnlos.toml").write_text('[paths]\nroots = ["../shared"]\n')  # relative to the project file
    assert shared.resolve() in config_roots(project / "configs")
    assert _resolve(project) == (shared / "radar.toml").resolve()


def test_root_flag_of_the_command_line(lab, monkeypatch, capsys):
    import os

    project, shared = lab
    cfg = project / "configs" / "p.toml"
    cfg.write_text(CORNER.read_text().replace('file = "../scenes/corner.toml"', 'builtin = "corner"')
                   .replace('preset = "xband_default"', 'preset = "../../shared/radar.toml"'))
    assert main(["check", str(cfg)]) == 2
    assert "outside the config roots" in capsys.readouterr().err
    assert main(["--root", str(shared), "check", str(cfg)]) == 0
    assert str(shared) in os.environ[ROOTS_ENV]  # worker processes see it too
    assert main(["--root", str(shared / "nope"), "check", str(cfg)]) == 2


def test_a_broken_project_file_is_named(lab):
    project, _ = lab
    (project / "xnlos.toml").write_text("[paths]\nroots = 3\n")
    with pytest.raises(ConfigError, match=r"xnlos.toml: \[paths\] roots must be a list"):
        config_roots(project / "configs")
