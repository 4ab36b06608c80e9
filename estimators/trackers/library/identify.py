"""The library's entry point: :func:`identify_batch` identifies every track of a frame at once.

Each track is brought into its own frame (:func:`line_direction`), the tracks sampled at the same
relative times are fitted together (:mod:`estimators.trackers.library.fit`), those with radial
velocities refitted with them (:mod:`estimators.trackers.library.doppler`), and each track's entry is
selected by Eqs. (1)–(2) (:mod:`estimators.trackers.library.selection`, thresholds from
:func:`lr_threshold`).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from xnlos_core.errors import InputError

from .doppler import RADIAL_SHARES, fit_doppler, radial_rows
from .entries import LIBRARY, MIN_SAMPLES, N_PARAMS, Envelope, LibraryFit
from .fit import fit_group
from .selection import criteria, select_fit


@lru_cache(maxsize=64)
def lr_threshold(dof: int, level: float, tests: int) -> float:
    """χ²_dof quantile at 1 − level/tests (scipy.special here, not at import: cheap start-up)."""
    from scipy.special import chdtri

    return float(chdtri(dof, level / tests))


def line_direction(z: np.ndarray) -> np.ndarray:
    """Unit principal axis (2,) of a track's positions z (n, 2), sign-fixed so that the net displacement
    runs along it (ties: +x)."""
    d = z - z.mean(axis=0)
    _, vec = np.linalg.eigh(d.T @ d)
    u = vec[:, 1]
    return u if float((z[-1] - z[0]) @ u) >= 0 else -u


def identify_batch(tracks, level: float = 0.01, envelope: Envelope = Envelope(), radial_share: str = "ar1",
                   radial_floor: float = 0.1) -> list[LibraryFit]:
    """Identify every track of ``tracks`` — a sequence of (t (n,) [s] increasing, z (n, 2) [m]), n ≥ 8,
    optionally with its Doppler samples (…, ĝ (n, 2) unit directions, y (n,) [m/s] radial velocities,
    NaN where a sample has none) — over the library at once (package docstring): a :class:`LibraryFit`
    per track. ``radial_share`` ("ar1" or "full") and ``radial_floor`` [m/s] (the least σ_r):
    :mod:`estimators.trackers.library.doppler`.

    Each track is fitted in its own frame (centred at its mean position, û along +x): every entry is
    rotation-equivariant there, so tracks sampled at the same relative times share their designs and
    normal matrices (:func:`~estimators.trackers.library.fit.shared_designs`), and one matrix product per
    entry fits them all; a track with Doppler rows is then refitted with them, over every grid value at
    once (:func:`~estimators.trackers.library.doppler.fit_doppler`)."""
    if not 0 < level < 1:
        raise InputError(f"identify_batch: level must be in (0, 1), got {level}")
    if radial_share not in RADIAL_SHARES:
        raise InputError(f"identify_batch: radial_share must be one of {RADIAL_SHARES}, got {radial_share!r}")
    if not (np.isfinite(radial_floor) and radial_floor > 0):
        raise InputError(f"identify_batch: radial_floor must be a positive SD [m/s], got {radial_floor}")
    groups, local = {}, []
    for i, track in enumerate(tracks):
        if len(track) not in (2, 4):
            raise InputError(f"identify_batch: track {i} must be (t, z) or (t, z, ĝ, y)")
        t, zi = np.asarray(track[0], np.float64), np.asarray(track[1], np.float64)
        if t.ndim != 1 or zi.shape != (len(t), 2) or np.any(np.diff(t) <= 0) or not np.all(np.isfinite(zi)):
            raise InputError(f"identify_batch: track {i} needs t (n,) strictly increasing [s] and finite z (n, 2) [m]")
        if len(t) < MIN_SAMPLES:
            raise InputError(f"identify_batch: track {i} needs ≥ {MIN_SAMPLES} samples, got {len(t)}")
        centre = zi.mean(axis=0)
        u = line_direction(zi)
        rot = np.array([[u[0], -u[1]], [u[1], u[0]]])
        zl = (zi - centre) @ rot                                       # rows: (ûᵀ(z − c), nᵀ(z − c))
        tau = np.round((t - t[-1]) * 1e6) / 1e6                        # µs: one pattern for one frame grid
        radial = radial_rows(i, track, len(t), rot, radial_floor) if len(track) == 4 else None
        local.append((t[-1], centre, u, tau, zl, radial))
        groups.setdefault(tau.tobytes(), []).append(i)
    out = [None] * len(local)
    k = np.array([N_PARAMS[m] for m in LIBRARY])
    thresholds = np.array([0.0] + [lr_threshold(int(kk - 4), level, len(LIBRARY) - 1) for kk in k[1:]])
    for members in groups.values():
        z = np.array([local[i][4] for i in members])
        tau = local[members[0]][3]
        fits = fit_group(tau, z)
        T = len(members)
        radial = {"rss": np.zeros((T, len(LIBRARY))), "m": np.zeros(T), "lam": np.zeros(T), "resid": [None] * T}
        patterns = {}                                                  # Doppler tracks by their samples' indices
        for row, i in enumerate(members):
            if local[i][5] is not None:
                patterns.setdefault(local[i][5][0].tobytes(), []).append(row)
        for rows in patterns.values():
            rows = np.array(rows)
            fit_doppler(fits, radial, rows, tau, z[rows], [local[members[r]][5] for r in rows], k)
        stats = criteria(fits, z, k, radial, radial_share)
        for row, i in enumerate(members):
            out[i] = select_fit(fits, row, local[i], k, thresholds, envelope, [a[row] for a in stats])
    return out
