"""The schema of one results.jsonl line (schema_version 2) and :func:`validate_record`.

:data:`RESULTS_SCHEMA` is a JSON Schema (draft 2020-12, the keyword subset of
:mod:`xnlos_core.app.json_schema`); ``json.dumps(RESULTS_SCHEMA)`` is the file form for other tools.
It fixes each key's type, bounds and inner shape; :func:`validate_record` adds what JSON Schema
cannot say: lengths that must agree across keys (K detections, P wall parameters, M hidden points).
Units: metres, radians, seconds; NaN is written as null, ±inf as ±Infinity (Python's json).
Keys of schema 1 (records without ``schema_version``) are all still written; ``detection_doppler`` and
``hidden_velocity`` repeat columns of ``detection_table`` and ``hidden`` and are kept for
readers of that layout.
"""
from __future__ import annotations

import math
from typing import Any

from xnlos_core.errors import InputError, SchemaViolation
from xnlos_core.frame_record import DETECTION_COLUMNS, SCHEMA_VERSION
from xnlos_core.app.json_schema import check
from xnlos_core.track_record import tracks_from_record
from xnlos_core.types import CLASS_NAMES

NUMBER = {"type": "number"}
NUMBER_OR_NULL = {"type": ["number", "null"], "description": "null where the value is NaN"}
NON_NEGATIVE = {"type": "number", "minimum": 0}


def _list(item: dict, description: str | None = None) -> dict:
    out = {"type": "array", "items": item}
    return out if description is None else {**out, "description": description}


def _vec(n: int, item: dict = NUMBER, description: str | None = None) -> dict:
    return {**_list(item, description), "minItems": n, "maxItems": n}


POINT = _vec(2, description="(x, y) [m], ego frame: x boresight, y left")
MAT2 = _vec(2, _vec(2))
INDEX = {"type": "integer", "minimum": 0}


def _object(properties: dict, required=None, description: str = "") -> dict:
    return {"type": "object", "description": description, "properties": properties,
            "required": list(properties if required is None else required), "additionalProperties": False}


DETECTION_TABLE = _object({
    "range": _list(NON_NEGATIVE, "range r [m] of each detection (K,)"),
    "azimuth": _list({"type": "number", "minimum": -math.pi, "maximum": math.pi}, "azimuth θ = atan2(y, x) [rad] (K,)"),
    "label": _list({"type": "integer", "enum": [0, 1, 2]}, "0 LOS, 1 mNLOS, 2 unclassified (K,)"),
    "class": _list({"type": "string", "enum": list(CLASS_NAMES)}, "name of each label (K,)"),
    "confidence": _list({"type": "number", "minimum": 0, "maximum": 1}, "detector confidence (K,)"),
    "range_std": _list(NON_NEGATIVE, "1-σ of r [m]; cov(r, θ) = diag(range_std², azimuth_std²) (K,)"),
    "azimuth_std": _list(NON_NEGATIVE, "1-σ of θ [rad] (K,)"),
    "velocity": _list(NUMBER, "radial velocity [m/s], positive receding; only with Doppler (K,)"),
    "velocity_var": _list(NON_NEGATIVE, "its variance [m²/s²]; only with Doppler (K,)"),
}, required=[c for c in DETECTION_COLUMNS], description="every detection, one column per field")

WALL = _object({
    "model": {"type": "string", "description": "'line' (phi, b) or 'arc' (phi, b, kappa), or a plugin's model"},
    "param_names": _list({"type": "string"}, "names of the P parameters, the order of mean and cov"),
    "mean": _list(NUMBER, "parameter estimate (P,): phi [rad] normal angle, b [m] offset ≥ 0, kappa [1/m]"),
    "params": {"type": "object", "additionalProperties": NUMBER, "description": "name → value, as mean"},
    "cov": _list(_list(NUMBER), "covariance (P, P) in the order of param_names"),
    "n_points": INDEX,
    "extent": {"type": ["array", "null"], "items": POINT, "minItems": 2, "maxItems": 2,
               "description": "end points (2, 2) [m] of the supported segment or arc; null if unknown"},
    "anchor": {**POINT, "type": ["array", "null"], "description": "an arc's anchor point (2,) [m]; null otherwise"},
}, description="one relay-wall posterior, nᵀx + b = 0 with n = (cos phi, sin phi)")

