"""Read a run's results.jsonl back as typed objects: :func:`load_results` → one :class:`FrameRecord`
per frame, with Detections, WallPosterior, HiddenPoints and Tracks as the pipeline had them.

The line layout is :data:`xnlos_core.app.results_schema.RESULTS_SCHEMA`. Records of schema 1 (written
before own-radar support, no ``schema_version``) are read too: their detections and hidden points have no
per-row record, so ``detections`` and ``hidden`` are None there (the counts are in
``detection_counts``, the points in ``raw["hidden_points"]``), and a :class:`~xnlos_core.errors.LegacyRecordWarning`
says so once per file.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from xnlos_core.errors import InputError, LegacyRecordWarning
from xnlos_core.frame_record import detections_from_record, hidden_from_record, wall_from_record
from xnlos_core.io import read_keyed_jsonl
from xnlos_core.app.results_schema import validate_record
from xnlos_core.track_record import tracks_from_record
from xnlos_core.types import Detections, HiddenPoints, Tracks, WallPosterior

RESULTS_FILE = "results.jsonl"


@dataclass(frozen=True, eq=False)
class FrameRecord:
    """One frame of a run as recorded: frame index, timestamp [s], the stage outputs as core types,
    metrics (scores against ground truth, {} without), timings_s (stage → wall time [s]), notes,
    schema_version and the raw record (for keys outside this view, e.g. legacy ones).

    detections / hidden: None in schema-1 records (see the module doc); walls: [] when no wall was
    estimated; tracks: None without a tracker."""

    frame: int
    timestamp: float
    detections: Detections | None
    detection_counts: dict[str, int]
    walls: list[WallPosterior]
    hidden: HiddenPoints | None
    tracks: Tracks | None
    metrics: dict[str, Any] = field(default_factory=dict)
    timings_s: dict[str, float] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)
    schema_version: int = 1
    raw: dict[str, Any] = field(default_factory=dict, repr=False)


def frame_record(rec: dict[str, Any], validate: bool = True, where: str = "record") -> FrameRecord:
    """The FrameRecord of one parsed results.jsonl line. ``validate``: a schema-2 record is first
    checked with :func:`~xnlos_core.app.results_schema.validate_record`. InputError names ``where`` and the key."""
    version = rec.get("schema_version", 1)
    try:
        if validate and version >= 2:
            validate_record(rec)
        if "frame" not in rec:
            raise InputError("frame: missing")
        return FrameRecord(
            frame=rec["frame"], timestamp=float(rec.get("timestamp", 0.0)),
            detections=detections_from_record(rec["detection_table"]) if "detection_table" in rec else None,
            detection_counts=dict(rec.get("detections", {})),
            walls=[wall_from_record(w, f"walls[{i}]") for i, w in enumerate(rec.get("walls", []))],
            hidden=hidden_from_record(rec["hidden"]) if "hidden" in rec else None,
            tracks=tracks_from_record(rec.get("tracks"), rec.get("timestamp", 0.0)),
            metrics=rec.get("metrics") or {}, timings_s=rec.get("timings_s", {}), notes=list(rec.get("notes", [])),
            schema_version=version, raw=rec)
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None


def load_results(run_dir: str | Path, validate: bool = True) -> list[FrameRecord]:
    """The frames of a run, in frame order: ``run_dir`` is the output directory of ``xnlos run`` /
    :func:`xnlos_core.app.runner.run_to_dir` or its results.jsonl itself. Lines are read as a resume
    reads them (:func:`xnlos_core.io.read_keyed_jsonl`: a torn last line is dropped, other damage
    refused naming the line); each schema-2 record is validated unless ``validate`` is False."""
    path = Path(run_dir)
    if path.is_dir():
        path = path / RESULTS_FILE
    if not path.is_file():
        raise InputError(f"{path}: no such results file; expected the output directory of `xnlos run` "
                         f"(holding {RESULTS_FILE}) or the file itself")
    records = read_keyed_jsonl(path, "frame")
    out = [frame_record(rec, validate, where=f"{path}: frame {k}") for k, rec in records.items()]
    old = [r.frame for r in out if r.schema_version < 2]
    if old:
        warnings.warn(f"{path}: {len(old)} record(s) of schema 1 (frames {old[:5]}{' …' if len(old) > 5 else ''}): "
                      "detections and hidden are None there (not recorded per row)", LegacyRecordWarning, stacklevel=2)
    return out
