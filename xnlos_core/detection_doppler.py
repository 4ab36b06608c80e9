"""Radial velocity of each detection from the RA map's Doppler maps (issue 28), shared by every detector.

When a frame came from Doppler processing its RA map carries, per cell, the radial velocity
v̂_r = dR/dt [m/s] (positive receding) and its σ [m/s] (:class:`xnlos_core.types.RAMap`). A
detection takes the values of **one cell, not an interpolation**: the cell of its peak. Velocity
is a per-cell estimate (the Doppler bin of that cell's strongest return); between two cells of
different targets a bilinear blend would be a velocity neither target has, and the peak cell is
the one with the highest SNR, hence the smallest σ. Sub-cell range/azimuth refinement does not
move the cell. variance = σ² [m²/s²].
"""
from __future__ import annotations

import dataclasses

import numpy as np

from .errors import InputError
from .types import Detections, RAMap


def with_cell_velocity(detections: Detections, ra_map: RAMap, rows, cols) -> Detections:
    """``detections`` with ``velocity`` / ``velocity_var`` read at each detection's peak cell.

    rows, cols: (K,) integer indices of the peak cells into ``ra_map`` (n_range, n_azimuth), in the
    order of ``detections``. Returns ``detections`` itself (unchanged, so bit-identical) when the
    map has no velocity maps; otherwise a copy with velocity (K,) [m/s] and velocity_var (K,) [m²/s²].
    """
    if ra_map.velocity is None:
        return detections
    k = len(detections)
    r = np.asarray(rows)
    c = np.asarray(cols)
    if r.shape != (k,) or c.shape != (k,) or (k and (r.dtype.kind not in "iu" or c.dtype.kind not in "iu")):
        raise InputError(f"with_cell_velocity: rows and cols must be integer arrays of shape ({k},) (one peak "
                         f"cell per detection), got {r.dtype} {r.shape} and {c.dtype} {c.shape}")
    h, w = ra_map.shape
    if k and (r.min() < 0 or r.max() >= h or c.min() < 0 or c.max() >= w):
        raise InputError(f"with_cell_velocity: peak cells must lie in the {h} × {w} RA map, got rows "
                         f"[{r.min()}, {r.max()}] and cols [{c.min()}, {c.max()}]")
    return dataclasses.replace(detections, velocity=ra_map.velocity[r, c], velocity_var=ra_map.velocity_std[r, c] ** 2)


def nearest_cells(frac_rows, frac_cols, shape: tuple[int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Integer (rows, cols) of the cells nearest to fractional indices (K,) on a map of ``shape``
    (n_range, n_azimuth), clipped into the map: the peak cell of a detection refined by at most ½ cell
    (a refinement of exactly ±½ is a tie, resolved to the even index)."""
    h, w = shape
    r = np.clip(np.rint(np.asarray(frac_rows, dtype=np.float64)), 0, h - 1).astype(np.int64)
    c = np.clip(np.rint(np.asarray(frac_cols, dtype=np.float64)), 0, w - 1).astype(np.int64)
    return r, c
