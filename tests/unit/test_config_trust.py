"""Regression tests of the trust fixes item 6: every bad config input ends in a typed error, `check`
refuses what `run` would crash on, files are regular files inside the config roots."""
from __future__ import annotations

import os
import signal
import textwrap
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import pytest

from sims.meshes import ConfinedResolver, load_user_mesh
from xnlos_core.signal.antenna import coupling_matrix
from xnlos_core.app.cli import check_file, main
from xnlos_core.config import load_toml
from xnlos_core.errors import ConfigError, InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.scene import MeshSpec

ROOT = Path(__file__).resolve().parents[2]
PIPELINE = """\
seed = 1
[radar]
n_samples = 256
max_range = 60.0
n_azimuth_bins = 61
{radar}
[scene]
{scene}
[forward_model]
name = "image"
[detector]
name = "nlos_cfar"
[wall_estimator]
name = "lsq"
[reconstructor]
name = "mirror"
"""
WALL = '[[scene.walls]]\nstart = [{x}, 10.0]\nend = [35.0, -10.0]\n'


@contextmanager
def no_hang(seconds=60):
    """A blocking read (the bug) fails the test instead of hanging the suite."""
    def boom(*_):
        raise AssertionError(f"blocked for {seconds} s")
    old = signal.signal(signal.SIGALRM, boom)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture
def proj(tmp_path, monkeypatch):
    """A project folder as the working directory; configs are written into proj/cfg/."""
    (tmp_path / "cfg").mkdir()
    monkeypatch.chdir(tmp_path)
    return tmp_path


def write(proj, text, name="p.toml"):
    path = proj / "cfg" / name
    path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
    return path


def pipeline(proj, radar="", scene='builtin = "corner"'):
    return write(proj, PIPELINE.format(radar=radar, scene=scene))


def test_valid_pipeline_passes(proj):
    assert "valid (1 pipeline(s))" in check_file(pipeline(proj))


@pytest.mark.parametrize("deep", ["[" * 5000 + "]" * 5000, "{a = " * 5000 + "1" + "}" * 5000, "[" * 40 + "]" * 40])
def test_deep_nesting_is_a_config_error(proj, deep):
    with pytest.raises(ConfigError, match=r"p\.toml.*nested"):
        check_file(write(proj, f"x = {deep}\n"))


def test_invalid_utf8_names_file_and_byte(proj):
    path = write(proj, b'name = "ok"\nseed = 1 # \xff\n')
    with pytest.raises(ConfigError, match=r"p\.toml: not UTF-8 text: byte 23 \(line 2\)"):
        load_toml(path)


@pytest.mark.parametrize("preset, match", [("3.5", r"\[radar\.preset\] expected a non-empty file path string, got 3\.5"),
                                           ('"' + "x" * 300 + '.toml"', "too long"),
                                           ('"{outside}"', "outside the config roots"),
                                           ('"../../../../../../../../../outside.toml"', "outside the config roots"),
                                           ('"/etc/hostname.toml"', "outside the config roots"),
                                           ('"dir.toml"', "a directory; expected a regular file"),
                                           ('"fifo.toml"', "a FIFO")])
def test_bad_preset_paths(proj, preset, match, tmp_path_factory):
    outside = tmp_path_factory.mktemp("elsewhere") / "outside.toml"
    outside.write_text("n_samples = 256\n")
    preset = preset.format(outside=outside)
    (proj / "cfg" / "dir.toml").mkdir()
    os.mkfifo(proj / "cfg" / "fifo.toml")
    text = PIPELINE.format(radar="", scene='builtin = "corner"').replace("[radar]\n", f"[radar]\npreset = {preset}\n")
    with no_hang(), pytest.raises(ConfigError, match=match):
        check_file(write(proj, text))


def test_preset_in_working_directory_is_allowed(proj):
    """configs/pipelines/*.toml name ../radar/…: allowed because the working directory holds both."""
    (proj / "radar").mkdir()
    (proj / "radar" / "r.toml").write_text("[radar]\nn_samples = 256\nmax_range = 60.0\n")
    text = PIPELINE.replace("n_samples = 256\n", "preset = \"../radar/r.toml\"\n").format(radar="", scene='builtin = "corner"')
    assert "valid" in check_file(write(proj, text))


