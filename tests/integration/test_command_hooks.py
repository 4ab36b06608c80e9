"""Commands and config checks arrive through hooks: a plugin adds a subcommand the way the built-in
packages add ``simulate``, ``train`` and ``emulate`` (like pytest's ``pytest_addoption``)."""
import argparse

import pytest

from xnlos_core import PluginError, hookimpl
from xnlos_core.app.cli import build_parser, check_file, main
from xnlos_core.registry import PluginManager


class _Greeter:
    """A third-party plugin that owns the ``hello`` command and ``[greeting]`` configs."""

    def __init__(self):
        self.calls = []

    @hookimpl
    def xnlos_add_commands(self, subparsers):
        p = subparsers.add_parser("hello", help="say hello")
        p.add_argument("--name", default="radar")
        p.set_defaults(func=lambda args: self.calls.append(args.name) or 7)

    @hookimpl
    def xnlos_check_config(self, table, path):
        return f"{path}: valid greeting" if "greeting" in table else None


@pytest.fixture()
def manager(monkeypatch):
    import xnlos_core.registry as registry

    mgr = PluginManager()
    greeter = _Greeter()
    mgr.register(greeter, name="greeter", provider="greeter-dist 1.0")
    monkeypatch.setattr(registry, "_MANAGER", mgr)
    return mgr, greeter


def _commands(parser: argparse.ArgumentParser) -> set[str]:
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return set(sub.choices)


def test_builtin_packages_add_their_commands():
    cmds = _commands(build_parser(PluginManager()))
    assert {"run", "demo", "sweep", "eval", "check", "plugins", "crossmodal"} <= cmds  # the application's own
    assert {"simulate", "train", "emulate"} <= cmds  # added by sims, plugins and hardware


def test_without_plugins_only_the_application_commands_remain():
    cmds = _commands(build_parser(PluginManager(autoload=False)))
    assert cmds == {"run", "demo", "sweep", "eval", "check", "plugins", "crossmodal", "new-plugin"}


def test_a_plugin_adds_a_command_and_main_runs_it(manager):
    _, greeter = manager
    assert main(["hello", "--name", "corner"]) == 7
    assert greeter.calls == ["corner"]


def test_a_plugin_checks_its_own_config_kind(manager, tmp_path):
    cfg = tmp_path / "g.toml"
    cfg.write_text('greeting = "hi"\n')
    assert check_file(cfg) == f"{cfg}: valid greeting"
    other = tmp_path / "o.toml"  # not the greeter's: falls through to the pipeline check
    other.write_text('salutation = "hi"\n')
    assert main(["check", str(other)]) == 2


def test_a_command_name_taken_twice_is_an_error(manager):
    mgr, _ = manager

    class _Thief:
        @hookimpl
        def xnlos_add_commands(self, subparsers):
            subparsers.add_parser("simulate")

    mgr.register(_Thief(), name="thief")
    with pytest.raises(PluginError, match="conflicting subparser: simulate.*thief"):
        build_parser(mgr)
    assert main(["plugins"]) == 2  # a clear error, not a traceback
