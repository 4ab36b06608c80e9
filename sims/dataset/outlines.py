"""Hidden objects' bird's-eye outlines per map, read back from the scenes a shard stores.

Every shard keeps the full Scene of each of its scenes (``scenes_json``, :mod:`sims.dataset.shard`),
so the true outline of each object at a map's time is recomputed when reading
(``ObjectSpec.footprint(t)``); nothing is added to the shards, which keep their bytes. The reader puts
it into ``frame.meta["object_outlines"]`` (JSON-ready: object name → list of [x, y] [m]), which
``xnlos eval``'s figures draw (:func:`xnlos_core.app.plot.figures.split_outlines`).
"""
from __future__ import annotations

import json

import numpy as np

from xnlos_core.scene import ObjectSpec


def scene_objects(z: dict[str, np.ndarray]) -> dict[int, list[ObjectSpec]]:
    """scene_index → that scene's objects, from shard arrays ``z``; {} for a shard without
    ``scenes_json`` (or whose stored objects this version cannot read: the maps then carry no outlines)."""
    if "scenes_json" not in z:
        return {}
    try:
        docs = json.loads(str(z["scenes_json"]))
        return {int(d["scene_index"]): [ObjectSpec.model_validate(o) for o in d["scene"].get("objects", [])]
                for d in docs}
    except (ValueError, KeyError, TypeError):  # pydantic's ValidationError is a ValueError
        return {}


def outline_meta(objects: list[ObjectSpec], t: float) -> dict[str, list[list[float]]]:
    """Object name → bird's-eye outline at time ``t`` [s] as a list of [x, y] [m] (a box's 4 corners,
    or a point object's centre)."""
    return {o.name: np.asarray(o.footprint(t), float).tolist() for o in objects}
