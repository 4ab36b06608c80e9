"""Analytic mirror reconstruction (Eq. 7 without the learned residual), with covariance.

For each mNLOS detection o' (the virtual point behind a wall) and its wall (n, b):

    o = R_Π(o') = o' − 2(nᵀo' + b)n,          n = (cos φ, sin φ),
    Σ_o = J_x Σ_o' J_xᵀ + J_w Σ_w J_wᵀ          (first-order propagation),

with J_x = ∂o/∂o' = I − 2nnᵀ and J_w = ∂o/∂(φ, b) (:func:`xnlos_core.geometry.mirror_jacobians`),
Σ_o' the detection's Cartesian covariance (Detections.position_cov) and Σ_w the wall's (φ, b)
covariance. The detection and the wall estimate are taken as independent.

Wall posteriors with samples (e.g. from the ``emcee`` estimator) and curved walls ('arc') go
through :func:`xnlos_core.wall_propagation.propagate`: every posterior sample mirrors o' exactly and the
hidden point's mean and covariance are the sample moments plus the (rotated) detection
covariance. An arc mirrors o' across its tangent at the point q where the ray radar → o' meets
the arc (n_q the arc's normal at q, b_q = −n_qᵀq; the tangent line at the arc's anchor if the ray
misses the circle) — Eq. 7 with the local wall (:mod:`xnlos_core.wall`). A 'line' without
samples keeps the first-order formula above.

Wall choice (:mod:`plugins.mirror.association`, shared with ``residual_mirror``): the wall whose
supported segment (WallPosterior.extent, lengthened by ``extent_margin`` at both ends; a wall
without extent is an unbounded line) is crossed by the segment radar → o'; if several are crossed, the first one along the ray (the wall the wave hits),
where a crossing inside a wall's observed extent beats one only within another wall's margin.
For an arc the crossing is the ray's hit q on the arc, inside the extent when q's coordinate
along the tangent line lies between the extent ends' (± margin). If none is crossed,
``fallback``: "nearest" takes the wall with o' on its far side (signed distance δ(o') < 0:
nᵀo' + b for a line) that is closest to o', "drop" leaves o' unanchored. Unanchored detections are
recorded in ``last_unanchored_`` (indices into the detections) and logged, never silently lost.

Visibility gate (``gate``, default on): a hidden point the relay wall cannot show (outside the wedge
its observed segment subtends, behind the wall, or behind the radar; :mod:`plugins.mirror.visibility`)
is a ghost, not a hidden point: it is left out and its detection listed in ``HiddenPoints.gated``
(the frame's ``n_gated``).

Mirror Doppler: when the detections carry a radial velocity (``Detections.velocity``), each hidden
point also gets the observed component of its velocity along the mirrored line of sight, with
covariance from the velocity variance, the detection's position and the wall
(:func:`plugins.mirror.mirror_doppler.unmirror_radial_velocity`); otherwise velocity stays None.
"""
from __future__ import annotations

import logging
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InputError, InsufficientDataError
from xnlos_core.geometry import mirror_jacobians, mirror_reflect
from xnlos_core.interfaces import Reconstructor
from plugins.mirror.mirror_doppler import observed_direction, unmirror_radial_velocity
from xnlos_core.types import MNLOS, Detections, HiddenPoints, WallPosterior
from xnlos_core.wall_propagation import propagate

from .association import anchor_points, crossing_parameters  # noqa: F401  (re-exported)
from .visibility import VISIBLE, describe_gated, visibility

log = logging.getLogger(__name__)


class MirrorParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    extent_margin: float = Field(2.0, ge=0, le=1e3, description="each wall's extent is lengthened by this "
                                                               "[m] at both ends before the ray test")
    fallback: Literal["nearest", "drop"] = Field(
        "nearest", description="mNLOS point whose ray crosses no wall: 'nearest' wall line it lies behind, "
                               "or 'drop' (counted in last_unanchored_)")
    gate: bool = Field(True, description="refuse hidden points the relay wall cannot show (outside its visibility "
                                         "wedge, behind it, behind the radar: plugins.mirror.visibility), counted "
                                         "as the frame's n_gated; false: report every mirror image")
    behind_radar: bool = Field(False, description="with gate: accept hidden points behind the radar (x < 0), "
                                                  "which only a wall facing the radar across its boresight shows")
    wedge_margin: float | None = Field(0.0, ge=0, le=1e3, description="with gate: how far [m] beyond each wall's "
                                       "observed extent its bounce point may lie (None: extent_margin). 0: the "
                                       "part the LOS detections showed; past it, most mirror images were ghosts "
                                       "(benchmarks/doppler_detector.md)")
    wall_echo: float = Field(1.0, ge=0, le=100, description="with gate and Doppler: an mNLOS detection within this "
                             "[m] of an estimated wall and at rest is that wall's own echo, not a hidden road user")
    static_speed: float = Field(0.3, ge=0, le=100, description="with gate and Doppler: radial speed [m/s] below which "
                                "(or within 3 σ of 0) a detection is at rest")
    one_relay: bool = Field(True, description="with gate: refuse a hidden point whose ray crosses two seen walls "
                            "(within wedge_margin): which relayed it is ambiguous (plugins.mirror.visibility, rule 5)")


