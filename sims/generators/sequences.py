"""Shared parts of the sequence families (issue 28): a crossroads whose hidden road user moves.

The street layout is :mod:`~sims.generators.crossroads`'s; the draw loop
(:func:`~sims.generators.common.generate`) places the hidden road user as for any family (out of
line of sight, mirror path at t = 0), then the family's ``motion`` turns it towards the junction,
gives it a trajectory (:mod:`xnlos_core.motion`) and rejects the draw unless, at every step of
:data:`STEP` over [0, ``horizon``], its footprint stays clear of every wall footprint and of the
radar: the scene is a valid sequence of frames for ``horizon`` seconds.
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from xnlos_core.motion import Trajectory
from xnlos_core.scene import ObjectSpec

from . import geometry as g
from .common import RADAR_CLEARANCE, Range, Region, Reject
from .crossroads import Params as CrossroadsParams

STEP = 0.1  # s, time step at which a trajectory is checked against the walls (one dataset frame_interval)


class SequenceParams(CrossroadsParams):
    """Crossroads parameters plus the time horizon the hidden road user's path is checked over."""

    horizon: float = Field(3.0, gt=0.0, le=20.0, description="the moving road user stays in the street, clear "
                                                              "of walls and radar, for t in [0, horizon] [s]")
    heading_jitter: float = Field(0.05, ge=0, le=math.pi, description="heading spread about the street [rad] "
                                                                      "(small: a road user follows its lane)")
    n_extra_objects: Range(0, 12, "objects", integer=True) = Field((0, 0), description="further (static) objects, of the family's "
                                                                 "class; their place is not checked against "
                                                                 "the road user's path")


def towards_junction(heading: float, arm: Region) -> float:
    """``heading`` [rad], turned by π if it points away from the junction (along ``arm.direction``).

    The arms run away from the ego street, so approaching means a heading against the arm's
    direction; a box turned by π has the same footprint, so the drawn placement still fits.
    """
    d = arm.direction
    return heading + math.pi if math.cos(heading) * d[0] + math.sin(heading) * d[1] > 0 else heading


def moving(o: ObjectSpec, heading: float, velocity=None, trajectory: Trajectory | None = None) -> ObjectSpec:
    """``o`` at ``heading`` [rad] with a constant ``velocity`` (vx, vy) [m/s] or a ``trajectory``."""
    heading = float((heading + math.pi) % (2 * math.pi) - math.pi)
    fields = {**o.model_dump(exclude={"velocity"}), "heading": heading}
    if trajectory is not None:
        return ObjectSpec(**fields, trajectory=trajectory)
    return ObjectSpec(**fields, velocity=tuple(float(v) for v in velocity))


def times(horizon: float) -> np.ndarray:
    """Check times 0, STEP, …, horizon [s] (T,) (the horizon itself included)."""
    return np.arange(int(math.floor(horizon / STEP + 1e-9)) + 1) * STEP if horizon > 0 else np.zeros(1)


def stays_in_street(o: ObjectSpec, walls, horizon: float) -> ObjectSpec:
    """``o`` if, at every check time over [0, horizon], its footprint keeps out of every wall's
    footprint (half its thickness around the segment) and RADAR_CLEARANCE from the radar; else Reject.
    Steps of STEP (≤ 1.4 m at 14 m/s) are below a car's length, so a box cannot jump a wall between two."""
    starts, ends, half = walls
    for t in times(horizon):
        poly = g.footprint(o, float(t))
        if len(starts) and np.any(g.polygon_segment_distance(poly, starts, ends) < half):
            raise Reject(f"road user's path meets a wall within the horizon (t = {t:.1f} s)")
        if g.polygon_distance(poly, np.zeros((1, 2))) < RADAR_CLEARANCE:
            raise Reject(f"road user's path meets the radar within the horizon (t = {t:.1f} s)")
    return o
