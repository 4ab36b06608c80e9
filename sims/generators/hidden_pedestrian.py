"""Hidden pedestrian: a crossroads whose hidden pedestrian walks at constant velocity
towards the road for a sequence of frames.

Speed is drawn from ``speed`` (default 0.8–1.8 m/s, slow to brisk walking), the heading uniformly
within ``heading_spread`` (default ±1.0 rad) of the direction to the junction along the cross
street (the ego street, where the radar drives); the box is turned to the walking direction.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.scene import ObjectSpec

from . import crossroads
from .common import Generator, Range, Region, uniform
from .sequences import SequenceParams, moving, stays_in_street


class Params(SequenceParams):
    """A pedestrian in a cross-street arm walking towards the road at constant velocity."""

    object_kinds: list[Literal["pedestrian"]] = Field(default_factory=lambda: ["pedestrian"], min_length=1,
                                                      description="object class (pedestrian only)")
    speed: Range(0.1, 4.0, "m/s") = Field((0.8, 1.8), description="walking speed [m/s]")
    heading_spread: float = Field(1.0, ge=0, le=math.pi / 2, description="walking direction within ± this of "
                                                                         "the direction to the junction [rad]")


def motion(p: Params, o: ObjectSpec, arm: Region, rng: np.random.Generator, walls) -> ObjectSpec:
    """The drawn pedestrian walking towards the road; Reject if its path leaves the street."""
    heading = math.atan2(-arm.direction[1], -arm.direction[0]) + float(rng.uniform(-p.heading_spread,
                                                                                     p.heading_spread))
    v = uniform(rng, p.speed)
    o = moving(o, heading, velocity=(v * math.cos(heading), v * math.sin(heading)))
    return stays_in_street(o, walls, p.horizon)


GENERATOR = Generator("hidden_pedestrian", Params, "crossroads; a hidden pedestrian in a cross-street arm walks "
                                                   "towards the road at constant velocity", crossroads.layout, motion)
