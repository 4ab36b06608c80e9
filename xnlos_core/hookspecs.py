"""pluggy hook specifications of xnlos (project name ``xnlos``).

Plugins implement these with ``@xnlos_core.hookimpl`` in a module exposed through the
``xnlos.plugins`` entry-point group; built-in plugins do exactly the same.
"""
from __future__ import annotations

import pluggy

hookspec = pluggy.HookspecMarker("xnlos")
hookimpl = pluggy.HookimplMarker("xnlos")


@hookspec(historic=True)
def xnlos_register_components(registry) -> None:
    """Register components with ``registry.add(kind, name, factory)``.

    Called once for every plugin when it is registered (historic: plugins registered later are
    called too). ``kind`` is one of :data:`xnlos_core.interfaces.KINDS` (the six pipeline stages,
    ``scene_generator`` and ``nlos_solver``); ``factory`` is a
    class with a pydantic ``Params`` model that subclasses the kind's interface. Returns nothing;
    all implementations are called.
    """


@hookspec
def xnlos_add_commands(subparsers) -> None:
    """Add command-line subcommands, as pytest's ``pytest_addoption`` adds options.

    ``subparsers`` is the ``argparse`` sub-parser action of ``xnlos``: call
    ``subparsers.add_parser(name, help=...)``, add the arguments and ``set_defaults(func=f)`` where
    ``f(args) -> int`` is the exit status. The package that owns a command adds it (``simulate`` by
    ``sims``, ``train`` by ``plugins``, ``emulate`` by ``hardware``); keep the hook light and import
    the command's work inside ``f``. A name that another plugin already added is an argparse error.
    """


@hookspec(firstresult=True)
def xnlos_check_config(table: dict, path) -> str | None:
    """``xnlos check`` for a config kind that is not a pipeline (a dataset or a training config).

    ``table`` is the parsed TOML of the file at ``path`` (a :class:`pathlib.Path`). Return the
    one-line verdict (``"PATH: valid …"``) when this plugin owns that kind of config, after running
    what its command runs before its first step; raise an :class:`xnlos_core.errors.XnlosError` when
    it is invalid; return None when the config is not yours. The first non-None answer wins.
    """
