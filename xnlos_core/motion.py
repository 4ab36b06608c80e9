"""Object trajectories in the bird's-eye plane: where a scene object is at time t.

Every model is a pydantic table (``trajectory = { model = "...", ... }`` on a scene object) and
gives, for an array of times t (T,) [s], the :class:`MotionState` relative to the object's start
pose (centre c₀ [m], heading θ₀ [rad] from +x at t = 0):

* ``constant_velocity`` (CV): c(t) = c₀ + t·v, heading θ₀ (the box keeps its orientation, as the
  scene's plain ``velocity`` key has always meant).
* ``constant_turn`` (CT): speed v, yaw rate ω; θ(t) = θ₀ + ωt and the centre runs on a circle of
  radius v/|ω| (a straight line for ω = 0).
* ``constant_acceleration`` (CA): straight along θ₀ with speed v(t) = v₀ + a·t, held at 0 once
  reached (braking stops after v₀²/(2|a|) and never reverses).
* ``bicycle``: kinematic bicycle referenced at the rear axle, wheelbase L, steering angle δ,
  speed v₀, acceleration a: ẋ = v cos θ, ẏ = v sin θ, θ̇ = v tan δ / L, v̇ = a (speed held at 0
  as for CA). For constant δ the curvature κ = tan δ / L is constant, so the path is the circle
  of radius L/|tan δ| travelled by arc length s(t) — integrated exactly in closed form (no
  solve_ivp: exact, vectorised over t, and free of step-size error).

All share one closed form: after arc length s along a path of constant curvature turning by
ψ = κs, the displacement is s·(cos θ₀ S(ψ) − sin θ₀ C(ψ), sin θ₀ S(ψ) + cos θ₀ C(ψ)) with
S(ψ) = sin ψ / ψ and C(ψ) = (1 − cos ψ)/ψ = sin(ψ/2)·S(ψ/2), both finite at ψ = 0 (ω → 0 or
δ → 0 is the straight line, without a division by zero).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

MAX_SPEED = 1_000.0  # m/s, as xnlos_core.scene
MAX_ACCEL = 100.0  # m/s²: beyond any vehicle's braking or launch
Speed = Annotated[float, Field(ge=0, le=MAX_SPEED, allow_inf_nan=False)]
Component = Annotated[float, Field(ge=-MAX_SPEED, le=MAX_SPEED, allow_inf_nan=False)]


@dataclass(frozen=True)
class MotionState:
    """Object state at times t (T,): position (T, 2) [m], velocity (T, 2) [m/s], heading (T,) [rad],
    yaw_rate (T,) [rad/s] (dθ/dt: a point p of a rigid box moves at velocity + yaw_rate × (p − position))."""

    position: np.ndarray
    velocity: np.ndarray
    heading: np.ndarray
    yaw_rate: np.ndarray


def _sinc(x):
    return np.sinc(x / np.pi)  # sin x / x, 1 at 0


def _arc(s, psi, heading0: float) -> np.ndarray:
    """Displacement (T, 2) [m] after arc length s (T,) turning by ψ (T,) [rad] from heading θ₀."""
    along = s * _sinc(psi)
    across = s * np.sin(psi / 2) * _sinc(psi / 2)
    c, sn = math.cos(heading0), math.sin(heading0)
    return np.stack([c * along - sn * across, sn * along + c * across], axis=-1)


def _speed_profile(t, v0: float, a: float) -> tuple[np.ndarray, np.ndarray]:
    """(arc length s (T,) [m], speed (T,) [m/s]) of v̇ = a from v₀ at t = 0, the speed held at 0 once
    it reaches 0 (forwards in time when braking, backwards when accelerating): never reverses."""
    lo = -v0 / a if a > 0 else -np.inf
    hi = v0 / -a if a < 0 else np.inf
    tc = np.clip(t, lo, hi)
    return v0 * tc + 0.5 * a * tc * tc, v0 + a * tc


def _times(t) -> np.ndarray:
    return np.atleast_1d(np.asarray(t, dtype=np.float64))


def _state(start, pos, speed, heading, yaw_rate) -> MotionState:
    vel = speed[:, None] * np.stack([np.cos(heading), np.sin(heading)], axis=-1)
    return MotionState(np.asarray(start, float) + pos, vel, heading, yaw_rate)


class ConstantVelocity(BaseModel):
    """CV: c(t) = c₀ + t·v; the heading stays θ₀. ``velocity`` (vx, vy) [m/s]."""

    model_config = ConfigDict(extra="forbid")
    model: Literal["constant_velocity"] = "constant_velocity"
    velocity: tuple[Component, Component] = (0.0, 0.0)

    def state(self, t, start=(0.0, 0.0), heading: float = 0.0) -> MotionState:
        t = _times(t)
        v = np.asarray(self.velocity, float)
        return MotionState(np.asarray(start, float) + t[:, None] * v, np.broadcast_to(v, (len(t), 2)).copy(),
                           np.full(len(t), float(heading)), np.zeros(len(t)))


class ConstantTurn(BaseModel):
    """CT: speed v [m/s] along the heading, which turns at yaw rate ω [rad/s]; circle of radius v/|ω|."""

    model_config = ConfigDict(extra="forbid")
    model: Literal["constant_turn"] = "constant_turn"
    speed: Speed
    yaw_rate: float = Field(..., ge=-10.0, le=10.0, allow_inf_nan=False, description="ω [rad/s], > 0 turns left")

    def state(self, t, start=(0.0, 0.0), heading: float = 0.0) -> MotionState:
        t = _times(t)
        psi = self.yaw_rate * t
        return _state(start, _arc(self.speed * t, psi, heading), np.full(len(t), self.speed), heading + psi,
                      np.full(len(t), self.yaw_rate))


class ConstantAcceleration(BaseModel):
    """CA: straight along θ₀, speed v₀ + a·t [m/s] held at 0 once reached (a < 0: braking to a stop
    after v₀²/(2|a|) metres)."""

    model_config = ConfigDict(extra="forbid")
    model: Literal["constant_acceleration"] = "constant_acceleration"
    speed: Speed
    acceleration: float = Field(..., ge=-MAX_ACCEL, le=MAX_ACCEL, allow_inf_nan=False, description="a [m/s²]")

    def state(self, t, start=(0.0, 0.0), heading: float = 0.0) -> MotionState:
        t = _times(t)
        s, v = _speed_profile(t, self.speed, self.acceleration)
        return _state(start, _arc(s, np.zeros_like(s), heading), v, np.full(len(t), float(heading)), np.zeros(len(t)))


class Bicycle(BaseModel):
    """Kinematic bicycle at the rear axle (module doc): wheelbase L [m], steering δ [rad], speed v₀
    [m/s], acceleration a [m/s²]; circle of radius L/|tan δ| by arc length, exact for constant inputs."""

    model_config = ConfigDict(extra="forbid")
    model: Literal["bicycle"] = "bicycle"
    wheelbase: float = Field(2.7, gt=0.1, le=20.0, allow_inf_nan=False, description="L [m]")
    steering: float = Field(0.0, ge=-1.2, le=1.2, allow_inf_nan=False, description="δ [rad], > 0 turns left")
    speed: Speed
    acceleration: float = Field(0.0, ge=-MAX_ACCEL, le=MAX_ACCEL, allow_inf_nan=False, description="a [m/s²]")

    def state(self, t, start=(0.0, 0.0), heading: float = 0.0) -> MotionState:
        t = _times(t)
        s, v = _speed_profile(t, self.speed, self.acceleration)
        kappa = math.tan(self.steering) / self.wheelbase
        return _state(start, _arc(s, kappa * s, heading), v, heading + kappa * s, kappa * v)


Trajectory = Annotated[Union[ConstantVelocity, ConstantTurn, ConstantAcceleration, Bicycle],
                       Field(discriminator="model")]
