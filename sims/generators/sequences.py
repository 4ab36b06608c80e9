"""Shared parts of the sequence families: a crossroads whose hidden road user moves.

The street layout is :mod:`~sims.generators.crossroads`'s; the draw loop
(:func:`~sims.generators.common.generate`) places the hidden road user as for any family (out of
line of sight, mirror path at t = 0), then the family's ``motion`` turns it towards the junction,
gives it a trajectory (:mod:`xnlos_core.motion`) and rejects the draw unless, at every step of
:data:`STEP` over [0, ``horizon``], its footprint stays clear of every wall footprint and of the
radar: the scene is a valid sequence of frames for ``horizon`` seconds. The loop then keeps the
draw only if the road user is out of line of sight at ≥ ``hidden_share`` of those steps and has a
mirror path that the ``radar`` sees (field of view, range, SNR ≥ ``min_snr_db``) at ≥
``visible_share`` of them, so a sequence shows it through the relay wall for most of its frames,
not only at t = 0.

``hidden_share`` (default 0: out of line of sight at t = 0 only) is there for scenes that must stay
NLOS, but few crossroads draws pass it: the corner's shadow edge runs diagonally across the arm, so a
road user approaching the junction shows a corner of its box to the radar within about a second
unless it starts ≥ 20 m back and slowly, and there its mirror path is mostly below ``min_snr_db`` on a
light radar (≈ 1 in 10²–10³ straight-car draws passed with ``hidden_share`` = 0.5 on the radar of
``configs/datasets/sequences.toml``; turning cars almost never).

The radar of that check is ``radar`` (RadarConfig fields; {}: the default radar), not the
dataset's: a dataset on another radar repeats its fields in ``[generator_params.radar]``
(``configs/datasets/sequences.toml`` does).
"""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from xnlos_core.motion import Trajectory
from xnlos_core.scene import ObjectSpec

from . import geometry as g
from .common import RADAR_CLEARANCE, STEP, Range, Region, Reject, times
from .crossroads import Params as CrossroadsParams

__all__ = ["STEP", "SequenceParams", "aligned_heading", "moving", "stays_in_street", "times", "towards_junction"]


class SequenceParams(CrossroadsParams):
    """Crossroads parameters plus the time horizon the hidden road user's path is checked over."""

    horizon: float = Field(3.0, gt=0.0, le=20.0, description="the moving road user stays in the street, clear "
                                                              "of walls and radar, for t in [0, horizon] [s]")
    visible_share: float = Field(0.8, ge=0.0, le=1.0, description="the road user's mirror path must count "
                                 "(field of view, range, SNR ≥ min_snr_db with `radar`) at ≥ this share of the "
                                 "times 0, 0.1, …, horizon [s] (0: only at t = 0)")
    hidden_share: float = Field(0.0, ge=0.0, le=1.0, description="the road user must be out of line of sight "
                                "(no scatterer seen directly) at ≥ this share of the times 0, 0.1, …, horizon [s] "
                                "(0: only at t = 0; see the module doc for why it is not on by default)")
    heading_jitter: float = Field(0.05, ge=0, le=math.pi, description="heading spread about the street [rad] "
                                                                      "(small: a road user follows its lane)")
    n_extra_objects: Range(0, 12, "objects", integer=True) = Field((0, 0), description="further (static) objects, of the family's "
                                                                 "class; their place is not checked against "
                                                                 "the road user's path")
    max_attempts: int = Field(2000, ge=1, le=10000, description="re-draws before giving up (the visibility "
                                                                "check over the horizon rejects many)")


def towards_junction(heading: float, arm: Region) -> float:
    """``heading`` [rad], turned by π if it points away from the junction (along ``arm.direction``).

    The arms run away from the ego street, so approaching means a heading against the arm's
    direction; a box turned by π has the same footprint, so the drawn placement still fits.
    """
    d = arm.direction
    return heading + math.pi if math.cos(heading) * d[0] + math.sin(heading) * d[1] > 0 else heading


def aligned_heading(heading: float, yaw_rate: float, t_aligned: float) -> float:
    """Start heading θ₀ [rad] of a road user turning at ``yaw_rate`` ω [rad/s] whose heading is
    ``heading`` (along its lane) at ``t_aligned`` [s]: θ₀ = heading − ω·t_aligned. Its path is then
    an arc that crosses the lane's direction at t_aligned, bending back towards the lane instead of
    leaving it (a lane change or swerve; t_aligned = 0: a turn out of the lane from t = 0)."""
    return heading - yaw_rate * t_aligned


def moving(o: ObjectSpec, heading: float, velocity=None, trajectory: Trajectory | None = None) -> ObjectSpec:
    """``o`` at ``heading`` [rad] with a constant ``velocity`` (vx, vy) [m/s] or a ``trajectory``."""
    heading = float((heading + math.pi) % (2 * math.pi) - math.pi)
    fields = {**o.model_dump(exclude={"velocity"}), "heading": heading}
    if trajectory is not None:
        return ObjectSpec(**fields, trajectory=trajectory)
    return ObjectSpec(**fields, velocity=tuple(float(v) for v in velocity))


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
