"""Files: atomic writes (temporary file, fsync, rename) and frames as pickle-free ``.npz``."""
from __future__ import annotations

import json
import os
import stat
import tempfile
import zipfile
import zlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from .errors import InputError
from .radar import RadarConfig
from .types import Frame, GroundTruth, RAMap, WallSegment

FRAME_SCHEMA = 1


def _umask() -> int:
    """The process umask, read from /proc where it can be (Linux ≥ 4.7) so that no thread ever sees
    it changed; elsewhere set and restored at once."""
    try:
        for line in Path("/proc/self/status").read_text().splitlines():
            if line.startswith("Umask:"):
                return int(line.split()[1], 8)
    except (OSError, ValueError, IndexError):
        pass
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def _plain_open_mode(path: Path) -> int:
    """The permission bits a plain ``open(path, "w")`` would leave: an existing regular file keeps
    its own, a new file gets 0o666 & ~umask (0o644 under the usual umask 022)."""
    try:
        st = os.stat(path)
        if stat.S_ISREG(st.st_mode):
            return stat.S_IMODE(st.st_mode)
    except OSError:
        pass
    return 0o666 & ~_umask()


def atomic_write_bytes(path: str | Path, data: bytes) -> None:
    """Write ``data`` so that ``path`` holds either the old or the complete new content.

    The file gets the permissions a plain ``open()`` would give (:func:`_plain_open_mode`), not the
    0600 of the temporary file it is written through: summaries, figures, provenance records and
    manifests are meant to be read by others."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    mode = _plain_open_mode(path)
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            os.fchmod(fh.fileno(), mode)
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


def _json_type(obj) -> str:
    """JSON's name for the type of a parsed value (for messages)."""
    return {dict: "object", list: "array", str: "string", bool: "boolean", int: "number",
            float: "number", type(None): "null"}.get(type(obj), type(obj).__name__)


def read_json_object(path: str | Path, what: str = "file") -> dict:
    """The JSON object in ``path`` (e.g. provenance.json); InputError naming the file when it is not
    valid UTF-8, not valid JSON or not an object (a bare traceback would hide which file is bad)."""
    path = Path(path)
    try:
        text = path.read_bytes().decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path}: {what} is not valid UTF-8 (byte {exc.start}); expected JSON written by "
                         "xnlos") from None
    try:
        obj = json.loads(text)
    except (ValueError, RecursionError) as exc:
        raise InputError(f"{path}: {what} is not valid JSON ({exc}); expected an object written by xnlos") from None
    if not isinstance(obj, dict):
        raise InputError(f"{path}: {what} holds a JSON {_json_type(obj)}, expected an object")
    return obj


def _jsonl_lines(path: Path) -> list[tuple[int, dict]]:
    """(line number, object) of every record of an append-only JSON-lines file.

    Repaired: blank lines (skipped) and a torn last line — bytes after the last newline that are
    not a complete JSON object, what a crash in the middle of :func:`append_jsonl` leaves (dropped).
    Refused (InputError naming file and line): invalid UTF-8, invalid JSON or a value that is not
    an object on any newline-terminated line; :func:`append_jsonl` writes a line and its newline in
    one write, so a terminated line that does not parse is damage, not a crash.
    """
    if not path.exists():
        return []
    raw = path.read_bytes().split(b"\n")
    tail = raw.pop()  # b"" when the file ends with a newline
    out = []
    for i, line in enumerate([*raw, tail]):
        torn = i == len(raw)
        try:
            text = line.decode("utf-8")
        except UnicodeDecodeError as exc:
            if torn:
                break
            raise InputError(f"{path}: line {i + 1} is not valid UTF-8 (byte {exc.start} of the line); "
                             "expected one JSON object per line") from None
        if not text.strip():
            continue
        try:
            obj = json.loads(text)
        except (ValueError, RecursionError) as exc:
            if torn:
                break
            raise InputError(f"{path}: line {i + 1} is not valid JSON ({exc}); expected one JSON object "
                             "per line") from None
        if not isinstance(obj, dict):
            raise InputError(f"{path}: line {i + 1} holds a JSON {_json_type(obj)} ({text[:40]!r}), "
                             "expected an object")
        out.append((i + 1, obj))
    return out


def read_jsonl(path: str | Path) -> list[dict]:
    """Records of a JSON-lines file in file order; a torn last line (crash mid-write) is ignored,
    any other bad line is an InputError naming file and line (see :func:`_jsonl_lines`)."""
    return [obj for _, obj in _jsonl_lines(Path(path))]


def _index_ok(value) -> str | None:
    if isinstance(value, int) and not isinstance(value, bool) and value >= 0:
        return None
    return "an integer ≥ 0"


def read_keyed_jsonl(path: str | Path, key: str, *, check: Callable[[Any], str | None] = _index_ok,
                     supersede: bool = False) -> dict[Any, dict]:
    """Records of an append-only JSON-lines log keyed by ``record[key]`` (frame index, point id,
    shard name), sorted by key: what a resume needs to know which items are done.

    Lines are read as :func:`read_jsonl` does (torn last line dropped, other bad lines refused).
    ``check(value)`` returns None for an acceptable key or what was expected (default: an integer
    ≥ 0); a missing or unacceptable key is an InputError naming file and line. A repeated key whose
    record is identical to the first is dropped (a repeated append); one with another record is
    refused naming both lines — which one holds the result is unknowable — unless ``supersede``
    (a log whose later line replaces an earlier one, e.g. a sweep point rerun after its config
    changed). Callers rewrite the log from the returned records, so repairs are made durable.
    """
    path = Path(path)
    out: dict[Any, dict] = {}
    where: dict[Any, int] = {}
    for line, rec in _jsonl_lines(path):
        if key not in rec:
            raise InputError(f"{path}: line {line} has no {key!r} field; expected a record with {key!r}")
        value = rec[key]
        expected = check(value)
        if expected is not None:
            raise InputError(f"{path}: line {line}: {key} = {value!r}; expected {expected}")
        if value in out and out[value] != rec and not supersede:
            raise InputError(f"{path}: lines {where[value]} and {line} hold different records for {key} "
                             f"{value!r}; remove the wrong line or start afresh (--overwrite)")
        if value not in out or out[value] != rec:
            out[value], where[value] = rec, line
    return {k: out[k] for k in sorted(out)}


