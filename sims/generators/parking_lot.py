"""Parking lot: the radar drives along an aisle past a row of containers (or a wall) on its right; the
hidden object stands in the parking area behind that row and is seen via the lot's boundary
facades (mostly the end facade, tilted by ``relay_angle``). Cars parked in bays on the
left add line-of-sight clutter."""
from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydantic import Field

from .common import BaseParams, Generator, Layout, Range, Reject, Region, block, draw_body, draw_surface, facade, \
    integer, make_object, uniform
from .streets import surface_drawn
from . import geometry as g

CONTAINER_WIDTH = 2.44  # m, ISO shipping container
BAY_WIDTH = 2.6  # m, perpendicular parking bay
BAY_DEPTH = 5.5  # m


class Params(BaseParams):
    """Aisle, occluding row, lot end facade and parked cars."""

    hidden_distance: Range(1.0, 40.0, "m") = Field((2.0, 15.0), description="distance of a hidden object's centre "
                                                                           "behind the occluding row [m]")
    aisle_width: Range(3.0, 15.0, "m") = Field((5.5, 8.0), description="width of the radar's aisle [m]")
    street_offset: Range(-5.0, 5.0, "m") = Field((-1.0, 1.0), description="y of the aisle's centre line [m]")
    occluder: Literal["container", "wall", "any"] = Field("any", description="the occluding row: metal shipping "
                                                                             "containers or a facade-material wall")
    occluder_start: Range(-10.0, 40.0, "m") = Field((-4.0, 4.0), description="x where the occluding row begins [m]")
    occluder_length: Range(3.0, 80.0, "m") = Field((8.0, 20.0), description="length of the occluding row [m]")
    occluder_gap: Range(0.0, 5.0, "m") = Field((0.5, 2.0), description="gap between aisle edge and the row [m]")
    relay_gap: Range(4.0, 80.0, "m") = Field((5.0, 15.0), description="x distance from the row's end to the lot's "
                                                                     "end facade (on the aisle's axis) [m]")
    relay_angle: Range(-0.8, 0.8, "rad") = Field((0.0, 0.6), description="tilt of the end facade [rad]; > 0 "
                                                                        "faces the parking area")
    lot_depth: Range(8.0, 80.0, "m") = Field((30.0, 50.0), description="depth of the parking area behind the "
                                                                      "row, up to the back building [m]")
    n_parked: Range(0, 30, "cars", integer=True) = Field((0, 8), description="cars parked in bays left of the aisle")

    def extra_materials(self) -> list[str]:
        return ["metal"] if self.occluder != "wall" else []


def layout(p: Params, rng: np.random.Generator) -> Layout:
    """One parking lot for a hidden object behind the occluding row on the right (see module doc)."""
    w = uniform(rng, p.aisle_width)
    yc = float(np.clip(uniform(rng, p.street_offset), -(w / 2 - 1.0), w / 2 - 1.0))
    y_edge, y_left = yc - w / 2, yc + w / 2
    kind = p.occluder if p.occluder != "any" else ("container", "wall")[int(rng.integers(2))]
    x0 = uniform(rng, p.occluder_start)
    x1 = x0 + uniform(rng, p.occluder_length)
    y_o = y_edge - uniform(rng, p.occluder_gap)
    xr, tau, depth = x1 + uniform(rng, p.relay_gap), uniform(rng, p.relay_angle), uniform(rng, p.lot_depth)
    s_occ = draw_surface(rng, p, material="metal" if kind == "container" else None)
    if kind == "container":
        s_occ.thickness = None
        walls = block("row", (x0, y_o), (1, 0), x1 - x0, (0, -1), CONTAINER_WIDTH, s_occ)
        walls += block("row_end", (x1, y_o - CONTAINER_WIDTH), (-1, 0), x1 - x0, (0, 1), CONTAINER_WIDTH, s_occ)
        y_back_of_row = y_o - CONTAINER_WIDTH
    else:
        walls = [facade("row", (x0, y_o), (x1, y_o), s_occ)]
        y_back_of_row = y_o - (s_occ.thickness or g.DEFAULT_WALL_THICKNESS) / 2
    y_back = y_back_of_row - depth
    y_top = y_left + BAY_DEPTH + 1.5
    # end facade through (xr, yc) along (−sin τ, cos τ), from the back building to the left boundary
    d = np.array([-math.sin(tau), math.cos(tau)])
    h = np.array([xr, yc])
    bottom, top = h + (y_back - yc) / d[1] * d, h + (y_top - yc) / d[1] * d
    s_end, s_back, s_left = draw_surface(rng, p), draw_surface(rng, p), draw_surface(rng, p)
    walls.append(facade("end", top, bottom, s_end))
    walls.append(facade("back", (-10.0, y_back), bottom, s_back))
    walls.append(facade("left", (-10.0, y_top), top, s_left))
    starts, ends, _ = g.wall_arrays(walls[-3:])
    row_s, row_e, _ = g.wall_arrays(walls[:-3])
    if g.segment_distance(row_s[:, None], row_e[:, None], starts[None], ends[None]).min() < 3.0:
        raise Reject("end facade touches the occluding row")
    # parked cars, nose towards the left boundary, in bays along the left of the aisle
    slots = np.arange(2.0, min(xr, top[0]) - 4.0, BAY_WIDTH)
    n = min(integer(rng, p.n_parked), len(slots))
    fixed = []
    for k, x in enumerate(np.sort(rng.choice(slots, size=n, replace=False)) if n else []):
        b = draw_body(rng, p, kind="car", moving=False)
        flip = math.pi * int(rng.integers(2))
        fixed.append(make_object(f"parked{k}_car", b, (x + BAY_WIDTH / 2, y_left + 0.3 + b.length / 2),
                                 math.pi / 2 + flip))
    arm = Region("parking_area", (x0, y_back_of_row), (0.0, -1.0), (1.0, 0.0), depth - 2.0, 0.0, xr - x0 + 50.0,
                 (x1, y_back_of_row))
    aisle = Region("aisle", (-8.0, y_edge), (1.0, 0.0), (0.0, 1.0), max(min(xr, top[0]) + 3.0, 1.0), 0.0, w)
    drawn = {"aisle_centre_y": yc, "aisle_width": w, "occluder": kind, "occluder_x": [x0, x1], "occluder_y": y_o,
             "relay_x": xr, "relay_angle": tau, "lot_depth": depth, "n_parked": n,
             "surfaces": {k: surface_drawn(s) for k, s in (("row", s_occ), ("end", s_end), ("back", s_back),
                                                           ("left", s_left))}}
    return Layout(walls, [arm], [aisle, arm], drawn, fixed)


GENERATOR = Generator("parking_lot", Params, "an aisle past a container row or wall; hidden object in the parking "
                                             "area behind it, relayed by the lot's boundary facades", layout)
