"""Which trainer trains a config: the one registered for its ``[model] name``.

Each learned component registers its :class:`Trainer` from its plugin module
(``plugins/detectors/plugin.py``, ``plugins/mirror/residual/plugin.py``) when the plugin is loaded,
as a ``"module:attribute"`` string so that loading a plugin imports no training code. A dict
rather than a pluggy hook: a trainer is not a pipeline component (the registry's kinds are the
six stages), the lookup is one name, and a hook would add a contract to ``xnlos_core`` for a
``plugins``-only concern. A component disabled in the plugin allow-list registers no trainer,
and ``xnlos train`` then names the models it can train.
"""
from __future__ import annotations

import difflib
import importlib
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from xnlos_core.errors import ConfigError


@dataclass(frozen=True)
class Trainer:
    """What ``xnlos train`` and ``xnlos check`` need of a learned component.

    parse(table, source): the validated config (ConfigError naming ``source`` and the key); it has
    ``out``, ``export``, ``seed``, ``model.name``, ``optim`` (:class:`.optim.OptimConfig`) and
    ``digest()``. train(cfg, *, overwrite, progress, source, named_export, base_dir): run it
    (:mod:`.run`), returns the summary; base_dir is the config file's folder, which every relative
    path of the config is taken from. report(summary): the result line ``xnlos train`` prints.
    check(cfg, source, base_dir): further checks of ``xnlos check`` (None: parsing is the check)."""

    parse: Callable[[dict[str, Any], str], Any]
    train: Callable[..., dict[str, Any]]
    report: Callable[[dict[str, Any]], str]
    check: Callable[[Any, str], None] | None = None


_TRAINERS: dict[str, str] = {}  # model name → "module:attribute" of its Trainer
_DEFAULT: list[str] = []  # the model trained when a config names none


def register(names: tuple[str, ...], target: str, *, default: str | None = None) -> None:
    """Register ``target`` ("module:attribute" of a :class:`Trainer`) for the model ``names``;
    ``default``: the model name a config without ``[model] name`` means."""
    for name in names:
        if _TRAINERS.get(name, target) != target:
            raise ConfigError(f"model {name!r}: a trainer is registered twice ({_TRAINERS[name]} and {target})")
        _TRAINERS[name] = target
    if default is not None:
        _DEFAULT[:] = [default]


def trainer_for(table: dict[str, Any], source: str) -> Trainer:
    """The trainer of a training table's ``[model] name``; ConfigError naming ``source`` when none is."""
    from xnlos_core.config import expect_kind
    from xnlos_core.registry import get_manager

    get_manager()  # loads the plugins, whose modules register their trainers
    expect_kind(table, "training", source)
    model = table.get("model")
    name = model.get("name") if isinstance(model, dict) else None
    name = name if name is not None else (_DEFAULT[0] if _DEFAULT else None)
    if not isinstance(name, str) or name not in _TRAINERS:
        close = difflib.get_close_matches(name, list(_TRAINERS), n=1) if isinstance(name, str) else []
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        raise ConfigError(f"{source}: [model] name {name!r}: no trainer for this model{hint}; expected one of "
                          f"{', '.join(sorted(_TRAINERS)) or 'none (no learned component is loaded)'}")
    module, attr = _TRAINERS[name].split(":")
    return getattr(importlib.import_module(module), attr)
