"""Hidden cyclist (issue 28): a crossroads whose hidden bicycle rides towards the junction on the
kinematic bicycle model (:class:`xnlos_core.motion.Bicycle`) for a sequence of frames.

Speed is drawn from ``speed`` (default 3–7 m/s, 11–25 km/h), the steering angle δ from
``steering`` (default ±0.03 rad: mild, a path curvature tan δ / L ≤ 0.03 m⁻¹ for the
``wheelbase`` L = 1.1 m of a city bicycle), held constant.
"""
from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.motion import Bicycle
from xnlos_core.scene import ObjectSpec

from . import crossroads
from .common import Generator, Range, Region, uniform
from .sequences import SequenceParams, moving, stays_in_street, towards_junction


class Params(SequenceParams):
    """A bicycle in a cross-street arm riding towards the junction with mild steering."""

    object_kinds: list[Literal["bicycle"]] = Field(default_factory=lambda: ["bicycle"], min_length=1,
                                                   description="object class (bicycle only)")
    speed: Range(0.5, 15.0, "m/s") = Field((3.0, 7.0), description="speed v [m/s]")
    steering: Range(-0.3, 0.3, "rad") = Field((-0.03, 0.03), description="steering angle δ [rad], > 0 turns left")
    wheelbase: float = Field(1.1, gt=0.3, le=3.0, description="wheelbase L [m]")


def motion(p: Params, o: ObjectSpec, arm: Region, rng: np.random.Generator, walls) -> ObjectSpec:
    """The drawn bicycle turned towards the junction on a bicycle-model path; Reject if it leaves the street."""
    heading = towards_junction(o.heading, arm)
    ride = Bicycle(wheelbase=p.wheelbase, steering=uniform(rng, p.steering), speed=uniform(rng, p.speed))
    return stays_in_street(moving(o, heading, trajectory=ride), walls, p.horizon)


GENERATOR = Generator("hidden_cyclist", Params, "crossroads; a hidden cyclist in a cross-street arm rides towards "
                                                "the junction (bicycle model, mild steering)", crossroads.layout,
                      motion)
