"""NLOS-CFAR (Scheiner et al. 2020, "Seeing around street corners"): CA-CFAR peaks classified
by a *known* relay wall, the paper's radar-NLOS baseline (Table 2).

A peak at p (its position from range/azimuth) is mNLOS when the straight ray from the radar at
the origin to p crosses a wall segment at least ``wall_margin`` metres before p:

    ∃ wall: ray(t) = t·p crosses the segment at 0 < t < 1 with (1 − t)·|p| > wall_margin,

otherwise LOS. The margin keeps scatterers on the wall itself (range error ± a few cm–dm) LOS.
The walls are looked up only when there is a peak to classify, so a frame without peaks gives
empty Detections even when its wall source is missing.
"""
from __future__ import annotations

import dataclasses
import logging
from typing import Literal

import numpy as np
from pydantic import Field, field_validator, model_validator

from xnlos_core.errors import InputError
from xnlos_core.geometry import ray_segment_intersection
from xnlos_core.interfaces import Detector
from xnlos_core.types import LOS, MNLOS, Detections, Frame

from .cfar import CFARDetector, CFARParams

log = logging.getLogger(__name__)


class NLOSCFARParams(CFARParams):
    """CA-CFAR parameters plus where the known relay walls come from."""

    wall_source: Literal["ground_truth", "config"] = Field(
        "ground_truth", description="'ground_truth': frame.ground_truth.walls (the paper's known-wall "
                                    "baseline); 'config': the segments in `walls`")
    walls: list[tuple[float, float, float, float]] = Field(
        default_factory=list, description="wall segments [[x0, y0, x1, y1], ...] [m] (wall_source='config')")
    wall_margin: float = Field(0.5, ge=0, le=100, description="a peak must lie this far [m] beyond the "
                                                             "wall crossing to count as mNLOS")

    @field_validator("walls")
    @classmethod
    def _finite_segments(cls, v):
        for i, (x0, y0, x1, y1) in enumerate(v):
            if not np.all(np.isfinite([x0, y0, x1, y1])) or (x0, y0) == (x1, y1):
                raise ValueError(f"walls[{i}] = {[x0, y0, x1, y1]}: need finite coordinates and start ≠ end")
        return v

    @model_validator(mode="after")
    def _walls_for_config(self):
        if self.wall_source == "config" and not self.walls:
            raise ValueError("wall_source='config' needs at least one segment in walls = [[x0, y0, x1, y1], ...]")
        return self


def behind_walls(points: np.ndarray, segments: list[tuple[np.ndarray, np.ndarray]], margin: float) -> np.ndarray:
    """(K,) bool: the ray origin→point (points (K, 2) [m]) crosses one of the segments
    [(start (2,), end (2,)), ...] at least ``margin`` [m] before reaching the point."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    dist = np.hypot(pts[:, 0], pts[:, 1])
    out = np.zeros(len(pts), dtype=bool)
    for start, end in segments:
        t, s = ray_segment_intersection(pts, start, end)
        with np.errstate(invalid="ignore"):
            out |= (t > 0) & (t < 1) & (s >= 0) & (s <= 1) & ((1 - t) * dist > margin)
    return out


class NLOSCFARDetector(Detector):
    """CA-CFAR peaks labelled mNLOS when behind a known relay wall, else LOS (Scheiner et al. 2020)."""

    Params = NLOSCFARParams

    def check_radar(self, radar) -> None:
        """The CFAR window must fit the radar's RA map (:func:`.peaks.window_error`)."""
        self.params.check_radar(radar)

    def _walls(self, frame: Frame) -> list[tuple[np.ndarray, np.ndarray]]:
        p = self.params
        if p.wall_source == "config":
            return [(np.array(w[:2], float), np.array(w[2:], float)) for w in p.walls]
        if frame.ground_truth is None:
            raise InputError(
                f"{type(self).__name__}: wall_source='ground_truth' needs frame.ground_truth.walls, but frame "
                f"{frame.index} has no ground truth (measured data); set wall_source='config' with "
                "walls = [[x0, y0, x1, y1], ...]")
        if not frame.ground_truth.walls:
            log.warning("frame %d: ground truth has no walls; every peak is labelled LOS", frame.index)
        return [(w.start, w.end) for w in frame.ground_truth.walls]

    def detect(self, frame: Frame) -> Detections:
        """CFAR detections of ``frame`` with labels LOS / MNLOS (order: descending power)."""
        self.check_frame(frame)
        cfar = CFARDetector(CFARParams(**self.params.model_dump(include=set(CFARParams.model_fields))))
        det = cfar.detect(frame)
        if len(det) == 0:  # nothing to classify: no walls needed (an empty map never errors)
            return det
        walls = self._walls(frame)
        label = np.where(behind_walls(det.position, walls, self.params.wall_margin), MNLOS, LOS).astype(np.int8)
        return dataclasses.replace(det, label=label)  # every other field (radial velocity too) kept