HIDDEN = _object({
    "mean": _list(POINT, "hidden points o (M, 2) [m]"),
    "cov": _list(MAT2, "their covariances (M, 2, 2) [m²]"),
    "source_index": _list(INDEX, "row of detection_table each was mirrored from (M,)"),
    "wall_index": _list(INDEX, "entry of walls used for the mirror (M,)"),
    "velocity": _list(_vec(2), "hidden velocity (M, 2) [m/s]; only with Doppler"),
    "velocity_cov": _list(MAT2, "its covariance (M, 2, 2) [m²/s²]; only with Doppler"),
    "view": _list(_vec(2), "unit direction (M, 2) of the mirrored line of sight at each point, from its "
                           "bounce point on the wall towards it; where the reconstructor gives it"),
    "gated": _list(INDEX, "rows of detection_table refused as ghosts by the visibility gate (their mirror image "
                          "lies where the relay wall cannot show it); only when some were"),
}, required=["mean", "cov", "source_index", "wall_index"], description="reconstructed hidden points (Eq. 7)")

TRACKS = {**_object({
    "id": _list({"type": "integer"}, "track ids (T,)"),
    "position": _list(POINT, "(T, 2) [m]"),
    "velocity": _list(_vec(2), "(T, 2) [m/s]"),
    "horizons": _list(NON_NEGATIVE, "forecast horizons (H,) [s]"),
    "forecast": _list(_list(POINT), "(T, H, 2) [m]"),
    "radius50": _list(_list(NUMBER_OR_NULL), "50 % disc radii (T, H) [m]"),
    "radius90": _list(_list(NUMBER_OR_NULL), "90 % disc radii (T, H) [m]"),
    "model": _list({"type": "string"}, "motion model of each track (T,)"),
    "arrival": _list(NUMBER_OR_NULL, "time of arrival in the region (T,) [s]"),
    "arrival_interval": _list(_vec(2, NUMBER_OR_NULL), "5–95 % interval (T, 2) [s]"),
}, required=["id", "position", "velocity"], description="tracker output (xnlos_core.track_record); null without tracker"),
    "type": ["object", "null"]}

RESULTS_SCHEMA: dict[str, Any] = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "title": "xnlos results.jsonl record (one frame)",
    **_object({
        "schema_version": {"const": SCHEMA_VERSION, "description": "layout version (absent: 1)"},
        "frame": INDEX,
        "timestamp": {"type": "number", "description": "[s]"},
        "detections": _object({k: INDEX for k in CLASS_NAMES}, description="number of detections per class"),
        "detection_table": DETECTION_TABLE,
        "walls": _list(WALL, "the frame's relay walls"),
        "hidden_points": _list(POINT, "= hidden.mean (schema 1 key)"),
        "hidden": HIDDEN,
        "n_gated": {"type": "integer", "minimum": 0, "description": "mNLOS detections gated as ghosts (= length "
                                                                    "of hidden.gated)"},
        "tracks": TRACKS,
        "metrics": {"type": "object", "description": "scores against ground truth (empty without it)"},
        "timings_s": {"type": "object", "additionalProperties": NUMBER, "description": "stage → wall time [s]"},
        "notes": _list({"type": "string"}, "why a stage produced nothing"),
        "detection_doppler": _object({
            "range": _list(NUMBER), "azimuth": _list(NUMBER), "label": _list({"type": "integer"}),
            "velocity": _list(NUMBER), "velocity_var": _list(NUMBER)},
            description="the first Doppler layout, repeats detection_table; only with Doppler"),
        "hidden_velocity": _object({
            "velocity": _list(_vec(2)), "velocity_cov": _list(MAT2), "source_index": _list(INDEX)},
            description="the first Doppler layout, repeats hidden; only with Doppler"),
    }, required=["schema_version", "frame", "timestamp", "detections", "detection_table", "walls",
                 "hidden_points", "hidden", "tracks", "metrics", "timings_s", "notes"]),
}


