"""T-junction: the ego street ends at a facade across the cross street (tilted by ``head_angle``);
the hidden object waits in a cross-street arm behind the near corner and is seen via that facade."""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from .common import Generator, Layout, Range, draw_surface, facade, uniform
from .streets import StreetParams, cross_arms, draw_ego, ego_lane, near_blocks, surface_drawn


class Params(StreetParams):
    """T-junction: the cross street of ``cross_width`` closes the ego street at ``corner_distance``."""

    cross_width: Range(4.0, 40.0, "m") = Field((7.0, 16.0), description="carriageway width of the cross street [m]")
    head_angle: Range(-0.8, 0.8, "rad") = Field((-0.1, 0.4), description="tilt of the facade across the T from "
                                                                          "perpendicular [rad]; > 0 turns it to "
                                                                          "face the right arm")


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One T-junction for a hidden object in the right arm (see module doc)."""
    e = draw_ego(p, rng)
    wc, s_near, s_far = uniform(rng, p.cross_width), uniform(rng, p.setback), uniform(rng, p.setback)
    xf = e.xn + s_near + wc + s_far
    tau = uniform(rng, p.head_angle)
    walls, s_nr, s_nl = near_blocks(e, p, rng)
    s_head = draw_surface(rng, p)
    # head facade through (xf, yc) along (−sin τ, cos τ), kept ≥ 3 m from the near building line
    h = np.array([xf, e.yc])
    d = np.array([-math.sin(tau), math.cos(tau)])
    room = (xf - e.xn - 3.0) / abs(d[0]) if abs(d[0]) > 1e-9 else math.inf
    t_lo = min((e.yc - e.yr + p.arm_length) / d[1], room if d[0] > 0 else math.inf)
    t_hi = min((e.yl - e.yc + p.arm_length) / d[1], room if d[0] < 0 else math.inf)
    walls.append(facade("head", h - t_lo * d, h + t_hi * d, s_head))
    right, left = cross_arms(e, xf + p.arm_length * abs(math.tan(tau)), p)
    drawn = {**e.drawn(), "cross_width": wc, "head_x": xf, "head_angle": tau,
             "surfaces": {k: surface_drawn(s) for k, s in (("near_right", s_nr), ("near_left", s_nl),
                                                           ("head", s_head))}}
    return Layout(walls, [right, left], [ego_lane(e, e.xn + s_near + wc / 2), right, left], drawn)


GENERATOR = Generator("t_junction", Params, "the ego street ends at a facade across a cross street; hidden object "
                                            "in an arm behind the near corner", layout)
