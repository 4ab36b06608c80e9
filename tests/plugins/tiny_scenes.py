"""A test plugin: three tiny corner scene generators (``corner_a``, ``corner_b``, ``corner_c``).

Registered by hand, the way a user's own plugin is: ``xnlos -p tiny_scenes`` on the command line
(tests/plugins on PYTHONPATH; pytest puts it on sys.path through its ``pythonpath`` setting), or
``tiny_registry()`` in-process. Only tests/integration/conftest.py imports this module; tests get it
through fixtures. Dataset workers receive the classes from the parent process (module-level, so
they pickle by reference).
"""
from __future__ import annotations

import functools
import sys
import time
from typing import ClassVar

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core import SceneGenerator, hookimpl
from xnlos_core.scene import Scene

FAMILIES = ("corner_a", "corner_b", "corner_c")


def tiny_scene(family: str, seed: int, rcs: float = 10.0, delay: float = 0.0) -> Scene:
    """A small corner (relay wall, occluder, hidden car) jittered by ``seed``; ``delay`` [s] slows it down."""
    if family not in FAMILIES:
        raise ValueError(f"unknown family {family!r}")
    if delay:
        time.sleep(delay)
    rng = np.random.default_rng(seed)
    dx, dy = rng.uniform(-1.0, 1.0, 2)
    speed = {"corner_a": 0.0, "corner_b": 1.5, "corner_c": -1.0}[family]
    return Scene.model_validate({
        "name": f"{family}-{seed}",
        "walls": [{"name": "relay", "start": [8.0 + dx, 6.0], "end": [18.0 + dx, -4.0]},
                  {"name": "occluder", "start": [3.0, -2.0], "end": [10.0, -2.0]},
                  {"name": "side", "start": [10.0, -2.0], "end": [10.0, -15.0]}],
        "objects": [{"name": "car", "center": [13.0 + dx, -8.0 + dy], "heading": 1.57, "rcs": rcs,
                     "velocity": [0.0, speed]}],
        "meta": {"family": family, "seed": seed, "dx": dx, "dy": dy},
    })


class TinyCorner(SceneGenerator):
    """A tiny corner scene whose hidden car moves at the family's speed."""

    family: ClassVar[str]

    class Params(BaseModel):
        model_config = ConfigDict(extra="forbid")
        rcs: float = Field(10.0, gt=0, description="hidden car's RCS [m²]")
        delay: float = Field(0.0, ge=0, le=10, description="sleep per scene [s] (to slow a run down)")

    def generate(self, seed: int) -> Scene:
        return tiny_scene(self.family, seed, self.params.rcs, self.params.delay)


class CornerA(TinyCorner):
    family = "corner_a"


class CornerB(TinyCorner):
    family = "corner_b"


class CornerC(TinyCorner):
    family = "corner_c"


@hookimpl
def xnlos_register_components(registry):
    for cls in (CornerA, CornerB, CornerC):
        registry.add("scene_generator", cls.family, cls)


@functools.lru_cache(maxsize=1)
def tiny_manager():
    """The installed plugins plus these generators, in a manager of their own (the process-wide
    one stays untouched, so other tests see only the installed plugins)."""
    from xnlos_core.registry import PluginManager

    mgr = PluginManager()
    mgr.register(sys.modules[__name__], name="tiny_scenes", provider="tiny_scenes")
    return mgr


def tiny_registry():
    """The registry of :func:`tiny_manager`."""
    return tiny_manager().registry
