"""Urban crossroads: four building blocks around a junction; the hidden object waits in a cross-street
arm behind the near corner and is seen via the far blocks' facades (optionally chamfered corners)."""
from __future__ import annotations

import numpy as np
from pydantic import Field

from .common import Generator, Layout, Range, block, draw_surface, uniform
from .streets import StreetParams, cross_arms, draw_ego, ego_lane, near_blocks, surface_drawn


class Params(StreetParams):
    """Crossroads: the ego street crosses a street of ``cross_width`` at ``corner_distance``."""

    cross_width: Range(4.0, 40.0, "m") = Field((7.0, 14.0), description="carriageway width of the cross street [m]")
    chamfer: Range(0.0, 20.0, "m") = Field((0.0, 8.0), description="corner cut of the two far blocks, along each "
                                                                  "facade [m] (0: square corner)")


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One crossroads for a hidden object in the right arm (see module doc)."""
    e = draw_ego(p, rng)
    wc, s_near, s_far = uniform(rng, p.cross_width), uniform(rng, p.setback), uniform(rng, p.setback)
    xf = e.xn + s_near + wc + s_far
    walls, s_nr, s_nl = near_blocks(e, p, rng)
    s_fr, s_fl = draw_surface(rng, p), draw_surface(rng, p)
    c_r, c_l = uniform(rng, p.chamfer), uniform(rng, p.chamfer)
    walls += block("far_right", (xf, e.yr), (1, 0), 40.0, (0, -1), p.arm_length, s_fr, chamfer=c_r)
    walls += block("far_left", (xf, e.yl), (1, 0), 40.0, (0, 1), p.arm_length, s_fl, chamfer=c_l)
    right, left = cross_arms(e, xf, p)
    drawn = {**e.drawn(), "cross_width": wc, "far_building_line_x": xf, "chamfer_right": c_r, "chamfer_left": c_l,
             "surfaces": {k: surface_drawn(s) for k, s in
                          (("near_right", s_nr), ("near_left", s_nl), ("far_right", s_fr), ("far_left", s_fl))}}
    return Layout(walls, [right, left], [ego_lane(e, xf + 30.0), right, left], drawn)


GENERATOR = Generator("crossroads", Params, "four blocks around a junction; hidden object in a cross-street arm, "
                                            "relayed by the far facades or their chamfers", layout)
