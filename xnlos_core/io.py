"""Files: atomic writes (temporary file, fsync, rename) and frames as pickle-free ``.npz``."""
from __future__ import annotations

import json
import os
import tempfile
import zipfile
import zlib
from pathlib import Path

import numpy as np

from .errors import InputError
from .radar import RadarConfig
from .types import Frame, GroundTruth, RAMap, WallSegment

FRAME_SCHEMA = 1


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` so that ``path`` holds either the old or the complete new content."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def atomic_write_text(path: str | Path, text: str) -> None:
    atomic_write_bytes(path, text.encode("utf-8"))


def append_jsonl(path: str | Path, record: dict) -> None:
    """Append one JSON line and fsync (a crash loses at most the line being written)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("a", encoding="utf-8") as fh:
        fh.write(json.dumps(record, sort_keys=True, default=json_default) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def read_jsonl(path: str | Path) -> list[dict]:
    """Records of a JSON-lines file; a torn last line (crash mid-write) is ignored."""
    out = []
    path = Path(path)
    if not path.exists():
        return out
    lines = path.read_text(encoding="utf-8").splitlines()
    for i, line in enumerate(lines):
        if not line.strip():
            continue
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            if i == len(lines) - 1:
                break
            raise InputError(f"{path}: line {i + 1} is not valid JSON") from None
    return out


def json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def save_frame(path: str | Path, frame: Frame) -> None:
    """Write a Frame (RA map, axes, radar config, ground truth) as ``.npz``, atomically."""
    import io as _io

    gt = frame.ground_truth
    arrays = {
        "schema": np.array(FRAME_SCHEMA),
        "data": frame.ra_map.data,
        "range_axis": frame.ra_map.range_axis,
        "azimuth_axis": frame.ra_map.azimuth_axis,
        "radar_json": np.array(frame.ra_map.radar.model_dump_json()),
        "timestamp": np.array(frame.timestamp),
        "index": np.array(frame.index),
        "meta_json": np.array(json.dumps(frame.meta, default=json_default)),
        "has_gt": np.array(gt is not None),
    }
    if gt is not None:
        arrays.update(
            gt_los=gt.los_points, gt_mnlos=gt.mnlos_points, gt_hidden=gt.hidden_points,
            gt_object=gt.mnlos_object, gt_names=np.array(gt.object_names, dtype=str),
            gt_walls=np.array([[w.start, w.end] for w in gt.walls]).reshape(-1, 2, 2),
            gt_wall_names=np.array([w.name for w in gt.walls], dtype=str),
        )
    buf = _io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_frame(path: str | Path) -> Frame:
    """Read a Frame written by :func:`save_frame` (no pickle is ever loaded)."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as z:
            schema = int(z["schema"])
            if schema != FRAME_SCHEMA:
                raise InputError(f"{path}: frame schema {schema}, this xnlos reads schema {FRAME_SCHEMA}")
            radar = RadarConfig.model_validate_json(str(z["radar_json"]))
            ra = RAMap(z["data"], z["range_axis"], z["azimuth_axis"], radar)
            gt = None
            if bool(z["has_gt"]):
                walls = tuple(WallSegment(s, e, str(n)) for (s, e), n in zip(z["gt_walls"], z["gt_wall_names"]))
                gt = GroundTruth(z["gt_los"], z["gt_mnlos"], z["gt_hidden"], z["gt_object"],
                                 tuple(str(n) for n in z["gt_names"]), walls)
            return Frame(ra, float(z["timestamp"]), gt, int(z["index"]), json.loads(str(z["meta_json"])))
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path}: not a readable xnlos frame file ({type(exc).__name__}: {exc})") from None
