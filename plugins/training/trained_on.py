"""What a learned model was trained on: the radar and the RA grid, recorded in its checkpoint and
compared with every map the model is used on.

The record (checkpoint metadata key ``trained_on``)::

    {"version": 1,
     "radar": {...},                        # RadarConfig.model_dump(mode="json") of the training maps
     "range_axis": {"n": 401, "first": 0.0, "last": 99.93, "step": 0.2498},      # [m]
     "azimuth_axis": {"n": 121, "first": -1.047, "last": 1.047, "step": 0.01745},  # [rad]
     "source": "<where the record comes from>"}

New trainings write it into every checkpoint (the trainer builds it with :func:`grid_record` from a
training map). A checkpoint written before the record existed can carry it in a sidecar file
``NAME.trained_on.json`` beside ``NAME.pt`` (:func:`sidecar_path`), the record plus the
``weights_sha256`` of the checkpoint it describes, so that the record of one model is never read
for another (the shipped models' records were added this way, leaving their bytes unchanged).

:func:`grid_mismatches` lists what differs between a record and a map: carrier frequency (relative
1e-6), range and azimuth bins, spacing (relative 1e-3) and extent (first and last bin, to 1e-3 of a
bin: the field of view). Other radar fields (power, array, windows) change a map's look but not its
grid, and are not compared.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.types import RAMap

RECORD_VERSION = 1
SIDECAR_SUFFIX = ".trained_on.json"
_CARRIER_RTOL, _STEP_RTOL, _EDGE_CELLS = 1e-6, 1e-3, 1e-3


def axis_summary(axis: np.ndarray) -> dict[str, float | int]:
    """{n, first, last, step} of a 1-D ascending axis (step: the mean bin spacing; 0 for one bin)."""
    a = np.asarray(axis, dtype=np.float64)
    n = int(a.size)
    return {"n": n, "first": float(a[0]), "last": float(a[-1]),
            "step": float((a[-1] - a[0]) / (n - 1)) if n > 1 else 0.0}


def grid_record(ra_map: RAMap, source: str) -> dict[str, Any]:
    """The ``trained_on`` record (module doc) of the radar and grid of ``ra_map``, a training map."""
    return {"version": RECORD_VERSION, "radar": ra_map.radar.model_dump(mode="json"),
            "range_axis": axis_summary(ra_map.range_axis), "azimuth_axis": axis_summary(ra_map.azimuth_axis),
            "source": source}


def sidecar_path(checkpoint: str | Path) -> Path:
    """``NAME.trained_on.json`` beside the checkpoint ``NAME.pt``."""
    p = Path(checkpoint)
    return p.with_name(p.stem + SIDECAR_SUFFIX)


def read_sidecar(checkpoint: str | Path, weights_sha256: str | None) -> dict[str, Any] | None:
    """The ``trained_on`` record of the sidecar of ``checkpoint`` (None when there is none).

    InputError naming the file when it is unreadable, lacks a record, or describes other weights
    (its ``weights_sha256`` is not the checkpoint's)."""
    path = sidecar_path(checkpoint)
    if not path.is_file():
        return None
    try:
        doc = json.loads(path.read_text())
        rec, digest = doc["trained_on"], doc["weights_sha256"]
        _check_record(rec)
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise InputError(f"{path}: not a readable trained_on record (expected JSON with 'trained_on' "
                         f"and 'weights_sha256'): {type(exc).__name__}: {exc}") from None
    if digest != weights_sha256:
        raise InputError(f"{path}: describes weights {str(digest)[:12]}…, but {Path(checkpoint).name} holds "
                         f"weights {str(weights_sha256)[:12]}…; remove or regenerate the sidecar")
    return rec


def write_sidecar(checkpoint: str | Path, weights_sha256: str, record: dict[str, Any]) -> Path:
    """Write the sidecar of ``checkpoint`` (record bound to ``weights_sha256``); returns its path."""
    from xnlos_core.io import atomic_write_text

    _check_record(record)
    path = sidecar_path(checkpoint)
    atomic_write_text(path, json.dumps({"trained_on": record, "weights_sha256": weights_sha256},
                                       indent=2, sort_keys=True) + "\n")
    return path


def _check_record(rec: Any) -> None:
    if not isinstance(rec, dict) or rec.get("version") != RECORD_VERSION:
        raise ValueError(f"trained_on record version {rec.get('version') if isinstance(rec, dict) else rec!r}, "
                         f"expected {RECORD_VERSION}")
    for key in ("range_axis", "azimuth_axis"):
        ax = rec[key]
        if not all(isinstance(ax[k], int | float) for k in ("n", "first", "last", "step")):
            raise ValueError(f"trained_on.{key}: expected numbers n, first, last, step")
    float(rec["radar"]["carrier_frequency"])


def _axis_problems(name: str, unit: str, scale: float, want: dict, got: dict) -> list[str]:
    out = []
    if want["n"] != got["n"]:
        out.append(f"{want['n']} {name} bins trained, {got['n']} here")
    if not math.isclose(want["step"], got["step"], rel_tol=_STEP_RTOL):
        out.append(f"{name} spacing {want['step'] * scale:.4g} {unit} trained, {got['step'] * scale:.4g} {unit} here")
    tol = _EDGE_CELLS * max(abs(want["step"]), 1e-12)
    if abs(want["first"] - got["first"]) > tol or abs(want["last"] - got["last"]) > tol:
        out.append(f"{name} extent {want['first'] * scale:.4g}…{want['last'] * scale:.4g} {unit} trained, "
                   f"{got['first'] * scale:.4g}…{got['last'] * scale:.4g} {unit} here")
    return out


def grid_mismatches(record: dict[str, Any], ra_map: RAMap) -> list[str]:
    """What differs between a ``trained_on`` record and ``ra_map`` (module doc); [] when nothing."""
    out = []
    fc_t, fc = float(record["radar"]["carrier_frequency"]), ra_map.radar.carrier_frequency
    if not math.isclose(fc_t, fc, rel_tol=_CARRIER_RTOL):
        out.append(f"carrier {fc_t / 1e9:.4g} GHz trained, {fc / 1e9:.4g} GHz here")
    out += _axis_problems("range", "m", 1.0, record["range_axis"], axis_summary(ra_map.range_axis))
    out += _axis_problems("azimuth", "°", 180.0 / math.pi, record["azimuth_axis"], axis_summary(ra_map.azimuth_axis))
    return out


def describe_grid(carrier: float, range_axis: dict, azimuth_axis: dict) -> str:
    """e.g. '10 GHz, 401 × 121 cells (range 0…100 m, azimuth −60…60°)'."""
    d = 180.0 / math.pi
    return (f"{carrier / 1e9:.4g} GHz, {range_axis['n']} × {azimuth_axis['n']} cells (range "
            f"{range_axis['first']:.4g}…{range_axis['last']:.4g} m, azimuth {azimuth_axis['first'] * d:.4g}…"
            f"{azimuth_axis['last'] * d:.4g}°)")


def mismatch_message(what: str, record: dict[str, Any], ra_map: RAMap, problems: list[str]) -> str:
    """One sentence naming the trained and the given grid and what differs."""
    trained = describe_grid(float(record["radar"]["carrier_frequency"]), record["range_axis"],
                            record["azimuth_axis"])
    here = describe_grid(ra_map.radar.carrier_frequency, axis_summary(ra_map.range_axis),
                         axis_summary(ra_map.azimuth_axis))
    return (f"{what}: trained on {trained}, used on {here} — {'; '.join(problems)}; its outputs on these maps "
            "are not what its validation figures describe (retrain on maps of this radar)")
