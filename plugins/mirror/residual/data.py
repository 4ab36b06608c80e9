"""Training pairs for the residual network from a simulated dataset's ground truth (Sec. 4.2).

Per map and noise draw: the ground truth thinned to the radar's resolution
(:func:`xnlos_core.metrics.thin_to_resolution`) gives LOS points, virtual points o' and their
hidden points o (row-aligned). Detection-like noise is added in polar coordinates (range σ_r [m],
azimuth σ_θ [rad], seeded by (seed, map index, draw)) and a random fraction of the LOS points is
dropped (sparse walls; with ``scale_min`` < 1 the noise level varies per draw); walls are fitted to the noisy LOS points by
the ``lsq`` estimator (single-linkage clusters, TLS lines); each noisy o' is anchored and
mirrored exactly as at inference (:meth:`ResidualMirrorReconstructor.prepare`). The Eq. 9 target
is o − ô_geom.
"""
from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from xnlos_core.errors import InsufficientDataError
from xnlos_core.geometry import cartesian_to_polar, polar_to_cartesian
from xnlos_core.metrics import thin_to_resolution
from xnlos_core.registry import get_registry
from xnlos_core.types import LOS, MNLOS, Detections, GroundTruth

KEYS = ("query", "neigh", "mask", "normal", "target", "geom", "truth", "family")


class NoiseConfig(BaseModel):
    """Detection-like noise on ground-truth points (and the std the detections report)."""

    model_config = ConfigDict(extra="forbid")
    range_std: float = Field(0.15, ge=0, le=10, description="range noise σ_r [m]")
    azimuth_std: float = Field(0.0175, ge=0, le=0.5, description="azimuth noise σ_θ [rad] (0.0175 ≈ 1°)")
    scale_min: float = Field(1.0, ge=0, le=1, description="each draw scales both stds by s ~ U(scale_min, 1) "
                             "(clean draws teach the network that consistent geometry needs no correction)")
    los_keep_min: float = Field(1.0, gt=0, le=1, description="each draw keeps a fraction f ~ U(los_keep_min, 1) "
                                "of the LOS points (detections are sparser than the thinned ground truth)")


def noisy_detections(points: np.ndarray, label: int, noise: NoiseConfig, rng: np.random.Generator,
                     scale: float = 1.0) -> Detections:
    """Detections at ``points`` (N, 2) [m] moved by Gaussian range/azimuth noise (the config's stds
    times ``scale``), reporting the config's stds."""
    r, a = cartesian_to_polar(np.asarray(points, dtype=np.float64).reshape(-1, 2))
    r = np.abs(r + scale * noise.range_std * rng.standard_normal(len(r)))
    a = a + scale * noise.azimuth_std * rng.standard_normal(len(a))
    return Detections.from_points(polar_to_cartesian(r, a), label, 1.0, max(noise.range_std, 1e-3),
                                  max(noise.azimuth_std, 1e-4))


def scene_inputs(gt: GroundTruth, recon, noise: NoiseConfig, rng: np.random.Generator, neighbours: int,
                 support_distance: float):
    """(detections, walls, mirror HiddenPoints, inputs, o (M, 2)) of one noisy draw of thinned ground
    truth ``gt``; None when the scene gives no wall or no anchored mNLOS point."""
    scale = rng.uniform(noise.scale_min, 1.0)
    keep = rng.random(len(gt.los_points)) < rng.uniform(noise.los_keep_min, 1.0)
    los = noisy_detections(gt.los_points[keep], LOS, noise, rng, scale)
    virt = noisy_detections(gt.mnlos_points, MNLOS, noise, rng, scale)
    det = Detections.concat(los, virt)
    try:
        # the lsq wall estimator with its defaults, reached through the registry (another stage)
        walls = get_registry().create("wall_estimator", "lsq").estimate(det)
    except InsufficientDataError:
        return None
    geom, x = recon.prepare(det, walls, neighbours, support_distance)
    if len(geom) == 0:
        return None
    return det, walls, geom, x, gt.hidden_points[geom.source_index - len(los)]


def build_pairs(frames, n_maps: int, recon, noise: NoiseConfig, seed: int, draws: int, neighbours: int,
                support_distance: float, max_maps: int | None = None, progress: bool = False) -> dict[str, np.ndarray]:
    """Concatenated training pairs (keys :data:`KEYS`: the inputs, target o − ô_geom (M, 2) [m],
    geom ô_geom and truth o (M, 2) [m], family (M,) str) over the first ``max_maps`` of the ``n_maps``
    ``frames`` (an iterable of Frames with ground truth, e.g. a ``dataset`` backend's ``frames()``)."""
    from tqdm import tqdm

    parts: list[dict] = []
    n = n_maps if max_maps is None else min(max_maps, n_maps)
    bar = tqdm(total=n, desc="pairs", unit="map", disable=not progress, leave=False)
    for i, frame in enumerate(frames):
        if i >= n:
            break
        bar.update()
        gt = thin_to_resolution(frame.ground_truth, frame.ra_map.radar)
        if len(gt.mnlos_points) == 0 or len(gt.los_points) < 2:
            continue
        for d in range(draws):
            got = scene_inputs(gt, recon, noise, np.random.default_rng([seed, frame.index, d]), neighbours,
                               support_distance)
            if got is None:
                continue
            _, _, geom, x, truth = got
            parts.append({**{k: x[k] for k in ("query", "neigh", "mask", "normal")}, "target": truth - geom.mean,
                          "geom": geom.mean, "truth": truth,
                          "family": np.full(len(geom), str(frame.meta.get("family", "")))})
    bar.close()
    if not parts:
        raise InsufficientDataError("build_pairs: no map gave an anchored mNLOS point")
    return {k: np.concatenate([p[k] for p in parts]) for k in KEYS}
