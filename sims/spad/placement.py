"""Where on the relay wall a confocal SPAD scan patch goes: centred as nearly as possible on the
wall point that faces a hidden target head-on, among the positions the sensor can see.

Why: LCT and f-k reconstruct only laterally inside the scan aperture (the volume has the scan
grid's x, y), so a hidden object far to the side of the patch cannot come back whatever the photon
count. The wall point that sees the target straight ahead along the wall normal is the foot of the
perpendicular from the target onto the wall line, offset o_f = (p − m)·u along the wall (m the
wall's midpoint, u its unit direction start → end, top view). The patch must also be scannable:

* on the wall: |o| ≤ L/2 − w/2 (L the wall's length, w the grid width);
* seen by the sensor: the segments from the sensor (``sensor`` at ``sensor_height``) to the patch's
  two ends and its centre (at ``grid_elevation``) cross no other wall and no box object
  (:func:`sims.spad.occlusion.blocked_by_segments`, the transport's own occlusion test);
* seeing the target: the segment from the patch centre to the target crosses none of them
  (the target's own object, ``exclude``, left out).

:func:`facing_offset` samples the offsets on the wall every ``step`` metres and returns the
feasible one nearest o_f (o_f itself when it is feasible). All lengths in metres, world frame
(x forward, y left, z up; DESIGN.md)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.scene import Scene

from .occlusion import blocked_by_segments
from .scene import SpadParams, relay_wall


@dataclass(frozen=True)
class Placement:
    """offset: the chosen ``grid_offset`` [m] along the wall from its midpoint (None: no position on
    the wall is both seen by the sensor and sees the target); facing: o_f [m], the offset of the
    foot of the perpendicular from the target; interval: (first, last) feasible sampled offset [m]
    or None; clipped: the chosen offset differs from o_f (o_f was not feasible)."""

    offset: float | None
    facing: float
    interval: tuple[float, float] | None
    clipped: bool


def _blockers(scene: Scene, wall, exclude: str | None):
    """Top-view segments a (K, 2), b (K, 2) and heights (K,) of every other wall and box object."""
    a, b, h = [], [], []
    for w in scene.planar_walls():
        if w.start == wall.start and w.end == wall.end:
            continue
        a.append(w.start)
        b.append(w.end)
        h.append(w.height)
    for obj in scene.objects:
        if obj.shape == "point" or obj.name == exclude:
            continue
        fp = obj.footprint(0.0)
        a += list(fp)
        b += list(np.roll(fp, -1, axis=0))
        h += [obj.height] * len(fp)
    return np.asarray(a, float).reshape(-1, 2), np.asarray(b, float).reshape(-1, 2), np.asarray(h, float)


def facing_offset(scene: Scene, params: SpadParams, target, *, exclude: str | None = None,
                  sensor=(0.0, 0.0), step: float = 0.01) -> Placement:
    """The scan patch's ``grid_offset`` for a hidden ``target`` (3,) [m] (module docstring)."""
    p = np.asarray(target, float).reshape(-1)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise InputError(f"facing_offset(target): expected a finite world point (x, y, z) [m], got {target!r}")
    if not step > 0:
        raise InputError(f"facing_offset(step): expected a positive sampling step [m], got {step}")
    wall = relay_wall(scene, params.wall)
    s, e = np.asarray(wall.start, float), np.asarray(wall.end, float)
    length = float(np.linalg.norm(e - s))
    u = (e - s) / length
    mid = (s + e) / 2
    foot = float((p[:2] - mid) @ u)
    half = length / 2 - params.grid_width / 2
    if half < 0:
        return Placement(None, foot, None, True)
    offs = np.arange(-half, half + step / 2, step)
    a, b, h = _blockers(scene, wall, exclude)
    z = params.grid_elevation

    def points(o: np.ndarray) -> np.ndarray:
        xy = mid[None] + o[:, None] * u[None]
        return np.c_[xy, np.full(len(o), z)]

    eye = np.array([*np.asarray(sensor, float), params.sensor_height])
    ok = np.ones(len(offs), bool)
    for shift in (-params.grid_width / 2, 0.0, params.grid_width / 2):
        ok &= ~blocked_by_segments(eye, points(offs + shift), a, b, h)
    ok &= ~blocked_by_segments(p, points(offs), a, b, h)
    if not ok.any():
        return Placement(None, foot, None, True)
    good = offs[ok]
    best = float(good[np.argmin(np.abs(good - foot))])
    if abs(foot) <= half and abs(best - foot) <= step:  # o_f itself is feasible (to the sampling)
        best = foot
    return Placement(best, foot, (float(good[0]), float(good[-1])), best != foot)
