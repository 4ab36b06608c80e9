"""Hidden cyclist: a crossroads whose hidden bicycle rides towards the junction on the
kinematic bicycle model (:class:`xnlos_core.motion.Bicycle`) for a sequence of frames, seen through
the relay wall for most of them (``visible_share``, :mod:`~sims.generators.sequences`).

Speed v is drawn from ``speed`` (default 3–6 m/s, 11–22 km/h); the motion uniformly from ``motions``, once per scene (as the car's, :mod:`.hidden_car_approach`):
``straight`` (steering δ = 0) or ``turning`` with yaw rate ω = v tan δ / L, |ω| drawn from ``yaw_rate``
(default 0.1–0.4 rad/s, either sign), i.e. the constant steering δ = atan(ωL/v) for the ``wheelbase``
L = 1.1 m of a city bicycle. A turning cyclist's heading is along its lane at t = ``aligned_at`` ×
horizon (default 0.3–0.7 of it), so its arc crosses the street and bends back (weaving round an
obstacle, a lane change) rather than riding into a facade.
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.motion import Bicycle
from xnlos_core.scene import ObjectSpec

from . import crossroads
from .common import Generator, Range, Region, uniform
from .sequences import SequenceParams, aligned_heading, moving, stays_in_street, towards_junction


class Params(SequenceParams):
    """A bicycle in a cross-street arm riding towards the junction, straight or turning."""

    object_kinds: list[Literal["bicycle"]] = Field(default_factory=lambda: ["bicycle"], min_length=1,
                                                   description="object class (bicycle only)")
    speed: Range(0.5, 15.0, "m/s") = Field((3.0, 6.0), description="speed v [m/s]")
    motions: list[Literal["straight", "turning"]] = Field(default_factory=lambda: ["straight", "turning"],
                                                          min_length=1, description="motions drawn uniformly: "
                                                          "straight (δ = 0) or turning (constant steering)")
    yaw_rate: Range(0.0, 1.0, "rad/s") = Field((0.1, 0.4), description="turn rate |ω| = v tan|δ| / L when turning "
                                                                       "[rad/s] (either sign)")
    wheelbase: float = Field(1.1, gt=0.3, le=3.0, description="wheelbase L [m]")
    aligned_at: Range(0.0, 1.0, "horizon") = Field((0.3, 0.7), description="a turning cyclist's heading is along "
                                                                          "its lane at this fraction of the horizon")


def per_scene(p: Params, rng: np.random.Generator) -> dict:
    """The scene's motion kind, drawn uniformly from ``p.motions``."""
    return {"motion": p.motions[int(rng.integers(len(p.motions)))]}


def motion(p: Params, o: ObjectSpec, arm: Region, rng: np.random.Generator, walls, choice: dict) -> ObjectSpec:
    """The drawn bicycle turned towards the junction on a bicycle-model path, straight or turning
    (``choice["motion"]``); Reject if it leaves the street."""
    heading = towards_junction(o.heading, arm)
    v = uniform(rng, p.speed)
    steering = 0.0
    if choice["motion"] == "turning":
        omega = uniform(rng, p.yaw_rate) * (1.0 if rng.random() < 0.5 else -1.0)
        steering = math.atan(omega * p.wheelbase / v)
        heading = aligned_heading(heading, omega, uniform(rng, p.aligned_at) * p.horizon)
    ride = Bicycle(wheelbase=p.wheelbase, steering=steering, speed=v)
    return stays_in_street(moving(o, heading, trajectory=ride), walls, p.horizon)


GENERATOR = Generator("hidden_cyclist", Params, "crossroads; a hidden cyclist in a cross-street arm rides towards "
                                                "the junction (bicycle model, straight or turning), mirror-visible "
                                                "over its horizon", crossroads.layout, motion, per_scene)
