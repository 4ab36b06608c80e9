"""Per-frame motion truth of a scene's objects: where each object is and how fast it
moves at time t, and the same for its mirror images across the relay walls.

A relay wall nᵀx + b = 0 maps a hidden point o to its virtual image o' = o − 2(nᵀo + b)n (Eq. 7, an
involution) and, being a fixed affine map, its velocity to v' = (I − 2nnᵀ)v: the mNLOS echo of a
moving object moves with the mirrored velocity (mirror Doppler;
:mod:`plugins.mirror.mirror_doppler` goes the other way, with uncertainty).
"""
from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.geometry import mirror_reflect
from xnlos_core.scene import Scene
from xnlos_core.types import WallSegment


@dataclass(frozen=True)
class SceneTruth:
    """Object truth at one time t [s] for K objects and J relay walls.

    names (K,); position (K, 2) [m] (object centres); velocity (K, 2) [m/s]; heading (K,) [rad];
    walls (J,) the WallSegments mirrored across; mirrored_position (K, J, 2) [m] the virtual centres
    o' across each wall; mirrored_velocity (K, J, 2) [m/s] their velocities (I − 2nnᵀ)v.
    """

    t: float
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    heading: np.ndarray
    walls: tuple[WallSegment, ...]
    mirrored_position: np.ndarray
    mirrored_velocity: np.ndarray


def mirror_velocity(velocity, normal) -> np.ndarray:
    """(I − 2nnᵀ)v for velocities (…, 2) [m/s] and a wall normal n (2,) (normalised here)."""
    return mirror_reflect(velocity, normal, 0.0)  # the linear part of Eq. 7: b drops out of a velocity


def point_velocities(scene: Scene, t: float, obj, points) -> np.ndarray:
    """Velocities (M, 2) [m/s] at time t [s] of scatterers at ``points`` (M, 2) [m] on the objects
    ``obj`` (M,) (index into scene.objects; < 0 for static surfaces, velocity 0): the rigid-body
    velocity v + ω × (p − c) of the object's centre c, velocity v and yaw rate ω."""
    obj = np.asarray(obj, dtype=np.int64).reshape(-1)
    p = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    out = np.zeros((len(obj), 2))
    for k in np.unique(obj[obj >= 0]):
        s = scene.objects[k].motion(float(t))
        r = p[obj == k] - s.position[0]
        out[obj == k] = s.velocity[0] + s.yaw_rate[0] * np.stack([-r[:, 1], r[:, 0]], axis=-1)
    return out


def image_velocities(hidden, virtual, velocity) -> np.ndarray:
    """Velocities (M, 2) [m/s] of virtual points o' (M, 2) [m], images of hidden points o (M, 2) [m]
    moving at ``velocity`` (M, 2): (I − 2nnᵀ)v with n ∥ o − o' (each pair's own mirror line)."""
    d = np.asarray(hidden, dtype=np.float64) - np.asarray(virtual, dtype=np.float64)
    v = np.asarray(velocity, dtype=np.float64)
    norm = np.linalg.norm(d, axis=-1, keepdims=True)
    n = np.divide(d, norm, out=np.zeros_like(d), where=norm > 0)  # o = o' only on the wall: no reflection
    return v - 2 * np.sum(v * n, axis=-1, keepdims=True) * n


def scene_truth(scene: Scene, t: float, walls: Sequence[WallSegment] | None = None) -> SceneTruth:
    """Objects of ``scene`` at time ``t`` [s] and their mirror images across ``walls`` (default: the
    planar pieces of the scene's relay walls, :meth:`Scene.planar_walls`). InputError for a
    non-finite ``t`` or a wall that is not a WallSegment."""
    if not isinstance(scene, Scene):
        raise InputError(f"scene_truth: scene must be a Scene, got {type(scene).__name__}")
    if not np.isfinite(t):
        raise InputError(f"scene_truth: t must be a finite time [s], got {t}")
    if walls is None:
        walls = [w.segment() for w in scene.planar_walls() if w.relay]
    walls = tuple(walls)
    for j, w in enumerate(walls):
        if not isinstance(w, WallSegment):
            raise InputError(f"scene_truth: walls[{j}] must be a WallSegment, got {type(w).__name__}")
    states = [o.motion(float(t)) for o in scene.objects]
    k = len(states)
    pos = np.array([s.position[0] for s in states]).reshape(k, 2)
    vel = np.array([s.velocity[0] for s in states]).reshape(k, 2)
    heading = np.array([s.heading[0] for s in states]).reshape(k)
    m_pos = np.stack([mirror_reflect(pos, w.normal, w.offset) for w in walls], axis=1) if walls else \
        np.empty((k, 0, 2))
    m_vel = np.stack([mirror_velocity(vel, w.normal) for w in walls], axis=1) if walls else np.empty((k, 0, 2))
    return SceneTruth(float(t), tuple(o.name for o in scene.objects), pos, vel, heading, walls, m_pos, m_vel)


# Thresholds of :func:`motion_kind`: a heading change of 0.1 rad (≈ 6°) or a speed loss of 1 m/s over
# the sequence is beyond what measurement noise makes of a straight, steady road user.
TURN_MIN_RAD = 0.1
BRAKE_MIN_SPEED = 1.0
MOTION_KINDS = ("static", "straight", "turning", "braking")


def is_moving(obj) -> bool:
    """Whether scene object ``obj`` (an ObjectSpec) moves: it has a trajectory or a non-zero velocity."""
    return obj.trajectory is not None or any(v != 0 for v in obj.velocity)


def motion_kind(obj, duration: float) -> str:
    """The kind of motion of ``obj`` (an ObjectSpec) over [0, ``duration``] [s], from its trajectory model:
    "static" (no speed), "braking" (speed falls by ≥ BRAKE_MIN_SPEED m/s), "turning" (heading turns by
    ≥ TURN_MIN_RAD rad) or "straight" (anything else: constant velocity, mild steering)."""
    if not (np.isfinite(duration) and duration >= 0):
        raise InputError(f"motion_kind: duration must be a finite time ≥ 0 [s], got {duration}")
    s = obj.motion(np.array([0.0, float(duration)]))
    speed = np.linalg.norm(s.velocity, axis=1)
    if speed.max() == 0:
        return "static"
    if speed[0] - speed[1] >= BRAKE_MIN_SPEED:
        return "braking"
    if abs(s.heading[1] - s.heading[0]) >= TURN_MIN_RAD:
        return "turning"
    return "straight"