def test_symlink_out_of_the_roots_is_refused(proj, tmp_path_factory):
    outside = tmp_path_factory.mktemp("elsewhere") / "r.toml"
    outside.write_text("n_samples = 256\n")
    (proj / "cfg" / "r.toml").symlink_to(outside)
    with pytest.raises(ConfigError, match="outside the config roots"):
        check_file(pipeline(proj, radar='preset = "r.toml"'))


def test_heads_zero_is_a_config_error(proj):
    text = (ROOT / "configs" / "training" / "swin_unet.toml").read_text().replace("heads = [3, 6]", "heads = [0, 4]")
    assert "heads = [0, 4]" in text
    with pytest.raises(ConfigError, match=r"heads\.0.*greater than or equal to 1"):
        check_file(write(proj, text))


@pytest.mark.parametrize("name", ["[nan, 1.0]", "{ a = 1 }", "3"])
def test_model_name_that_is_no_string_is_a_config_error(proj, name):
    # found by `make fuzz` (16 of 10,000 cases: TypeError unhashable type from the trainer lookup)
    text = (ROOT / "configs" / "training" / "tiny.toml").read_text()
    text = text.replace('name = "swin_unet"', f"name = {name}", 1)
    assert f"name = {name}" in text
    with pytest.raises(ConfigError, match=r"\[model\] name"):
        check_file(write(proj, text))


@pytest.mark.parametrize("x", ["1e308", "2147483648.0", "nan", "inf", "-1e5"])
def test_check_refuses_wall_coordinates_run_cannot_handle(proj, x):
    with pytest.raises(ConfigError, match=r"walls\.0\.start\.0"):
        check_file(pipeline(proj, scene=WALL.format(x=x)))


def test_oversized_wall_sampling_is_refused(proj):
    scene = '[[scene.walls]]\nstart = [-9000.0, 10.0]\nend = [9000.0, 10.0]\nspacing = 0.006\n'
    with pytest.raises(ConfigError, match="more than 1000000 scatterers"):
        check_file(pipeline(proj, scene=scene))


def test_coupling_file_fifo_is_refused_without_blocking(proj):
    os.mkfifo(proj / "cfg" / "c.npy")
    with no_hang(), pytest.raises(ConfigError, match=r"radar\.coupling_file.*a FIFO"):
        check_file(pipeline(proj, radar='coupling_file = "c.npy"'))
    # the reader itself never blocks, even given a FIFO directly (e.g. swapped in after the check)
    with no_hang(), pytest.raises(InputError, match="FIFO"):
        coupling_matrix(RadarConfig(coupling_file=str(proj / "cfg" / "c.npy")))


def test_check_reads_the_coupling_matrix_like_run(proj):
    np.save(proj / "cfg" / "c.npy", np.eye(3))
    with pytest.raises(InputError, match=r"expected a finite \(32, 32\) matrix"):
        check_file(pipeline(proj, radar='coupling_file = "c.npy"'))
    np.save(proj / "cfg" / "c.npy", np.eye(32))
    assert "valid" in check_file(pipeline(proj, radar='coupling_file = "c.npy"'))


@pytest.mark.parametrize("name", ['"../../x"', '"/etc/passwd"', "3", '"corner/../corner"'])
def test_builtin_scene_is_a_name_not_a_path(proj, name):
    with pytest.raises(ConfigError, match=r"\[scene\.builtin\] unknown scene"):
        check_file(pipeline(proj, scene=f"builtin = {name}"))


def test_scene_base_dir_cannot_be_set(proj):
    with pytest.raises(ConfigError, match=r"scene\.base_dir"):
        check_file(pipeline(proj, scene='base_dir = "/"'))


