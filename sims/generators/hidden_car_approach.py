"""Hidden car approaching the junction: a crossroads whose hidden car drives towards
the junction for a sequence of frames, straight, braking or turning, seen through the relay wall
for most of them (``visible_share``, :mod:`~sims.generators.sequences`).

The motion is drawn uniformly from ``motions`` once per scene (``per_scene``: re-draws keep it, so
the kinds stay equally frequent although some pass the visibility check less often), then its
values at each draw:

* ``straight``: constant velocity at v₀ from ``speed`` (default 4–10 m/s, 14–36 km/h: a car slowing
  for a junction; faster cars leave the hidden arm before ``visible_share`` of a 6 s sequence);
* ``braking``: ``constant_acceleration`` from v₀ at a < 0, |a| drawn from ``deceleration`` (default
  1.5–4 m/s², gentle to firm braking) and cut to v₀ / ``min_braking_time`` so that the car brakes for
  at least that long (default 3 s) before it stops: it is still braking when a 2 s-ahead prediction
  is made after the track is established;
* ``turning``: ``constant_turn`` at v₀ with yaw rate ω, |ω| from ``yaw_rate`` (default 0.1–0.4 rad/s),
  either sign; its heading is along the lane at t = ``aligned_at`` × horizon (drawn, default 0.3–0.7
  of it, :func:`~sims.generators.sequences.aligned_heading`): the path is an arc across the street
  and back (a lane change, a swerve round a parked car), since a constant turn held for seconds in a
  straight street otherwise drives into a facade (such draws are rejected).
"""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from xnlos_core.motion import ConstantAcceleration, ConstantTurn
from xnlos_core.scene import ObjectSpec

from . import crossroads
from .common import Generator, Range, Region, uniform
from .sequences import SequenceParams, aligned_heading, moving, stays_in_street, towards_junction

Motion = Literal["straight", "braking", "turning"]


class Params(SequenceParams):
    """A car in a cross-street arm approaching the junction (straight, braking or turning)."""

    object_kinds: list[Literal["car"]] = Field(default_factory=lambda: ["car"], min_length=1,
                                               description="object class (car only)")
    speed: Range(0.5, 20.0, "m/s") = Field((4.0, 10.0), description="initial speed v₀ [m/s]")
    motions: list[Motion] = Field(default_factory=lambda: ["straight", "braking", "turning"], min_length=1,
                                  description="motions drawn uniformly: straight (constant velocity), braking "
                                              "(constant deceleration), turning (constant turn rate)")
    deceleration: Range(0.5, 10.0, "m/s²") = Field((1.5, 4.0), description="braking deceleration |a| [m/s²]")
    min_braking_time: float = Field(3.0, ge=0.0, le=20.0, description="|a| is cut to v₀ / this, so the car brakes "
                                                                      "for at least this long before it stops [s]")
    yaw_rate: Range(0.0, 2.0, "rad/s") = Field((0.1, 0.4), description="turn rate |ω| when turning [rad/s] (either "
                                                                       "sign)")
    aligned_at: Range(0.0, 1.0, "horizon") = Field((0.3, 0.7), description="a turning car's heading is along its "
                                                                          "lane at this fraction of the horizon")


def per_scene(p: Params, rng: np.random.Generator) -> dict:
    """The scene's motion kind, drawn uniformly from ``p.motions``."""
    return {"motion": p.motions[int(rng.integers(len(p.motions)))]}


def motion(p: Params, o: ObjectSpec, arm: Region, rng: np.random.Generator, walls, choice: dict) -> ObjectSpec:
    """The drawn car turned towards the junction, driving, braking or turning (``choice["motion"]``);
    Reject if it leaves the street."""
    heading = towards_junction(o.heading, arm)
    kind = choice["motion"]
    v0 = uniform(rng, p.speed)
    if kind == "braking":
        decel = uniform(rng, p.deceleration)
        if p.min_braking_time > 0:
            decel = min(decel, v0 / p.min_braking_time)
        o = moving(o, heading, trajectory=ConstantAcceleration(speed=v0, acceleration=-decel))
    elif kind == "turning":
        omega = uniform(rng, p.yaw_rate) * (1.0 if rng.random() < 0.5 else -1.0)
        start = aligned_heading(heading, omega, uniform(rng, p.aligned_at) * p.horizon)
        o = moving(o, start, trajectory=ConstantTurn(speed=v0, yaw_rate=omega))
    else:
        o = moving(o, heading, velocity=(v0 * math.cos(heading), v0 * math.sin(heading)))
    return stays_in_street(o, walls, p.horizon)


GENERATOR = Generator("hidden_car_approach", Params, "crossroads; a hidden car in a cross-street arm drives towards "
                                                     "the junction straight, braking or turning, mirror-visible over "
                                                     "its horizon", crossroads.layout, motion, per_scene)
