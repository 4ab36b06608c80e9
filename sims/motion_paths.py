"""Motion of propagation paths: object velocity, its mirror image, and a path's range rate.

The one place the forward models read how fast a scene object moves (:func:`object_velocity`),
so a time-varying trajectory changes only this function. A mirrored path's echo belongs to the
virtual scatterer o' = R_Π(o) (Eq. 5), which moves at v' = (I − 2nnᵀ)v (:func:`mirror_velocity`).
"""
from __future__ import annotations

import numpy as np


def object_velocity(obj, t: float) -> np.ndarray:
    """Velocity (2,) [m/s] of scene object ``obj`` (:class:`xnlos_core.scene.ObjectSpec`) at time ``t`` [s]:
    its trajectory's centre velocity (:mod:`xnlos_core.motion`; constant ``velocity`` without one).

    Every scatterer of the object gets the centre's velocity; a turning box's rigid-body term ω × r
    (:func:`sims.scene_truth.point_velocities`) is left out of the paths' Doppler (|ω r| ≤ 0.5 m/s
    for a car turning at 0.2 rad/s, 2.5 m from its centre).
    """
    return np.asarray(obj.motion(np.array([float(t)])).velocity[0], dtype=np.float64)


def mirror_velocity(velocity, normals) -> np.ndarray:
    """Velocity of a virtual scatterer seen through the mirrors ``normals``: v' = Π(I − 2nnᵀ)v.

    velocity: (..., d) [m/s]; normals: (k, d) unit plane normals in the order the points were
    reflected (first row applied first). Only the linear part of each reflection acts on a velocity
    (the offset b of nᵀx + b = 0 moves the point, not its rate).
    """
    v = np.asarray(velocity, dtype=np.float64)
    for n in np.atleast_2d(np.asarray(normals, dtype=np.float64)):
        v = v - 2.0 * (v @ n)[..., None] * n  # any dimension: the ray tracer reflects 3-D velocities
    return v


def radial_velocity(pos: np.ndarray, velocity: np.ndarray, length: np.ndarray) -> np.ndarray:
    """Range rate v_r = d(L/2)/dt [m/s] (positive receding) of P paths, (P,).

    pos (P, 2) [m]: the (virtual) point whose distance from the radar is L/2, horizontal
    coordinates relative to the radar; velocity (P, 2) [m/s]: its horizontal velocity; length (P,)
    [m]: unfolded round trip L. With the radar at the origin, d|o' − r|/dt = (o' − r)·v'/|o' − r|,
    whose horizontal part is pos·v' (motion is horizontal), over |o' − r| = L/2. For a single-bounce
    specular path the unfolded path L/2 = |o'| is the distance to the virtual target, so this is
    exactly the virtual target's radial velocity; for a direct path, the target's own.
    """
    half = np.maximum(np.asarray(length, dtype=np.float64) / 2.0, 1e-12)
    return np.einsum("ij,ij->i", np.asarray(pos, dtype=np.float64).reshape(-1, 2),
                     np.asarray(velocity, dtype=np.float64).reshape(-1, 2)) / half