def write_jsonl(path: str | Path, records) -> None:
    """Replace ``path`` atomically with one JSON line per record (the same bytes as
    :func:`append_jsonl` writes line by line)."""
    atomic_write_text(path, "".join(json.dumps(r, sort_keys=True, default=json_default) + "\n" for r in records))


def json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    return str(o)


def finite_json(obj):
    """``obj`` with every non-finite float (NaN, ±inf) replaced by None, recursively through dicts,
    lists and tuples, so that ``json.dumps(..., allow_nan=False)`` writes strict JSON (RFC 8259 has
    no NaN or Infinity; Python's and JavaScript's strict parsers refuse them). None reads as "no
    finite value", e.g. a Chamfer distance with an empty side."""
    if isinstance(obj, np.ndarray | np.generic):
        obj = obj.tolist()
    if isinstance(obj, float):
        return obj if np.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: finite_json(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [finite_json(v) for v in obj]
    return obj


def strict_json_text(obj, **kwargs) -> str:
    """``json.dumps`` of :func:`finite_json` (``obj``) with ``allow_nan=False`` (and ``kwargs``; numpy
    scalars and arrays as numbers and lists, any other type JSON lacks as its str)."""
    return json.dumps(finite_json(obj), default=str, allow_nan=False, **kwargs)


# GroundTruth fields a frame file holds only when the truth records them (gt_<name>)
GT_OPTIONAL = ("hidden_velocity", "mnlos_velocity", "los_object", "los_radial_velocity")


def save_frame(path: str | Path, frame: Frame) -> None:
    """Write a Frame (RA map, axes, its velocity maps if any, radar config, ground truth) as ``.npz``, atomically."""
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
    if frame.ra_map.velocity is not None:  # Doppler maps only: other frames keep their bytes
        arrays.update(ra_velocity=frame.ra_map.velocity, ra_velocity_std=frame.ra_map.velocity_std)
    if gt is not None:
        arrays.update(
            gt_los=gt.los_points, gt_mnlos=gt.mnlos_points, gt_hidden=gt.hidden_points,
            gt_object=gt.mnlos_object, gt_names=np.array(gt.object_names, dtype=str),
            gt_walls=np.array([[w.start, w.end] for w in gt.walls]).reshape(-1, 2, 2),
            gt_wall_names=np.array([w.name for w in gt.walls], dtype=str),
            gt_los_snr_db=gt.los_snr_db, gt_mnlos_snr_db=gt.mnlos_snr_db,
        )
        for name in GT_OPTIONAL:  # only what the truth records: a still frame keeps its members
            if getattr(gt, name) is not None:
                arrays[f"gt_{name}"] = getattr(gt, name)
    buf = _io.BytesIO()
    np.savez_compressed(buf, **arrays)
    atomic_write_bytes(path, buf.getvalue())


def load_frame(path: str | Path) -> Frame:
    """Read a Frame written by :func:`save_frame` (no pickle is ever loaded). The file is read as
    :mod:`xnlos_core.datafiles` reads data: a regular file only (a FIFO or device is refused before a
    byte is read), each array's declared size checked before it is decompressed."""
    from .datafiles import npz_archive

    path = Path(path)
    try:
        with npz_archive(path, what=str(path)) as z:
            schema = int(z["schema"])
            if schema != FRAME_SCHEMA:
                raise InputError(f"{path}: frame schema {schema}, this xnlos reads schema {FRAME_SCHEMA}")
            radar = RadarConfig.model_validate_json(str(z["radar_json"]))
            vel = (z["ra_velocity"], z["ra_velocity_std"]) if "ra_velocity" in z.files else (None, None)
            ra = RAMap(z["data"], z["range_axis"], z["azimuth_axis"], radar, *vel)
            gt = None
            if bool(z["has_gt"]):
                walls = tuple(WallSegment(s, e, str(n)) for (s, e), n in zip(z["gt_walls"], z["gt_wall_names"]))
                snr = [z[k] if k in z.files else None for k in ("gt_los_snr_db", "gt_mnlos_snr_db")]  # older files: none
                gt = GroundTruth(z["gt_los"], z["gt_mnlos"], z["gt_hidden"], z["gt_object"],
                                 tuple(str(n) for n in z["gt_names"]), walls, *snr,
                                 **{k: z[f"gt_{k}"] for k in GT_OPTIONAL if f"gt_{k}" in z.files})
            return Frame(ra, float(z["timestamp"]), gt, int(z["index"]), json.loads(str(z["meta_json"])))
    except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile, zlib.error) as exc:
        if isinstance(exc, InputError):
            raise
        raise InputError(f"{path}: not a readable xnlos frame file ({type(exc).__name__}: {exc})") from None
