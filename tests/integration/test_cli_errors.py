"""Every command answers a user's mistake in one or two lines with exit status 2, never a traceback:
an output folder that cannot be written (a place the OS refuses, an existing file), a config that
does not exist, an unknown plugin name in a config, a ``-p`` module that cannot be imported or is no
plugin. Run in process (``main(argv)``): an exception escaping ``main`` fails the test by itself."""
from __future__ import annotations

from pathlib import Path

import pytest

from xnlos_core.app.cli import main

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = ROOT / "configs"
UNWRITABLE = "/proc/xnlos-no-such-dir/out"  # the kernel's /proc refuses new folders


def variant(src: Path, dst: Path, *replacements: tuple[str, str]) -> Path:
    """``src``'s text with each (old, new) replaced once, written to ``dst``."""
    text = src.read_text()
    for old, new in replacements:
        assert old in text, (src, old)
        text = text.replace(old, new, 1)
    dst.write_text(text)
    return dst


def bad_plugin_config(kind: str, tmp: Path) -> Path:
    """A config of ``kind`` whose plugin name is misspelt (its nearest registered name is real)."""
    if kind == "pipeline":
        return variant(CONFIGS / "pipelines" / "corner.toml", tmp / "pipeline.toml",
                       ('file = "../scenes/corner.toml"', 'builtin = "corner"'), ('"nlos_cfar"', '"nlos_cfa"'),
                       ('name = "image"', 'name = "imag"'))
    if kind == "train":
        return variant(CONFIGS / "training" / "tiny.toml", tmp / "train.toml", ('"swin_unet"', '"swin_unt"'))
    if kind == "simulate":
        return variant(CONFIGS / "datasets" / "smoke.toml", tmp / "data.toml",
                       ('preset = "../radar/xband_default.toml"', 'preset = "xband_default"'),
                       ('name = "image"', 'name = "imag"'))
    return variant(CONFIGS / "ablations" / "crossmodal.toml", tmp / "study.toml",
                   ('["xband", "radar77"]', '["xbnd", "radar77"]'))


# command → (argv before the options, its config kind or None, whether it takes --out)
COMMANDS = {
    "run": (["run", "{config}"], "pipeline", "--out"),
    "demo": (["demo"], None, "--out"),
    "sweep": (["sweep", "{config}"], "pipeline", "--out"),
    "eval": (["eval", "{config}", "--limit", "1", "--no-figures"], "pipeline", "--out"),
    "check": (["check", "{config}"], "pipeline", None),
    "plugins": (["plugins"], None, None),
    "crossmodal": (["crossmodal", "{config}", "--no-figures"], "crossmodal", "--out"),
    "train": (["train", "{config}"], "train", "--out"),
    "simulate": (["simulate", "{config}", "--max-maps", "1"], "simulate", "--out"),
    "emulate": (["emulate", "--config", "{config}", "--frames", "1"], "pipeline", "--record"),
    "new-plugin": (["new-plugin", "detector", "my_detector"], None, "--out"),
}
SHIPPED = {"pipeline": CONFIGS / "pipelines" / "corner.toml", "train": CONFIGS / "training" / "tiny.toml",
           "simulate": CONFIGS / "datasets" / "smoke.toml", "crossmodal": CONFIGS / "ablations" / "crossmodal.toml"}


def cases():
    for cmd, (argv, kind, out) in COMMANDS.items():
        if out:
            yield cmd, "unwritable --out"
            yield cmd, "--out names a file"
        if kind:
            yield cmd, "missing config"
            yield cmd, "unknown plugin"
        yield cmd, "bad -p"
        yield cmd, "-p without hooks"


@pytest.mark.parametrize("cmd,case", list(cases()))
def test_user_mistake_is_one_line_and_exit_2(cmd, case, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    argv, kind, out = COMMANDS[cmd]
    config = SHIPPED.get(kind)
    extra: list[str] = []
    if case == "missing config":
        config = tmp_path / "missing.toml"
    elif case == "unknown plugin":
        config = bad_plugin_config(kind, tmp_path)
    if out:
        target = tmp_path / "out"
        if case == "unwritable --out":
            target = Path(UNWRITABLE)
        elif case == "--out names a file":
            target = tmp_path / "a-file"
            target.write_text("x")
        extra = [out, str(target / "log.blf") if out == "--record" and case != "--out names a file" else str(target)]
    argv = [a.replace("{config}", str(config)) for a in argv] + extra
    if case == "bad -p":
        argv = ["-p", "no_such_module_xyz"] + argv
    elif case == "-p without hooks":
        argv = ["-p", "json"] + argv
    rc = main(argv)
    err = capsys.readouterr().err
    assert rc == 2, (argv, err)
    assert "Traceback" not in err
    lines = [line for line in err.splitlines() if line.strip() and not line.startswith("xnlos: warning")]
    assert 1 <= len(lines) <= 2, err
    expected = {"unwritable --out": "xnlos-no-such-dir", "--out names a file": "a-file",
                "missing config": "missing.toml", "unknown plugin": "did you mean",
                "bad -p": "no_such_module_xyz", "-p without hooks": "none of the xnlos hooks"}[case]
    assert expected in err, err
