"""What a learned model was trained on: the radar and the RA grid, recorded in its checkpoint and
compared with every map the model is used on.

The record (checkpoint metadata key ``trained_on``)::

    {"version": 1,
     "radar": {...},                        # RadarConfig.model_dump(mode="json") of the training maps
     "range_axis": {"n": 401, "first": 0.0, "last": 99.93, "step": 0.2498},      # [m]
     "azimuth_axis": {"n": 121, "first": -1.047, "last": 1.047, "step": 0.01745},  # [rad]
     "virtual_array": [[y, z], …],          # the channels' (y, z) [wavelengths] (antenna.virtual_layout)
     "source": "<where the record comes from>"}

New trainings write it into every checkpoint (the trainer builds it with :func:`grid_record` from a
training map). A checkpoint written before the record existed can carry it in a sidecar file
``NAME.trained_on.json`` beside ``NAME.pt`` (:func:`sidecar_path`), the record plus the
``weights_sha256`` of the checkpoint it describes, so that the record of one model is never read
for another (the shipped models' records were added this way, leaving their bytes unchanged).

:func:`grid_mismatches` lists what differs between a record and a map: carrier frequency (relative
1e-6), range and azimuth bins, spacing (relative 1e-3) and extent (first and last bin, to 1e-3 of a
bin: the field of view). :func:`radar_mismatches` lists what differs between a record and a radar
before any map is made: those, the sweep bandwidth (relative 1e-6) and the virtual array — the
channels' (y, z) positions in wavelengths (:func:`xnlos_core.signal.antenna.virtual_layout`), compared
as a set after centring y (a shift of the whole array or another channel order does not change a map;
1e-6 λ). A record without ``virtual_array`` (the shipped models' sidecars, written before it existed)
gives it from its ``radar``, which fixes the layout. :func:`map_mismatches` is both on a map and its
radar. Other radar fields (power, noise, windows) change a map's look but not what it shows where, and
are not compared.
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.errors import InputError
from xnlos_core.radar import RadarConfig
from xnlos_core.signal.antenna import virtual_layout
from xnlos_core.types import RAMap

RECORD_VERSION = 1
SIDECAR_SUFFIX = ".trained_on.json"
_CARRIER_RTOL, _STEP_RTOL, _EDGE_CELLS = 1e-6, 1e-3, 1e-3
_BANDWIDTH_RTOL, _ARRAY_ATOL = 1e-6, 1e-6  # relative; [wavelengths]


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
            "virtual_array": virtual_layout(ra_map.radar).tolist(), "source": source}


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


def recorded_array(record: dict[str, Any]) -> np.ndarray:
    """(K, 2) channel (y, z) [wavelengths] of a record: its ``virtual_array``, else its radar's layout."""
    if "virtual_array" in record:
        return np.asarray(record["virtual_array"], dtype=np.float64).reshape(-1, 2)
    return virtual_layout(RadarConfig.model_validate(record["radar"]))


def _canonical(positions: np.ndarray) -> np.ndarray:
    """Positions (K, 2) with y centred on its mean, rows sorted by (y, z) as rounded to 1e-7 λ (so that
    a last-bit difference cannot reorder two channels at one y)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    p = p - np.array([p[:, 0].mean(), 0.0])
    key = np.round(p / 1e-7)
    return p[np.lexsort((key[:, 1], key[:, 0]))]


def describe_array(positions: np.ndarray) -> str:
    """e.g. '32 channels, y 0…15.5 λ, z 0 λ' (y span after shifting the first element to 0)."""
    p = np.asarray(positions, dtype=np.float64).reshape(-1, 2)
    y, z = p[:, 0] - p[:, 0].min(), p[:, 1]
    zs = f"{z.min():.4g} λ" if np.ptp(z) <= _ARRAY_ATOL else f"{z.min():.4g}…{z.max():.4g} λ"
    return f"{len(p)} channels, y 0…{y.max():.4g} λ, z {zs}"


def array_mismatch(record: dict[str, Any], radar: RadarConfig) -> str | None:
    """'virtual array …' naming both arrays when the record's channels are not ``radar``'s (module
    doc), else None."""
    want, got = recorded_array(record), virtual_layout(radar)
    if want.shape == got.shape and np.allclose(_canonical(want), _canonical(got), rtol=0.0, atol=_ARRAY_ATOL):
        return None
    return f"virtual array {describe_array(want)} trained, {describe_array(got)} here"


def radar_mismatches(record: dict[str, Any], radar: RadarConfig) -> list[str]:
    """What differs between a ``trained_on`` record and the maps ``radar`` makes (module doc): carrier,
    bandwidth, virtual array, range and azimuth grid; [] when nothing."""
    out = []
    fc_t, fc = float(record["radar"]["carrier_frequency"]), radar.carrier_frequency
    if not math.isclose(fc_t, fc, rel_tol=_CARRIER_RTOL):
        out.append(f"carrier {fc_t / 1e9:.4g} GHz trained, {fc / 1e9:.4g} GHz here")
    b_t, b = float(record["radar"]["bandwidth"]), radar.bandwidth
    if not math.isclose(b_t, b, rel_tol=_BANDWIDTH_RTOL):
        out.append(f"bandwidth {b_t / 1e6:.4g} MHz trained, {b / 1e6:.4g} MHz here")
    arr = array_mismatch(record, radar)
    if arr:
        out.append(arr)
    out += _axis_problems("range", "m", 1.0, record["range_axis"], axis_summary(radar.range_axis))
    out += _axis_problems("azimuth", "°", 180.0 / math.pi, record["azimuth_axis"], axis_summary(radar.azimuth_axis))
    return out


def map_mismatches(record: dict[str, Any], ra_map: RAMap) -> list[str]:
    """:func:`grid_mismatches` of ``ra_map`` plus its radar's bandwidth and virtual array (module doc)."""
    out = grid_mismatches(record, ra_map)
    b_t, b = float(record["radar"]["bandwidth"]), ra_map.radar.bandwidth
    if not math.isclose(b_t, b, rel_tol=_BANDWIDTH_RTOL):
        out.insert(1 if out and out[0].startswith("carrier") else 0,
                   f"bandwidth {b_t / 1e6:.4g} MHz trained, {b / 1e6:.4g} MHz here")
    arr = array_mismatch(record, ra_map.radar)
    return out + [arr] if arr else out


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
