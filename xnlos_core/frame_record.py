"""Detections, walls and hidden points ↔ their objects in a results.jsonl record (schema 2).

Written by :meth:`xnlos_core.pipeline.FrameResult.record`, read back by :mod:`xnlos_core.app.results`;
the layout of a whole line is :data:`xnlos_core.app.results_schema.RESULTS_SCHEMA`.

- ``detection_table``: one column per field, K rows, row k = detection k (the row a hidden
  point's ``source_index`` names): range [m], azimuth [rad], label (0 LOS, 1 mNLOS, 2 unclassified),
  class (its name), confidence [0, 1], range_std [m] and azimuth_std [rad] (1-σ; the covariance of
  (r, θ) is diag(range_std², azimuth_std²)); with Doppler also velocity [m/s] (radial, positive
  receding) and velocity_var [m²/s²].
- a wall: model, param_names (P,), mean (P,), params {name: value}, cov (P, P) in the order of
  param_names, n_points, extent (2, 2) [m] (end points of the supported segment or arc) or null,
  anchor (2,) [m] of an arc or null. Posterior samples and diagnostics are not recorded.
- ``hidden``: mean (M, 2) [m], cov (M, 2, 2) [m²], source_index (M,) (row of detection_table),
  wall_index (M,) (index into walls); with Doppler also velocity (M, 2) [m/s] and velocity_cov
  (M, 2, 2) [m²/s²].
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError
from .types import CLASS_NAMES, Detections, HiddenPoints, WallPosterior

#: Version of the record layout: 2 adds schema_version, detection_table, the wall fields beyond
#: model/mean/cov/n_points, and hidden. Records without ``schema_version`` are version 1.
SCHEMA_VERSION = 2

DETECTION_COLUMNS = ("range", "azimuth", "label", "class", "confidence", "range_std", "azimuth_std")
DOPPLER_COLUMNS = ("velocity", "velocity_var")
#: Parameter names of the built-in wall models (a version-1 record does not name them).
WALL_PARAMS = {"line": ("phi", "b"), "arc": ("phi", "b", "kappa")}


def detections_record(d: Detections) -> dict[str, Any]:
    """The ``detection_table`` object of ``d`` (columns of length K)."""
    out: dict[str, Any] = {"range": d.range.tolist(), "azimuth": d.azimuth.tolist(), "label": d.label.tolist(),
                           "class": [CLASS_NAMES[k] for k in d.label], "confidence": d.confidence.tolist(),
                           "range_std": d.range_std.tolist(), "azimuth_std": d.azimuth_std.tolist()}
    if d.velocity is not None:
        out.update(velocity=d.velocity.tolist(), velocity_var=d.velocity_var.tolist())
    return out


def wall_record(w: WallPosterior) -> dict[str, Any]:
    """One entry of ``walls``: the version-1 keys (model, mean, cov, n_points) and the named ones."""
    return {"model": w.model, "mean": w.mean.tolist(), "cov": w.cov.tolist(), "n_points": int(w.n_points),
            "param_names": list(w.param_names), "params": dict(zip(w.param_names, w.mean.tolist())),
            "extent": None if w.extent is None else w.extent.tolist(),
            "anchor": None if w.anchor is None else w.anchor.tolist()}


def hidden_record(h: HiddenPoints) -> dict[str, Any]:
    """The ``hidden`` object of ``h``."""
    out: dict[str, Any] = {"mean": h.mean.tolist(), "cov": h.cov.tolist(), "source_index": h.source_index.tolist(),
                           "wall_index": h.wall_index.tolist()}
    if h.velocity is not None:
        out.update(velocity=h.velocity.tolist(), velocity_cov=h.velocity_cov.tolist())
    if h.view is not None:
        out["view"] = h.view.tolist()
    if len(h.gated):
        out["gated"] = h.gated.tolist()
    return out


def _array(rec: dict, key: str, where: str, shape_tail: tuple[int, ...] = (), dtype=float) -> np.ndarray:
    """rec[key] as an array of shape (n, *shape_tail) (JSON drops the inner shape of an empty list)."""
    if key not in rec:
        raise InputError(f"{where}: missing {key}")
    try:
        arr = np.asarray(rec[key], dtype=dtype)
    except (TypeError, ValueError):
        raise InputError(f"{where}.{key}: expected (nested) numbers, got {str(rec[key])[:80]}") from None
    if arr.size == 0:
        return np.zeros((0, *shape_tail), dtype)
    if arr.shape[1:] != shape_tail:
        raise InputError(f"{where}.{key}: expected shape (n, {', '.join(map(str, shape_tail))}), got {arr.shape}"
                         if shape_tail else f"{where}.{key}: expected a flat list, got shape {arr.shape}")
    return arr


def _checked(where: str, build):
    """``build()``, its InputError prefixed with ``where`` (the record key being read)."""
    try:
        return build()
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def detections_from_record(rec: dict[str, Any], where: str = "detection_table") -> Detections:
    """The Detections a ``detection_table`` object describes; InputError naming the key."""
    if not isinstance(rec, dict):
        raise InputError(f"{where}: expected an object of columns, got {type(rec).__name__}")
    cols = [_array(rec, k, where, dtype=np.int8 if k == "label" else float)
            for k in DETECTION_COLUMNS if k != "class"]
    doppler = [_array(rec, k, where) for k in DOPPLER_COLUMNS] if "velocity" in rec else []
    return _checked(where, lambda: Detections(*cols, *doppler))


def wall_from_record(rec: dict[str, Any], where: str = "walls[0]") -> WallPosterior:
    """The WallPosterior a ``walls`` entry describes (version 1: parameter names from the model;
    an arc of version 1 has no anchor and is read with the radar as anchor)."""
    if not isinstance(rec, dict) or "model" not in rec:
        raise InputError(f"{where}: expected an object with model, mean, cov")
    mean = _array(rec, "mean", where)
    names = tuple(rec.get("param_names") or WALL_PARAMS.get(rec["model"], ()))
    cov = _array(rec, "cov", where, (len(mean),))
    extent = rec.get("extent")
    anchor = rec.get("anchor")
    return _checked(where, lambda: WallPosterior(
        rec["model"], mean, cov, names, int(rec.get("n_points", 0)),
        extent=None if extent is None else np.asarray(extent, float),
        anchor=None if anchor is None else np.asarray(anchor, float)))


def hidden_from_record(rec: dict[str, Any], where: str = "hidden") -> HiddenPoints:
    """The HiddenPoints a ``hidden`` object describes; InputError naming the key."""
    if not isinstance(rec, dict):
        raise InputError(f"{where}: expected an object with mean, cov, source_index, wall_index")
    parts = [_array(rec, "mean", where, (2,)), _array(rec, "cov", where, (2, 2)),
             _array(rec, "source_index", where, dtype=np.int64), _array(rec, "wall_index", where, dtype=np.int64)]
    parts += [_array(rec, "velocity", where, (2,)), _array(rec, "velocity_cov", where, (2, 2))] if "velocity" in rec \
        else [None, None]
    view = _array(rec, "view", where, (2,)) if "view" in rec else None
    gated = _array(rec, "gated", where, dtype=np.int64) if "gated" in rec else None
    return _checked(where, lambda: HiddenPoints(*parts, view=view, gated=gated))
