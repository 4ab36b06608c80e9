"""Radar views beside the RA image: the range–Doppler map and the Cartesian (fan) view of an RA map.

* Range–Doppler from a chirp cube: power Σ_channels |κ(r, d, c)|² of
  :func:`xnlos_core.signal.doppler.range_doppler` [W] over range [m] × radial velocity [m/s]
  (``radar.velocity_axis``), in dB above its median (:func:`range_doppler_db`).
* Range–Doppler from a Doppler RA map alone (``RAMap.velocity``, what a Frame carries): each
  cell's power deposited at its velocity, summed over azimuth, on a velocity grid of
  ``n_velocity`` bins (:func:`range_velocity_from_ra`); a cell whose velocity is NaN counts nowhere.
  It shows where the moving power is, not the spectrum (one velocity per cell).
* Fan view: the RA map's power on its polar grid drawn in the bird's-eye plane (x forward up,
  y left to the left, :mod:`xnlos_core.bev`) with ``pcolormesh``, cell edges half-way between
  the axis samples (:func:`draw_ra_cartesian`).

Each ``draw_*`` function takes an ``ax``, draws, and returns its artist; none keeps state.
"""
from __future__ import annotations

import numpy as np

from xnlos_core.bev import set_bev_limits
from xnlos_core.errors import InputError

#: Label of every radial-velocity axis and colour bar (sign as :mod:`xnlos_core.signal.doppler`).
VELOCITY_LABEL = "radial velocity [m/s] (+ receding)"


def _edges(axis) -> np.ndarray:
    """Cell edges (n + 1,) half-way between the samples of an ascending axis (n,), ends extrapolated."""
    a = np.asarray(axis, float)
    if a.ndim != 1 or len(a) < 2:
        raise InputError(f"axis: expected at least two ascending samples, got shape {a.shape}")
    mid = 0.5 * (a[1:] + a[:-1])
    return np.concatenate([[a[0] - (mid[0] - a[0])], mid, [a[-1] + (a[-1] - mid[-1])]])


def range_doppler_db(cube, radar, **kw) -> np.ndarray:
    """(n_range_bins, n_chirps) range–Doppler power summed over the channels, in dB above its
    median, of a chirp cube (n_samples, n_chirps, n_channels) [√W]; keywords go to
    :func:`xnlos_core.signal.doppler.range_doppler`. Velocity bins as ``radar.velocity_axis``."""
    from xnlos_core.signal.doppler import range_doppler

    p = np.sum(np.abs(range_doppler(cube, radar, **kw)) ** 2, axis=-1)
    db = 10 * np.log10(np.maximum(p, np.finfo(float).tiny))
    return db - np.median(db)


def range_velocity_from_ra(ra, n_velocity: int = 32, v_max: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """(power dB above its median (n_range, n_velocity), velocity bin centres (n_velocity,) [m/s])
    of a Doppler RA map: |κ|² of every cell added to the bin of its ``RAMap.velocity`` (module doc).

    v_max [m/s]: the grid spans ±v_max (default: the largest |v| of the map, at least 1 m/s).
    InputError when the map has no velocity (no Doppler processing)."""
    if ra.velocity is None:
        raise InputError("range_velocity_from_ra: the RA map has no velocity (RAMap.velocity is None): "
                         "a range–Doppler view needs Doppler processing (forward_model doppler = true, or a chirp cube)")
    v = np.asarray(ra.velocity, float)
    p = np.abs(np.asarray(ra.data)) ** 2
    ok = np.isfinite(v)
    if v_max is None:
        v_max = max(1.0, float(np.abs(v[ok]).max())) if ok.any() else 1.0
    edges = np.linspace(-v_max, v_max, n_velocity + 1)
    k = np.clip(np.digitize(v, edges) - 1, 0, n_velocity - 1)
    out = np.zeros((p.shape[0], n_velocity))
    rows = np.broadcast_to(np.arange(p.shape[0])[:, None], p.shape)
    np.add.at(out, (rows[ok], k[ok]), p[ok])
    db = 10 * np.log10(np.maximum(out, np.finfo(float).tiny))
    floor = np.median(db[out > 0]) if (out > 0).any() else 0.0
    return np.where(out > 0, db - floor, np.nan), 0.5 * (edges[1:] + edges[:-1])


def draw_range_doppler(ax, db, range_axis, velocity_axis, *, vmax: float | None = None, cmap: str = "viridis"):
    """Range–Doppler image on ``ax``: ``db`` (n_range, n_velocity) [dB] over velocity [m/s] (x) ×
    range [m] (y), 0 … vmax dB (default: 99.9th percentile, at least 20 dB); returns the QuadMesh."""
    db = np.asarray(db, float)
    r, v = np.asarray(range_axis, float), np.asarray(velocity_axis, float)
    if db.shape != (len(r), len(v)):
        raise InputError(f"draw_range_doppler: db has shape {db.shape}, expected (len(range_axis), "
                         f"len(velocity_axis)) = ({len(r)}, {len(v)})")
    finite = db[np.isfinite(db)]
    top = vmax if vmax is not None else max(20.0, float(np.percentile(finite, 99.9)) if finite.size else 20.0)
    import matplotlib as mpl

    cm = mpl.colormaps[cmap]
    cm = cm.with_extremes(bad=cm(0.0))  # a bin no cell's power fell into reads as the floor
    mesh = ax.pcolormesh(_edges(v), _edges(r), db, cmap=cm, vmin=0.0, vmax=top, shading="flat")
    ax.axvline(0.0, color="w", lw=0.6, ls=":")
    ax.set_xlabel(VELOCITY_LABEL)
    ax.set_ylabel("range [m]")
    return mesh


def draw_ra_cartesian(ax, ra, *, vmax: float | None = None, cmap: str = "viridis", margin: float = 2.0):
    """Fan (bird's-eye) view of the RA map ``ra`` on ``ax``: power above the map's median [dB]
    drawn with ``pcolormesh`` on its polar grid, each cell the annular sector between its range
    and azimuth edges, at (−y, x) like every bird's-eye panel; equal aspect, limits the fan plus
    ``margin`` [m]. Returns the QuadMesh."""
    p_db = ra.power_db()
    rel = p_db - np.median(p_db)
    top = vmax if vmax is not None else max(30.0, float(np.percentile(rel, 99.9)))
    re, ae = np.meshgrid(np.clip(_edges(ra.range_axis), 0.0, None), _edges(ra.azimuth_axis), indexing="ij")
    x, y = re * np.cos(ae), re * np.sin(ae)
    mesh = ax.pcolormesh(-y, x, rel, cmap=cmap, vmin=0.0, vmax=top, shading="flat")
    set_bev_limits(ax, np.column_stack([x.ravel(), y.ravel()]), margin=margin)
    return mesh