def validate_record(record: Any) -> None:
    """Check one results.jsonl record (a parsed JSON object) against :data:`RESULTS_SCHEMA` and the
    cross-key lengths; raise :class:`~xnlos_core.errors.SchemaViolation` (an InputError) whose
    message and ``path`` name the offending key, e.g. ``walls[0].cov[1]: expected 2 items, got 3``."""
    check(record, RESULTS_SCHEMA)
    k = _same_length(record["detection_table"], "detection_table")
    labels = record["detection_table"]["label"]
    for i, (lab, name) in enumerate(zip(labels, record["detection_table"]["class"])):
        if CLASS_NAMES[lab] != name:
            raise SchemaViolation(f"detection_table.class[{i}]", f"expected {CLASS_NAMES[lab]!r} (label {lab}), got {name!r}")
    for j, name in enumerate(CLASS_NAMES):
        if record["detections"][name] != labels.count(j):
            raise SchemaViolation(f"detections.{name}", f"expected {labels.count(j)} (rows of detection_table "
                                  f"with label {j}), got {record['detections'][name]}")
    for i, w in enumerate(record["walls"]):
        _check_wall(w, f"walls[{i}]")
    m = _same_length({key: v for key, v in record["hidden"].items() if key != "gated"}, "hidden")
    _below(record["hidden"].get("gated", []), k, "hidden.gated", "rows of detection_table")
    if "n_gated" in record and record["n_gated"] != len(record["hidden"].get("gated", [])):
        raise SchemaViolation("n_gated", f"expected {len(record['hidden'].get('gated', []))} (the length of "
                              f"hidden.gated), got {record['n_gated']}")
    if record["hidden_points"] != record["hidden"]["mean"]:
        raise SchemaViolation("hidden_points", "expected the same points as hidden.mean")
    _below(record["hidden"]["source_index"], k, "hidden.source_index", "rows of detection_table")
    _below(record["hidden"]["wall_index"], len(record["walls"]), "hidden.wall_index", "walls")
    for key, n in (("detection_doppler", k), ("hidden_velocity", m)):
        if key in record and _same_length(record[key], key) != n:
            raise SchemaViolation(key, f"expected columns of length {n}")
    try:
        tracks_from_record(record["tracks"], record["timestamp"])
    except InputError as exc:
        raise SchemaViolation("tracks", str(exc)) from None


def _same_length(columns: dict, where: str) -> int:
    lengths = {key: len(v) for key, v in columns.items()}
    n = next(iter(lengths.values()), 0)
    for key, length in lengths.items():
        if length != n:
            raise SchemaViolation(f"{where}.{key}", f"expected {n} rows (as {next(iter(lengths))}), got {length}")
    return n


def _check_wall(w: dict, where: str) -> None:
    p = len(w["param_names"])
    if len(w["mean"]) != p:
        raise SchemaViolation(f"{where}.mean", f"expected {p} values (one per param_names), got {len(w['mean'])}")
    if len(w["cov"]) != p or any(len(row) != p for row in w["cov"]):
        raise SchemaViolation(f"{where}.cov", f"expected a {p}×{p} matrix (param_names {w['param_names']})")
    if w["params"] != dict(zip(w["param_names"], w["mean"])):  # a dict: key order is not kept (sort_keys)
        raise SchemaViolation(f"{where}.params", f"expected {dict(zip(w['param_names'], w['mean']))}")


def _below(indices: list[int], n: int, where: str, what: str) -> None:
    for i, v in enumerate(indices):
        if v >= n:
            raise SchemaViolation(f"{where}[{i}]", f"expected an index < {n} (the {what}), got {v}")