def test_check_runs_the_forward_models_scene_check(proj):
    """The image model cannot render meshes: check says so (it used to pass and run failed)."""
    (proj / "cfg" / "box.stl").write_bytes((ROOT / "tests" / "data" / "meshes" / "box.stl").read_bytes())
    scene = 'builtin = "corner"\n[[scene.meshes]]\nfile = "box.stl"\n'
    with pytest.raises(InputError, match="image method handles walls and objects only"):
        check_file(pipeline(proj, scene=scene))
    bad = 'builtin = "corner"\n[[scene.meshes]]\nfile = "../../../etc/passwd.obj"\n'
    with pytest.raises(ConfigError, match=r"meshes\.0\.file"):
        check_file(pipeline(proj, scene=bad))


OBJ = "mtllib {lib}\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nusemtl secret\nf 1 2 3\nf 1 2 4\nf 1 3 4\nf 2 3 4\n"


def test_obj_mtllib_cannot_leave_the_mesh_folder(tmp_path):
    secret = tmp_path / "secret.mtl"
    secret.write_text("newmtl secret\n")
    meshes = tmp_path / "a" / "b"
    meshes.mkdir(parents=True)
    (meshes / "m.obj").write_text(OBJ.format(lib="../../secret.mtl"))
    with pytest.raises(InputError, match=r"mtllib '\.\./\.\./secret\.mtl' leaves the mesh's folder"):
        load_user_mesh(MeshSpec(file="m.obj", material="concrete"), meshes)
    # a symlink beside the mesh that points out of the folder is refused by the resolver
    (meshes / "lib.mtl").symlink_to(secret)
    with pytest.raises(OSError, match="outside the mesh's folder"):
        ConfinedResolver(meshes).get("lib.mtl")
    os.mkfifo(meshes / "fifo.mtl")
    with no_hang(), pytest.raises(OSError, match="FIFO"):
        ConfinedResolver(meshes).get("fifo.mtl")


def test_obj_mtllib_beside_the_mesh_still_tags_parts(tmp_path):
    (tmp_path / "m.mtl").write_text("newmtl secret\n")
    (tmp_path / "m.obj").write_text(OBJ.format(lib="m.mtl"))
    parts = load_user_mesh(MeshSpec(file="m.obj", materials={"secret": "concrete"}), tmp_path)
    assert [tag for _, _, tag in parts] == ["secret"]


def test_config_that_is_a_fifo_is_refused(proj):
    os.mkfifo(proj / "cfg" / "p.toml")
    with no_hang(), pytest.raises(ConfigError, match="a FIFO"):
        check_file(proj / "cfg" / "p.toml")


def test_cli_reports_typed_errors_in_one_line_without_traceback(proj, capsys):
    path = write(proj, b"seed = \xff\n")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.startswith("xnlos: error: ") and "not UTF-8" in err and "Traceback" not in err
    assert err.count("\n") == 1
    assert main(["check", str(pipeline(proj))]) == 0


def test_dataset_and_training_preset_escape_is_refused(proj):
    text = textwrap.dedent("""\
        families = ["crossroads"]
        n_maps = 2
        shard_size = 2
        [radar]
        preset = "../../../../../../etc/passwd.toml"
        [forward_model]
        name = "image"
        """)
    with pytest.raises(ConfigError, match=r"radar\.preset"):
        check_file(write(proj, text))


def test_config_cannot_move_its_own_base_dir(proj):
    """base_dir = "/" would make every absolute path a path inside the config root."""
    with pytest.raises(ConfigError, match=r"\[base_dir\] is set by the loader"):
        check_file(write(proj, 'base_dir = "/"\n' + PIPELINE.format(radar='preset = "etc/passwd.toml"',
                                                                   scene='builtin = "corner"')))


def test_nan_target_width_is_refused(proj):
    text = (ROOT / "configs" / "training" / "unet.toml").read_text()
    text = text.replace("sigma = [0.7, 1.0]", "sigma = [0.7, nan]")
    assert "sigma = [0.7, nan]" in text
    with pytest.raises(ConfigError, match=r"model\.sigma"):
        check_file(write(proj, text))