class MirrorReconstructor(Reconstructor):
    """Eq. 7 mirror of each mNLOS detection across the wall its ray crosses, with propagated covariance."""

    Params = MirrorParams

    def assign_walls(self, points: np.ndarray, walls: list[WallPosterior]) -> np.ndarray:
        """(K,) wall index for each point, −1 where unanchored (see module doc and
        :func:`plugins.mirror.association.anchor_points`)."""
        return anchor_points(points, walls, self.params.extent_margin, self.params.fallback,
                             who=type(self).__name__).wall_index

    def reconstruct(self, detections: Detections, walls: list[WallPosterior]) -> HiddenPoints:
        """Hidden points for the mNLOS rows of ``detections`` (source_index into ``detections``,
        wall_index into ``walls``), in detection order. Raises InsufficientDataError when there
        are mNLOS detections but no walls; InputError for a wall model other than 'line'/'arc'."""
        return self.mirror_detections(detections, walls)[0]

    def mirror_detections(self, detections: Detections, walls: list[WallPosterior]) -> tuple[HiddenPoints, np.ndarray]:
        """(Eq. 7 hidden points as :meth:`reconstruct`, the virtual points o' (M, 2) [m] of its rows);
        sets ``last_unanchored_``."""
        if not isinstance(detections, Detections):
            raise InputError(f"{type(self).__name__}.reconstruct: expected Detections, got {type(detections).__name__}")
        walls = list(walls)
        for j, w in enumerate(walls):
            if not isinstance(w, WallPosterior) or w.model not in ("line", "arc"):
                got = w.model if isinstance(w, WallPosterior) else type(w).__name__
                raise InputError(f"{type(self).__name__}: walls[{j}] must be a WallPosterior of model 'line' or "
                                 f"'arc', got {got!r}")
        idx = detections.of_class(MNLOS)
        self.last_unanchored_ = np.empty(0, dtype=np.int64)
        if len(idx) == 0:
            return HiddenPoints.empty(), np.empty((0, 2))
        if not walls:
            raise InsufficientDataError(
                f"{type(self).__name__}: {len(idx)} mNLOS detection(s) but no relay wall was estimated; "
                "nothing to mirror them across")
        pts = detections.position[idx]
        pcov = detections.position_cov()[idx]
        anchoring = anchor_points(pts, walls, self.params.extent_margin, self.params.fallback,
                                  who=type(self).__name__, index=idx)
        choice = anchoring.wall_index
        self.last_unanchored_ = idx[anchoring.unanchored]
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
        keep = self.visible(mean, pts, walls, choice, src, detections)
        mean, cov, pts, pcov, choice, gated, src = mean[keep], cov[keep], pts[keep], pcov[keep], choice[keep], \
            src[~keep], src[keep]
        vel = self._velocities(detections, walls, pts, pcov, choice, src) or (None, None)
        return HiddenPoints(mean, cov, src, choice, *vel, view=self._views(walls, pts, choice), gated=gated), pts

    def visible(self, hidden: np.ndarray, virtual: np.ndarray, walls: list[WallPosterior], choice: np.ndarray,
                src: np.ndarray, detections: Detections) -> np.ndarray:
        """(M,) bool: the hidden points (M, 2) [m] that pass the visibility gate
        (:func:`plugins.mirror.visibility.visibility` with ``wedge_margin`` (else ``extent_margin``), ``behind_radar``,
        ``wall_echo``, ``static_speed``, ``one_relay`` and the radial velocities of the detections ``src`` when they carry
        Doppler); all True without ``gate``. The gated ones are logged by rule with their detection indices."""
        if not self.params.gate or len(hidden) == 0:
            return np.ones(len(hidden), dtype=bool)
        p = self.params
        vel = None if detections.velocity is None else detections.velocity[src]
        var = None if detections.velocity_var is None else detections.velocity_var[src]
        margin = p.extent_margin if p.wedge_margin is None else p.wedge_margin
        reason = visibility(hidden, virtual, walls, choice, margin, None if p.behind_radar else 0.0,
                            vel, var, p.wall_echo, p.static_speed, p.one_relay)
        line = describe_gated(reason, src)
        if line:
            log.info("%s: %s", type(self).__name__, line)
        return reason == VISIBLE

    @staticmethod
    def _views(walls, pts, choice) -> np.ndarray:
        """(M, 2) unit direction of the mirrored line of sight at each hidden point, from its bounce point
        towards it: ĝ = g/|g| with g = J_x⁻ᵀ r̂' (:func:`plugins.mirror.mirror_doppler.observed_direction`)."""
        view = pts / np.linalg.norm(pts, axis=1, keepdims=True)  # r̂', where an arc's mirror has no hit
        for j in np.unique(choice):
            m = choice == j
            with np.errstate(invalid="ignore", divide="ignore"):
                g = observed_direction(pts[m], walls[j])
                g = g / np.linalg.norm(g, axis=1, keepdims=True)
            ok = np.all(np.isfinite(g), axis=1)
            view[np.flatnonzero(m)[ok]] = g[ok]
        return view

    @staticmethod
    def _velocities(detections: Detections, walls, pts, pcov, choice, src) -> tuple:
        """(velocity (M, 2), velocity_cov (M, 2, 2)) of the hidden points from the radial velocities, or ()."""
        if detections.velocity is None:
            return ()
        vel, vcov = np.empty_like(pts), np.empty((len(pts), 2, 2))
        for j in np.unique(choice):
            m = choice == j
            vel[m], vcov[m] = unmirror_radial_velocity(pts[m], detections.velocity[src[m]],
                                                       detections.velocity_var[src[m]], walls[j], point_cov=pcov[m])
        return vel, vcov
