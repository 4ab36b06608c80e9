"""Analytic mirror reconstruction (Eq. 7 without the learned residual), with covariance.

For each mNLOS detection o' (the virtual point behind a wall) and its wall (n, b):

    o = R_Π(o') = o' − 2(nᵀo' + b)n,          n = (cos φ, sin φ),
    Σ_o = J_x Σ_o' J_xᵀ + J_w Σ_w J_wᵀ          (first-order propagation),

with J_x = ∂o/∂o' = I − 2nnᵀ and J_w = ∂o/∂(φ, b) (:func:`xnlos_core.geometry.mirror_jacobians`),
Σ_o' the detection's Cartesian covariance (Detections.position_cov) and Σ_w the wall's (φ, b)
covariance. The detection and the wall estimate are taken as independent.

Wall posteriors with samples (e.g. from the ``emcee`` estimator) and curved walls ('arc') go
through :func:`estimators.propagate.propagate`: every posterior sample mirrors o' exactly and the
hidden point's mean and covariance are the sample moments plus the (rotated) detection
covariance. An arc mirrors o' across its tangent at the point q where the ray radar → o' meets
the arc (n_q the arc's normal at q, b_q = −n_qᵀq; the tangent line at the arc's anchor if the ray
misses the circle) — Eq. 7 with the local wall (:mod:`estimators.wall_models`). A 'line' without
samples keeps the first-order formula above.

Wall choice: the wall whose supported segment (WallPosterior.extent, lengthened by
``extent_margin`` at both ends; a wall without extent is an unbounded line) is crossed by the
segment radar → o'; if several are crossed, the first one along the ray (the wall the wave hits).
For an arc the crossing is the ray's hit q on the arc, inside the extent when q's coordinate
along the tangent line lies between the extent ends' (± margin). If none is crossed,
``fallback``: "nearest" takes the wall with o' on its far side (signed distance δ(o') < 0:
nᵀo' + b for a line) that is closest to o', "drop" leaves o' unanchored. Unanchored detections are
recorded in ``last_unanchored_`` (indices into the detections) and logged, never silently lost.
"""
from __future__ import annotations

import logging
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.geometry import mirror_jacobians, mirror_reflect, ray_segment_intersection
from xnlos_core.interfaces import Reconstructor
from xnlos_core.types import MNLOS, Detections, HiddenPoints, WallPosterior

from estimators.propagate import propagate
from estimators.wall_models import ray_hits, signed_distance

log = logging.getLogger(__name__)


class MirrorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    extent_margin: float = Field(2.0, ge=0, le=1e3, description="each wall's extent is lengthened by this "
                                                               "[m] at both ends before the ray test")
    fallback: Literal["nearest", "drop"] = Field(
        "nearest", description="mNLOS point whose ray crosses no wall: 'nearest' wall line it lies behind, "
                               "or 'drop' (counted in last_unanchored_)")


