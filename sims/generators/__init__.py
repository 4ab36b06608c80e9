"""Seeded scene generators for the paper's scene families (Sec. 5.1: urban, parking and residential
scenes; Sec. 5.1.4: curved relay walls and beam splitting at corners).

Every family places at least one object out of the radar's line of sight that one specular bounce
on a relay wall makes visible (a mirrored "mNLOS" echo inside the field of view)::

    from sims.generators import generate_scene
    scene = generate_scene("crossroads", seed=3, hidden_distance=[20, 40], object_kinds=["car"],
                           materials=["metal", "glass"])

Each family is also a registered ``scene_generator`` component (:mod:`sims.generators.components`,
registered by :mod:`sims.plugin`), which is how dataset configs name them.

The same seed and parameters give the same :class:`~xnlos_core.scene.Scene`; its ``meta`` records
the family, the seed, the parameters and every drawn value. By default a hidden object counts only
when its best mirror path reaches the detectability threshold (``min_snr_db``, default
:data:`sims.propagation.DETECTABLE_SNR_DB` = 10.4 dB RA-map SNR) with the default radar (1.6 mW
per transmitter, 64 chirps averaged): concrete and brick facades allow cars 40 m behind the
corner. A weaker ``radar`` (e.g. ``n_chirps = 1``, 18 dB less) needs stronger relays (metal,
glass), closer objects or ``min_snr_db=None`` (geometry only).
"""
from __future__ import annotations

import difflib

import numpy as np
from pydantic import ValidationError

from xnlos_core.errors import InputError
from xnlos_core.scene import Scene

from .common import Generator, generate
from .components import COMPONENTS
from .params import KINDS, BaseParams

# name → Generator of each registered family: the components are the one table of families.
FAMILIES: dict[str, Generator] = {name: component.GENERATOR for name, component in COMPONENTS.items()}

__all__ = ["FAMILIES", "KINDS", "BaseParams", "Generator", "family_params", "generate_scene", "validate_params"]


def _family(family: str) -> Generator:
    if isinstance(family, str) and family in FAMILIES:
        return FAMILIES[family]
    close = difflib.get_close_matches(str(family), list(FAMILIES), n=1)
    hint = f" — did you mean {close[0]!r}?" if close else ""
    raise InputError(f"unknown scene family {family!r}{hint} Families: {', '.join(FAMILIES)}")


def family_params(family: str) -> type[BaseParams]:
    """The pydantic parameter model of ``family`` (fields with defaults, bounds and descriptions)."""
    return _family(family).Params


def _field_help(model: type[BaseParams], key: str) -> str:
    f = model.model_fields.get(key)
    if f is None:
        return ""
    return f" (expected: {f.description}; default {f.get_default(call_default_factory=True)!r})" if f.description \
        else ""


def validate_params(family: str, overrides: dict) -> BaseParams:
    """``family``'s parameters with ``overrides`` applied; InputError naming each bad key."""
    model = family_params(family)
    try:
        return model.model_validate(overrides)
    except ValidationError as err:
        lines = []
        for e in err.errors():
            key = ".".join(str(x) for x in e["loc"]) or "(parameters)"
            top = str(e["loc"][0]) if e["loc"] else ""
            if e["type"] == "extra_forbidden":
                close = difflib.get_close_matches(top, list(model.model_fields), n=1)
                hint = f" — did you mean {close[0]!r}?" if close else ""
                lines.append(f"unknown parameter {key!r}{hint}; allowed: {', '.join(model.model_fields)}")
            else:
                msg = e["msg"].removeprefix("Value error, ")
                lines.append(f"parameter {key!r} = {e.get('input')!r}: {msg}{_field_help(model, top)}")
        raise InputError(f"scene family {family!r}: " + "; ".join(lines)) from None


def generate_scene(family: str, seed: int, **overrides) -> Scene:
    """A random scene of ``family`` drawn from ``numpy.random.default_rng(seed)``.

    family: one of :data:`FAMILIES`; seed: integer ≥ 0; overrides: parameters of the family
    (:func:`family_params`), intervals as ``[low, high]`` or a single number. Returns a Scene named
    ``"{family}-{seed}"`` whose meta holds ``family``, ``seed``, ``attempts``, ``params`` and
    ``drawn``. Raises InputError for an unknown family, a bad parameter (naming the key and what is
    allowed) or when no valid scene is found within ``max_attempts`` draws.
    """
    gen = _family(family)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise InputError(f"scene family {family!r}: seed must be an integer ≥ 0, got {seed!r}")
    return generate(gen, int(seed), validate_params(family, overrides))
