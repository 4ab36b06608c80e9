"""Discrete outcomes of the numerically sensitive stages on fixed, seeded data, printed as JSON.

Run in a subprocess under different BLAS kernels (``OPENBLAS_CORETYPE``) and thread counts
(``OPENBLAS_NUM_THREADS``) by ``tests/unit/test_kernels.py`` and ``tests/kernels/matrix.py``: every
run must print the same outcomes. The cases are the extremes where rounding used to decide: a
noiseless braking car (with and without radial velocities), a noiseless turn, noisy tracks, an exact
L corner and a noisy one, CFAR on a map with an exact plateau, wall model selection on an exact
line, and an association with exactly tied costs.
"""
from __future__ import annotations

import json

import numpy as np


def tracks():
    """(name, t, xy, kwargs) of the motion-identification cases."""
    t = np.arange(30) * 0.1
    u = np.array([np.cos(0.6), np.sin(0.6)])
    pos = (9.0 * t - 1.25 * t ** 2)[:, None] * u
    vel = (9.0 - 2.5 * t)[:, None] * u
    g = pos - np.array([40.0, 30.0])
    g /= np.linalg.norm(g, axis=1, keepdims=True)
    y = np.sum(g * vel, axis=1)
    w = 0.3
    turn = 8.0 / w * np.stack([np.sin(w * t), 1.0 - np.cos(w * t)], axis=1) + [12.0, -3.0]
    rng = np.random.default_rng(5)
    noisy = pos + rng.normal(0.0, 0.3, pos.shape)
    straight = np.stack([20.0 + 6.0 * t, 4.0 - 1.0 * t], axis=1)
    return [("braking", t, pos, dict(sigma=1e-3)),
            ("braking_doppler", t, pos, dict(sigma=1e-3, direction=g, radial=y)),
            ("braking_profiled", t, pos, dict(direction=g, radial=y)),
            ("turn", t, turn, dict(sigma=1e-3)),
            ("straight_profiled", t, straight, {}),
            ("noisy_braking", t, noisy, dict(sigma=0.3))]


def motion() -> dict:
    from estimators.trackers.sindy_model import identify_motion

    return {name: identify_motion(t, xy, n_models=5, **kw).terms() for name, t, xy, kw in tracks()}


def corners() -> dict:
    from estimators.corners import split_corners

    a = np.stack([np.linspace(10, 20, 40), np.full(40, 5.0)], axis=1)
    b = np.stack([np.full(40, 20.0), np.linspace(5.5, 15, 40)], axis=1)
    exact = np.concatenate([a, b])
    noisy = exact + np.random.default_rng(3).normal(0.0, 0.05, exact.shape)
    line = np.stack([np.linspace(10, 30, 60), 0.5 * np.linspace(10, 30, 60) + 2.0], axis=1)
    return {name: sorted(len(p) for p in split_corners(x, 0.5))
            for name, x in (("L_exact", exact), ("L_noisy", noisy), ("line_exact", line))}


def walls() -> dict:
    """Wall model selection (line / arc / corner) of the MAP estimator on exact points: a line, a
    circular arc and an L seen as two facades."""
    from xnlos_core import LOS, Detections
    from xnlos_core.registry import get_registry

    est = get_registry().create("wall_estimator", "casadi_map", {})
    x = np.linspace(8, 16, 30)
    ang = np.linspace(-0.5, 0.5, 40)
    cases = {"line": np.stack([x, 0.4 * x + 3.0], axis=1),
             "arc": np.stack([25.0 - 12.0 * np.cos(ang), 12.0 * np.sin(ang)], axis=1),
             "L": np.concatenate([np.stack([np.linspace(10, 20, 40), np.full(40, 5.0)], axis=1),
                                  np.stack([np.full(40, 20.0), np.linspace(5.5, 15, 40)], axis=1)])}
    return {name: sorted(w.model for w in est.estimate(Detections.from_points(p, LOS, 1.0, 0.05, 0.002)))
            for name, p in cases.items()}


def cfar() -> dict:
    from plugins.detectors.peaks import local_maxima

    rng = np.random.default_rng(11)
    p = rng.exponential(1.0, (64, 48))
    p[20, 10] = p[20, 11] = 500.0                      # an exact two-cell plateau: one peak
    p[40, 30] = 300.0
    p[40, 31] = 300.0 * (1 - 1e-13)                    # equal up to rounding: one peak
    return {"peaks": int(local_maxima(p).sum()), "strong": int((local_maxima(p) & (p > 100)).sum())}


def association() -> dict:
    from xnlos_core.numerics import gated_assignment

    c = np.array([[1.0, 1.0, 5.0], [1.0, 1.0 + 1e-15, 5.0], [5.0, 5.0, 2.0]])
    rows, cols = gated_assignment(c, 3.0)
    return {"pairs": [[int(r), int(k)] for r, k in zip(rows, cols)]}


def outcomes() -> dict:
    return {"motion": motion(), "corners": corners(), "walls": walls(), "cfar": cfar(),
            "association": association()}


if __name__ == "__main__":
    print(json.dumps(outcomes(), sort_keys=True))
