"""Atomic writes leave the permissions a plain open() would (0666 & ~umask), not mkstemp's 0600."""
import os
import stat

import pytest

from xnlos_core.io import atomic_write_bytes, atomic_write_text, write_jsonl


@pytest.fixture
def umask():
    """``umask(mask)`` sets the process umask for the test; the old one is restored afterwards."""
    old = os.umask(0o022)
    os.umask(old)
    yield os.umask
    os.umask(old)


def _mode(path) -> int:
    return stat.S_IMODE(os.stat(path).st_mode)


@pytest.mark.parametrize("mask, expected", [(0o022, 0o644), (0o077, 0o600), (0o002, 0o664)])
def test_new_file_gets_0666_less_umask(tmp_path, umask, mask, expected):
    umask(mask)
    atomic_write_text(tmp_path / "summary.md", "# run\n")
    atomic_write_bytes(tmp_path / "frame_0000.png", b"\x89PNG")
    write_jsonl(tmp_path / "results.jsonl", [{"frame": 0}])
    for name in ("summary.md", "frame_0000.png", "results.jsonl"):
        assert _mode(tmp_path / name) == expected, (name, oct(_mode(tmp_path / name)))
    with open(tmp_path / "plain.txt", "w") as fh:  # the reference: what open() itself gives
        fh.write("x")
    assert _mode(tmp_path / "plain.txt") == expected


def test_existing_file_keeps_its_permissions(tmp_path, umask):
    umask(0o022)
    p = tmp_path / "provenance.json"
    p.write_text("{}")
    os.chmod(p, 0o640)
    atomic_write_text(p, '{"seed": 1}\n')
    assert _mode(p) == 0o640 and p.read_text() == '{"seed": 1}\n'


def test_no_temporary_file_is_left(tmp_path, umask):
    umask(0o022)
    atomic_write_text(tmp_path / "a.json", "{}")
    assert [p.name for p in tmp_path.iterdir()] == ["a.json"]
