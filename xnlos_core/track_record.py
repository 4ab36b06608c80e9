"""Tracks ↔ the ``tracks`` object of a results.jsonl record.

Always: id (T,), position (T, 2) [m], velocity (T, 2) [m/s]. With a forecast (Tracks.horizons …
model given) also horizons (K,) [s], forecast (T, K, 2) [m], radius50 / radius90 (T, K) [m] and
model (T,) str; with time-to-appearance also arrival (T,) [s] and arrival_interval (T, 2) [s].
Absent fields are absent keys, so records of trackers without them are byte-identical to those
written before the fields existed. NaN is written as null (JSON has no NaN) and read back as NaN;
an infinite upper arrival bound stays ``Infinity`` (as Python's json writes and reads it).
"""
from __future__ import annotations

from typing import Any

import numpy as np

from .errors import InputError
from .types import Tracks

_ARRAYS = ("horizons", "forecast", "radius50", "radius90")


def tracks_record(tracks: Tracks) -> dict[str, Any]:
    """JSON-ready dict of ``tracks`` (NaN still NaN: the caller's record writer maps it to null)."""
    out: dict[str, Any] = {"id": tracks.track_id.tolist(), "position": tracks.position.tolist(),
                           "velocity": tracks.velocity.tolist()}
    if tracks.forecast is not None:
        out.update({n: getattr(tracks, n).tolist() for n in _ARRAYS})
        out["model"] = list(tracks.model)
    if tracks.arrival is not None:
        out["arrival"] = tracks.arrival.tolist()
        out["arrival_interval"] = tracks.arrival_interval.tolist()
    return out


def _floats(rec: dict, key: str, where: str) -> np.ndarray:
    """rec[key] as float64 with null → NaN; InputError naming ``where``.key if it is not numeric."""
    if key not in rec:
        raise InputError(f"{where}: missing {key}")
    try:
        return np.array(_none_to_nan(rec[key]), dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}.{key}: expected (nested) numbers or null, got {str(rec[key])[:80]}") from None


def _shaped(rec: dict, key: str, where: str, shape: tuple[int, ...]) -> np.ndarray:
    """:func:`_floats` reshaped to ``shape``; InputError naming ``where``.key when the size differs."""
    arr = _floats(rec, key, where)
    if arr.size != int(np.prod(shape)):
        raise InputError(f"{where}.{key}: expected shape {shape} (one row per track id), got {arr.shape}")
    return arr.reshape(shape)


def _none_to_nan(x):
    if x is None:
        return float("nan")
    if isinstance(x, list):
        return [_none_to_nan(v) for v in x]
    return x


def tracks_from_record(rec: dict[str, Any] | None, timestamp: float = 0.0, where: str = "tracks") -> Tracks | None:
    """The Tracks a record's ``tracks`` object describes (None for null). ``predicted`` is not
    recorded and is set to ``position``; timestamp [s] is the frame's. Shapes are checked by Tracks;
    an InputError names ``where`` and the key when one is missing or not numeric."""
    if rec is None:
        return None
    if not isinstance(rec, dict):
        raise InputError(f"{where}: expected an object with id, position, velocity, got {type(rec).__name__}")
    missing = [k for k in ("id", "position", "velocity") if k not in rec]
    if missing:
        raise InputError(f"{where}: missing {', '.join(missing)}")
    k = len(rec["id"])
    pos = _shaped(rec, "position", where, (k, 2))
    vel = _shaped(rec, "velocity", where, (k, 2))
    kw: dict[str, Any] = {}
    if "forecast" in rec:
        kw = {n: _floats(rec, n, where) for n in _ARRAYS}
        kw["model"] = tuple(rec.get("model", ()))
        if not k:  # empty lists lose their inner shape in JSON
            n_h = len(kw["horizons"])
            kw.update(forecast=np.zeros((0, n_h, 2)), radius50=np.zeros((0, n_h)), radius90=np.zeros((0, n_h)))
    if "arrival" in rec:
        kw["arrival"] = _floats(rec, "arrival", where)
        kw["arrival_interval"] = _shaped(rec, "arrival_interval", where, (k, 2))
    return Tracks(np.asarray(rec["id"], dtype=np.int64), pos, vel, pos, float(timestamp), **kw)


def track_history(records, upto: int, max_frames: int = 15) -> dict[int, np.ndarray]:
    """track id → (n, 2) [m] its recorded positions, oldest first, over the last ``max_frames``
    records with frame index ≤ ``upto`` (the current frame included); ``records``: results.jsonl
    records in any order (frames without tracks are skipped)."""
    recent = sorted((r for r in records if r["frame"] <= upto), key=lambda r: r["frame"])[-max_frames:]
    out: dict[int, list] = {}
    for r in recent:
        t = r.get("tracks")
        if not t:
            continue
        for tid, p in zip(t["id"], t["position"]):
            out.setdefault(int(tid), []).append(p)
    return {k: np.asarray(v, float).reshape(-1, 2) for k, v in out.items()}
