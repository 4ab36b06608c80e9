"""``oracle`` detector: a simulated frame's own ground truth as detections, with seeded noise.

For analysis only: it reads ``frame.ground_truth`` (what a simulator knows; a real radar frame has
none), so the stages after detection — wall estimation, mirroring, tracking — can be scored apart
from the detector's misses and false alarms (an upper bound on what a perfect detector gives them).

Per frame: every LOS point (label LOS) and every virtual mNLOS point o' (label MNLOS) of the ground
truth becomes one detection at (r, θ) + (ε_r, ε_θ), ε_r ~ N(0, ``range_sigma``²) [m],
ε_θ ~ N(0, ``azimuth_sigma``²) [rad], with range_std / azimuth_std set to those σ; points outside the RA
map's range and azimuth axes are not detected, and a frame without ground truth gives no detections. When the ground
truth carries velocities (a moving scene), each mNLOS detection's radial velocity is that of its
virtual point along the virtual line of sight, r̂'ᵀ v' + ε_v (ε_v ~ N(0, ``velocity_sigma``²)), and an
LOS detection's is its point's range rate (``GroundTruth.los_radial_velocity``: 0 on a wall, r̂ᵀv on a road
user in line of sight; 0 where the truth does not record it) + ε_v. Draws come from
``numpy.random.default_rng([seed, frame.index])``: the same frame gives the same detections in any
order or process.
"""
from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError
from xnlos_core.interfaces import Detector
from xnlos_core.types import LOS, MNLOS, Detections, Frame


class OracleParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    range_sigma: float = Field(0.1, ge=0, le=100, description="standard deviation [m] of the range noise")
    azimuth_sigma: float = Field(0.01, ge=0, le=1, description="standard deviation [rad] of the azimuth noise")
    velocity_sigma: float = Field(0.1, ge=0, le=100, description="standard deviation [m/s] of the radial-velocity "
                                                                 "noise (moving scenes)")
    seed: int = Field(0, ge=0, description="seed of the noise draws (with the frame index)")


class OracleDetector(Detector):
    """The frame's ground-truth LOS and mNLOS points plus seeded noise (analysis of later stages)."""

    Params = OracleParams

    def detect(self, frame: Frame) -> Detections:
        """Detections from ``frame.ground_truth`` (module doc): the points inside the RA map's range and
        azimuth axes, noisy values clipped to them. A frame without ground truth gives no detections."""
        if not isinstance(frame, Frame):
            raise InputError(f"oracle.detect: expected a Frame, got {type(frame).__name__}")
        gt = frame.ground_truth
        if gt is None:
            return Detections(np.empty(0), np.empty(0), np.empty(0, np.int8), np.empty(0))
        p = self.params
        ra = frame.ra_map
        rng = np.random.default_rng([p.seed, max(int(frame.index), 0)])
        pts = np.vstack([gt.los_points, gt.mnlos_points])
        n_los = len(gt.los_points)
        label = np.r_[np.full(n_los, LOS), np.full(len(pts) - n_los, MNLOS)].astype(np.int8)
        r = np.hypot(pts[:, 0], pts[:, 1])
        theta = np.arctan2(pts[:, 1], pts[:, 0])
        v_true = None
        if gt.mnlos_velocity is not None:
            los_dir = pts[n_los:] / np.maximum(r[n_los:, None], 1e-12)
            v_los = np.zeros(n_los) if gt.los_radial_velocity is None else gt.los_radial_velocity
            v_true = np.r_[v_los, np.sum(los_dir * gt.mnlos_velocity, axis=1)]
        (r0, r1), (a0, a1) = (ra.range_axis[[0, -1]], ra.azimuth_axis[[0, -1]])
        seen = (r >= r0) & (r <= r1) & (theta >= a0) & (theta <= a1)
        k = int(seen.sum())
        noise = rng.standard_normal((3, k))
        r_meas = np.clip(r[seen] + p.range_sigma * noise[0], r0, r1)
        th_meas = np.clip(theta[seen] + p.azimuth_sigma * noise[1], a0, a1)
        velocity = var = None
        if v_true is not None:
            velocity = v_true[seen] + p.velocity_sigma * noise[2]
            var = np.full(k, p.velocity_sigma ** 2)
        return Detections(r_meas, th_meas, label[seen], np.ones(k), range_std=np.full(k, p.range_sigma),
                          azimuth_std=np.full(k, p.azimuth_sigma), velocity=velocity, velocity_var=var)
