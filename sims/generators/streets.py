"""The radar's street and the two near building blocks that hide a cross street (shared by the
junction families: crossroads, T-junction, curved wall, corner split).

Frame: radar at the origin driving along +x. The ego street's carriageway is ``ego_width`` wide
around y = yc; the building lines (facades) stand ``setback`` beyond each kerb, at y = yR < 0 on
the right and y = yL > 0 on the left. The near blocks end at the cross street's near building
line x = xn = ``corner_distance``; their corners (xn, yR) and (xn, yL) are the occluding corners
that ``hidden_distance`` is measured from (along the cross street, away from the ego street).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import Field

from .common import BaseParams, Range, Region, Surface, block, draw_surface, uniform

BACK = 10.0  # m, facades of the ego street start this far behind the radar


class StreetParams(BaseParams):
    """Geometry of the radar's street and the near corner (families built on a junction)."""

    ego_width: Range(4.0, 40.0, "m") = Field((7.0, 14.0), description="carriageway width of the radar's street [m]")
    setback: Range(0.0, 15.0, "m") = Field((0.5, 4.0), description="building line behind the kerb "
                                                                    "(sidewalk, front yard) [m], per street side")
    corner_distance: Range(1.0, 80.0, "m") = Field((3.0, 15.0), description="distance along x from the radar "
                                                                            "to the occluding corner [m]")
    street_offset: Range(-10.0, 10.0, "m") = Field((-2.0, 2.0), description="y of the ego street's centre line "
                                                                           "[m] (kept ≥ 1 m inside the kerbs)")
    arm_length: float = Field(55.0, ge=10.0, le=300.0, description="length of the cross-street arms beyond the "
                                                                   "ego street's building lines [m]")


@dataclass
class Ego:
    """Drawn ego street: centre yc, building lines yR < 0 < yL, near corner line xn [m]."""

    yc: float
    yr: float
    yl: float
    xn: float

    def drawn(self) -> dict:
        return {"street_centre_y": self.yc, "right_building_line_y": self.yr, "left_building_line_y": self.yl,
                "corner_distance": self.xn}


def draw_ego(p: StreetParams, rng: np.random.Generator) -> Ego:
    """Draw the ego street (width, setbacks, centre offset) and the corner distance."""
    w = uniform(rng, p.ego_width)
    s_r, s_l = uniform(rng, p.setback), uniform(rng, p.setback)
    yc = float(np.clip(uniform(rng, p.street_offset), -(w / 2 - 1.0), w / 2 - 1.0))
    return Ego(yc, yc - w / 2 - s_r, yc + w / 2 + s_l, uniform(rng, p.corner_distance))


def near_blocks(e: Ego, p: StreetParams, rng: np.random.Generator) -> tuple[list, Surface, Surface]:
    """The near-right and near-left blocks (facade along the ego street, facade along the cross
    street) and their drawn surfaces."""
    s_r, s_l = draw_surface(rng, p), draw_surface(rng, p)
    walls = block("near_right", (e.xn, e.yr), (-1, 0), e.xn + BACK, (0, -1), p.arm_length, s_r)
    walls += block("near_left", (e.xn, e.yl), (-1, 0), e.xn + BACK, (0, 1), p.arm_length, s_l)
    return walls, s_r, s_l


def cross_arms(e: Ego, xf: float, p: StreetParams) -> tuple[Region, Region]:
    """Right and left cross-street arms between the near building line xn and the far one xf [m]."""
    width = xf - e.xn
    right = Region("right_arm", (e.xn, e.yr), (0.0, -1.0), (1.0, 0.0), p.arm_length - 3.0, 0.0, width, (e.xn, e.yr))
    left = Region("left_arm", (e.xn, e.yl), (0.0, 1.0), (1.0, 0.0), p.arm_length - 3.0, 0.0, width, (e.xn, e.yl))
    return right, left


def ego_lane(e: Ego, length: float) -> Region:
    """The ego street from behind the radar up to ``length`` [m] ahead, between its building lines."""
    return Region("ego_street", (-BACK + 2.0, e.yr), (1.0, 0.0), (0.0, 1.0), length + BACK - 2.0, 0.0, e.yl - e.yr)


def surface_drawn(s: Surface) -> dict:
    return {"material": s.material, "roughness": s.roughness, "thickness": s.thickness, "height": s.height}
