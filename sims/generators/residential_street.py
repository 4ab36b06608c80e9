"""Residential street: detached houses with front yards on both sides; the hidden object stands in a
driveway between two houses on the right, or (``side_street_probability``) in a side street lined
with garden walls, and is seen via a neighbouring house's side wall or the facades across."""
from __future__ import annotations

import math

import numpy as np
from pydantic import Field

from .common import BaseParams, Generator, Layout, Range, Region, Reject, Surface, draw_surface, facade, uniform
from .streets import surface_drawn

X_FROM, X_TO = -10.0, 60.0  # m, extent of the street that is built up


class Params(BaseParams):
    """Street, front yards, house sizes and gaps, optional side street."""

    materials: list[str] = Field(default_factory=lambda: ["brick", "concrete", "wood"], min_length=1,
                                 description="house materials (sims.materials names), one drawn per house")
    hidden_distance: Range(1.0, 40.0, "m") = Field((2.0, 12.0), description="distance of a hidden object's centre "
                                                                           "behind the house fronts [m]")
    building_height: Range(2.0, 200.0, "m") = Field((5.0, 9.0), description="house height [m]")
    street_width: Range(3.0, 20.0, "m") = Field((5.5, 9.0), description="carriageway width [m]")
    street_offset: Range(-5.0, 5.0, "m") = Field((-1.0, 1.5), description="y of the street's centre line [m]")
    front_setback: Range(0.0, 20.0, "m") = Field((3.0, 8.0), description="front yard depth, per side [m]")
    house_width: Range(3.0, 40.0, "m") = Field((8.0, 14.0), description="house frontage [m]")
    house_depth: Range(3.0, 40.0, "m") = Field((8.0, 12.0), description="house depth [m]")
    house_gap: Range(1.0, 30.0, "m") = Field((3.0, 8.0), description="driveway between neighbouring houses [m]")
    side_street_probability: float = Field(0.5, ge=0, le=1, description="chance of a side street on the hidden side")
    side_street_width: Range(3.0, 20.0, "m") = Field((5.0, 9.0), description="side street between its walls [m]")
    side_street_angle: Range(-0.8, 0.8, "rad") = Field((-0.2, 0.6), description="side street's turn from "
                                                                               "perpendicular [rad]; > 0 leads "
                                                                               "away from the radar")


def _houses(prefix: str, y_front: float, side: float, p: Params, rng, skip: tuple[float, float] | None):
    """Houses along one street side (side −1 right, +1 left): walls, gaps (x0, x1) and surfaces."""
    walls, gaps, surfaces = [], [], {}
    x = X_FROM + uniform(rng, p.house_gap)
    k = 0
    while x < X_TO:
        width, depth = uniform(rng, p.house_width), uniform(rng, p.house_depth)
        if skip is not None and x < skip[1] and x + width > skip[0]:
            x = skip[1] + 1.0
            continue
        s: Surface = draw_surface(rng, p)
        yb = y_front + side * depth
        name = f"{prefix}{k}"
        walls += [facade(f"{name}.front", (x, y_front), (x + width, y_front), s),
                  facade(f"{name}.near_side", (x, y_front), (x, yb), s),
                  facade(f"{name}.far_side", (x + width, y_front), (x + width, yb), s)]
        surfaces[name] = surface_drawn(s)
        gap = uniform(rng, p.house_gap)
        gaps.append((x + width, x + width + gap, depth))
        x += width + gap
        k += 1
    return walls, gaps, surfaces


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One residential street for a hidden object on the right (see module doc)."""
    w = uniform(rng, p.street_width)
    yc = float(np.clip(uniform(rng, p.street_offset), -(w / 2 - 1.0), w / 2 - 1.0))
    y_r, y_l = yc - w / 2 - uniform(rng, p.front_setback), yc + w / 2 + uniform(rng, p.front_setback)
    side_street = bool(rng.random() < p.side_street_probability)
    skip, phi = None, 0.0
    if side_street:
        x_s, phi = uniform(rng, (6.0, 35.0)), uniform(rng, p.side_street_angle)
        skip = (x_s, x_s + uniform(rng, p.side_street_width) / math.cos(phi))
    walls, gaps, surf = _houses("right", y_r, -1.0, p, rng, skip)
    w_l, _, surf_l = _houses("left", y_l, 1.0, p, rng, None)
    walls += w_l
    arm_len = 50.0
    if side_street:
        s = draw_surface(rng, p)
        d = np.array([math.sin(phi), -math.cos(phi)])
        walls += [facade("side_street.near_wall", (skip[0], y_r), np.array([skip[0], y_r]) + arm_len * d, s),
                  facade("side_street.far_wall", (skip[1], y_r), np.array([skip[1], y_r]) + arm_len * d, s)]
        arm = Region("side_street", (skip[0], y_r), tuple(d), (math.cos(phi), math.sin(phi)), arm_len - 3.0, 0.0,
                     (skip[1] - skip[0]) * math.cos(phi), (skip[0], y_r))
        surf["side_street"] = surface_drawn(s)
    else:
        usable = [gp for gp in gaps if 5.0 <= gp[0] <= 45.0]
        if not usable:
            raise Reject("no driveway ahead")
        x0, x1, depth = usable[int(rng.integers(len(usable)))]
        arm = Region("driveway", (x0, y_r), (0.0, -1.0), (1.0, 0.0), depth + 2.0, 0.0, x1 - x0, (x0, y_r))
    street = Region("street", (X_FROM + 2.0, y_r), (1.0, 0.0), (0.0, 1.0), X_TO - X_FROM - 4.0, 0.0, y_l - y_r)
    drawn = {"street_centre_y": yc, "street_width": w, "right_front_y": y_r, "left_front_y": y_l,
             "side_street_x": list(skip) if skip else None, "side_street_angle": phi if skip else None,
             "hidden_region": arm.name,
             "surfaces": {**surf, **surf_l}}
    return Layout(walls, [arm], [street, arm], drawn)


GENERATOR = Generator("residential_street", Params, "detached houses with front yards; hidden object in a driveway "
                                                    "or a side street behind the house fronts", layout)
