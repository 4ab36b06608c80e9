"""Corner beam splitting: a wedge-shaped building's convex corner faces the radar between two cross-street
arms; the beam footprint straddles the corner edge, so its two facades relay into opposite arms
(mixed returns from both sides; ``n_hidden`` = 2 hides one object in each arm)."""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from .common import Generator, Layout, Range, Reject, draw_surface, facade, uniform
from .streets import StreetParams, cross_arms, draw_ego, ego_lane, near_blocks, surface_drawn


def _rot(v: np.ndarray, a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([c * v[0] - s * v[1], s * v[0] + c * v[1]])


class Params(StreetParams):
    """Near corners on both sides and a wedge building whose apex points at the radar."""

    n_hidden: int = Field(2, ge=1, le=4, description="hidden objects, alternating right and left arm")
    apex_gap: Range(2.0, 60.0, "m") = Field((6.0, 18.0), description="x distance from the near corners to the "
                                                                    "wedge's apex [m]")
    apex_offset: Range(-10.0, 10.0, "m") = Field((-2.0, 2.0), description="y of the apex relative to the ego "
                                                                         "street's centre [m]")
    apex_angle: Range(0.5, 2.8, "rad") = Field((1.2, 2.2), description="interior angle of the wedge at the apex "
                                                                      "[rad] (π/2: a right-angled corner)")
    apex_yaw: Range(-0.5, 0.5, "rad") = Field((-0.15, 0.15), description="turn of the wedge's axis from +x [rad]")


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One split-corner junction (hidden objects alternate right arm, left arm)."""
    e = draw_ego(p, rng)
    walls, s_nr, s_nl = near_blocks(e, p, rng)
    s_wedge = draw_surface(rng, p)
    apex = np.array([e.xn + uniform(rng, p.apex_gap), e.yc + uniform(rng, p.apex_offset)])
    half, yaw = uniform(rng, p.apex_angle) / 2, uniform(rng, p.apex_yaw)
    axis = np.array([math.cos(yaw), math.sin(yaw)])
    ends = []
    for name, turn, y_end in (("wedge_right", -half, e.yr - p.arm_length), ("wedge_left", half, e.yl + p.arm_length)):
        d = _rot(axis, turn)
        if d[0] <= 0.05:
            raise Reject("wedge facade turns back towards the radar")
        length = min(abs((y_end - apex[1]) / d[1]) if abs(d[1]) > 1e-6 else 150.0, 150.0)
        ends.append(apex + length * d)
        walls.append(facade(name, apex, apex + length * d, s_wedge))
    if not (e.yr + 1.0 < apex[1] < e.yl - 1.0):
        raise Reject("apex outside the ego street")
    right, left = cross_arms(e, max(ends[0][0], ends[1][0]), p)
    drawn = {**e.drawn(), "apex": apex.tolist(), "apex_angle": 2 * half, "apex_yaw": yaw,
             "surfaces": {k: surface_drawn(s) for k, s in (("near_right", s_nr), ("near_left", s_nl),
                                                           ("wedge", s_wedge))}}
    return Layout(walls, [right, left], [ego_lane(e, e.xn), right, left], drawn)


GENERATOR = Generator("corner_split", Params, "a wedge building's corner faces the radar; its two facades split "
                                              "the beam into both cross-street arms", layout)
