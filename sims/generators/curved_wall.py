"""Curved relay wall: a corner whose facade across the junction is a circular arc (a rounded
building front, convex or concave), cut into planar facets that each act as a mirror."""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from .common import Generator, Layout, Range, Reject, draw_surface, facade, uniform
from .streets import StreetParams, cross_arms, draw_ego, ego_lane, near_blocks, surface_drawn


class Params(StreetParams):
    """A near corner and a curved facade across the junction (chord, tilt, radius, convex/concave)."""

    relay_gap: Range(3.0, 60.0, "m") = Field((8.0, 20.0), description="x distance from the near corner to the "
                                                                     "curved facade's chord centre [m]")
    relay_offset: Range(-20.0, 20.0, "m") = Field((-6.0, 2.0), description="y of the chord centre relative to the "
                                                                           "right building line [m]")
    relay_angle: Range(0.0, 1.3, "rad") = Field((0.3, 1.0), description="chord tilt from the y axis [rad] (0: "
                                                                       "facing the radar, π/4: a chamfer)")
    chord_length: Range(4.0, 80.0, "m") = Field((15.0, 35.0), description="chord of the curved facade [m]")
    radius: Range(3.0, 1000.0, "m") = Field((15.0, 120.0), description="|radius of curvature| [m] (at least half "
                                                                      "the chord)")
    curvature: Literal["convex", "concave", "any"] = Field("any", description="convex bulges towards the radar")


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One rounded-corner junction for a hidden object in the right arm (see module doc)."""
    e = draw_ego(p, rng)
    walls, s_nr, s_nl = near_blocks(e, p, rng)
    s_relay = draw_surface(rng, p)
    gap, off, alpha = uniform(rng, p.relay_gap), uniform(rng, p.relay_offset), uniform(rng, p.relay_angle)
    chord, r = uniform(rng, p.chord_length), uniform(rng, p.radius)
    convex = p.curvature == "convex" or (p.curvature == "any" and bool(rng.integers(2)))
    if r < chord / 2 * 1.001:
        raise Reject("radius below half the chord")
    c = np.array([e.xn + gap, e.yr + off])
    d = np.array([math.sin(alpha), -math.cos(alpha)])  # top → bottom
    top, bottom = c - chord / 2 * d, c + chord / 2 * d
    sag = r - math.sqrt(r * r - chord * chord / 4)
    if min(top[0], bottom[0]) - (sag if convex else 0.0) < e.xn + 3.0:
        raise Reject("curved facade reaches into the near block")
    # start = top: its left is (cos α, sin α), away from the radar, so convex needs radius < 0
    walls.append(facade("relay", top, bottom, s_relay, radius=-r if convex else r, facet_length=p.facet_length))
    s_far = draw_surface(rng, p)
    walls.append(facade("far_right", bottom, (bottom[0], e.yr - p.arm_length), s_far))
    if top[1] > e.yl:
        walls.append(facade("far_left", top, (top[0], e.yl + p.arm_length), s_far))
    right, left = cross_arms(e, max(top[0], bottom[0]) + sag, p)
    drawn = {**e.drawn(), "chord_centre": c.tolist(), "relay_angle": alpha, "chord_length": chord,
             "radius": r, "curvature": "convex" if convex else "concave",
             "surfaces": {k: surface_drawn(s) for k, s in (("near_right", s_nr), ("near_left", s_nl),
                                                           ("relay", s_relay), ("far", s_far))}}
    return Layout(walls, [right, left], [ego_lane(e, e.xn), right], drawn)


GENERATOR = Generator("curved_wall", Params, "a junction whose relay facade is a convex or concave arc (faceted "
                                             "mirrors); hidden object behind the near corner", layout)