def crossing_parameters(points: np.ndarray, walls: list[WallPosterior], margin: float) -> np.ndarray:
    """(K, J) ray parameter t ∈ (0, 1) where the segment origin → point (points (K, 2)) crosses
    wall j's extended extent (or its line when extent is None); +inf where it does not cross."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = np.full((len(pts), len(walls)), np.inf)
    for j, w in enumerate(walls):
        n, b = w.normal, w.offset
        u = np.array([-n[1], n[0]])
        if w.model == "arc":
            t = ray_hits("arc", w.mean, pts, w.anchor)[0]
            if w.extent is None:
                inside = np.ones(len(pts), dtype=bool)
            else:
                along = (w.extent - w.tangent_point) @ u
                with np.errstate(invalid="ignore"):
                    hit_along = (t[:, None] * pts - w.tangent_point) @ u
                    inside = (hit_along >= along.min() - margin) & (hit_along <= along.max() + margin)
        elif w.extent is None:
            with np.errstate(divide="ignore", invalid="ignore"):
                t = -b / (pts @ n)
            inside = np.ones(len(pts), dtype=bool)
        else:
            along = w.extent @ u
            lo, hi = along.min() - margin, along.max() + margin
            if not hi > lo:
                continue
            t, s = ray_segment_intersection(pts, -b * n + lo * u, -b * n + hi * u)
            with np.errstate(invalid="ignore"):
                inside = (s >= 0) & (s <= 1)
        with np.errstate(invalid="ignore"):
            ok = inside & (t > 0) & (t < 1)
        out[ok, j] = t[ok]
    return out


class MirrorReconstructor(Reconstructor):
    """Eq. 7 mirror of each mNLOS detection across the wall its ray crosses, with propagated covariance."""

    Params = MirrorParams

    def assign_walls(self, points: np.ndarray, walls: list[WallPosterior]) -> np.ndarray:
        """(K,) wall index for each point, −1 where unanchored (see module doc)."""
        t = crossing_parameters(points, walls, self.params.extent_margin)
        choice = np.where(np.isfinite(t).any(axis=1), np.argmin(t, axis=1), -1)
        if self.params.fallback == "nearest":
            d = np.stack([points @ w.normal + w.offset if w.model == "line" else
                          signed_distance(w.model, w.mean, points, w.anchor) for w in walls], axis=1)  # [m]
            far = np.where(d < 0, -d, np.inf)
            nearest = np.where(np.isfinite(far).any(axis=1), np.argmin(far, axis=1), -1)
            choice = np.where(choice >= 0, choice, nearest)
        return choice

    def reconstruct(self, detections: Detections, walls: list[WallPosterior]) -> HiddenPoints:
        """Hidden points for the mNLOS rows of ``detections`` (source_index into ``detections``,
        wall_index into ``walls``), in detection order. Raises InsufficientDataError when there
        are mNLOS detections but no walls; InputError for a wall model other than 'line'/'arc'."""
        if not isinstance(detections, Detections):
            raise InputError(f"MirrorReconstructor.reconstruct: expected Detections, got {type(detections).__name__}")
        walls = list(walls)
        for j, w in enumerate(walls):
            if not isinstance(w, WallPosterior) or w.model not in ("line", "arc"):
                got = w.model if isinstance(w, WallPosterior) else type(w).__name__
                raise InputError(f"MirrorReconstructor: walls[{j}] must be a WallPosterior of model 'line' or "
                                 f"'arc', got {got!r}")
        idx = detections.of_class(MNLOS)
        self.last_unanchored_ = np.empty(0, dtype=np.int64)
        if len(idx) == 0:
            return HiddenPoints.empty()
        if not walls:
            raise InsufficientDataError(
                f"MirrorReconstructor: {len(idx)} mNLOS detection(s) but no relay wall was estimated; "
                "nothing to mirror them across")
        pts = detections.position[idx]
        pcov = detections.position_cov()[idx]
        choice = self.assign_walls(pts, walls)
        self.last_unanchored_ = idx[choice < 0]
        if len(self.last_unanchored_):
            log.info("MirrorReconstructor: %d of %d mNLOS detection(s) cross no wall and were dropped "
                        "(fallback=%r): indices %s", len(self.last_unanchored_), len(idx),
                        self.params.fallback, self.last_unanchored_.tolist())
        keep = choice >= 0
        pts, pcov, choice, src = pts[keep], pcov[keep], choice[keep], idx[keep]
        mean = np.empty_like(pts)
        cov = np.empty((len(pts), 2, 2))
        for j in np.unique(choice):
            m = choice == j
            w = walls[j]
            if w.model != "line" or w.samples is not None:
                mean[m], cov[m] = propagate(pts[m], pcov[m], w)
                continue
            mean[m] = mirror_reflect(pts[m], w.normal, w.offset)
            jx, jw = mirror_jacobians(pts[m], float(w.mean[0]), float(w.mean[1]))
            c = jx @ pcov[m] @ np.swapaxes(jx, -1, -2) + jw @ w.cov @ np.swapaxes(jw, -1, -2)
            cov[m] = 0.5 * (c + np.swapaxes(c, -1, -2))
        return HiddenPoints(mean, cov, src, choice)
