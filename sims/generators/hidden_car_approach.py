"""Hidden car approaching the junction (issue 28): a crossroads whose hidden car drives towards
the ego street at constant velocity, or brakes to a stop, for a sequence of frames.

Speed v₀ is drawn from ``speed`` (default 5–14 m/s, 18–50 km/h urban traffic); with probability
``braking_probability`` the car brakes at a deceleration drawn from ``deceleration`` (default
2–6 m/s², comfortable to firm braking) (``constant_acceleration`` with a < 0, stopping after
v₀²/(2|a|)), else it keeps its speed (plain ``velocity``, constant velocity).
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.motion import ConstantAcceleration
from xnlos_core.scene import ObjectSpec

from . import crossroads
from .common import Generator, Range, Region, uniform
from .sequences import SequenceParams, moving, stays_in_street, towards_junction


class Params(SequenceParams):
    """A car in a cross-street arm approaching the junction (constant velocity or braking)."""

    object_kinds: list[Literal["car"]] = Field(default_factory=lambda: ["car"], min_length=1,
                                               description="object class (car only)")
    speed: Range(0.5, 20.0, "m/s") = Field((5.0, 14.0), description="initial speed v₀ [m/s]")
    braking_probability: float = Field(0.5, ge=0, le=1, description="chance that the car brakes (else constant "
                                                                    "velocity)")
    deceleration: Range(0.5, 10.0, "m/s²") = Field((2.0, 6.0), description="braking deceleration |a| [m/s²]")


def motion(p: Params, o: ObjectSpec, arm: Region, rng: np.random.Generator, walls) -> ObjectSpec:
    """The drawn car turned towards the junction, driving or braking; Reject if it leaves the street."""
    heading = towards_junction(o.heading, arm)
    v0 = uniform(rng, p.speed)
    if rng.random() < p.braking_probability:
        o = moving(o, heading, trajectory=ConstantAcceleration(speed=v0, acceleration=-uniform(rng, p.deceleration)))
    else:
        o = moving(o, heading, velocity=(v0 * math.cos(heading), v0 * math.sin(heading)))
    return stays_in_street(o, walls, p.horizon)


GENERATOR = Generator("hidden_car_approach", Params, "crossroads; a hidden car in a cross-street arm drives towards "
                                                     "the junction at constant speed or braking", crossroads.layout,
                      motion)
