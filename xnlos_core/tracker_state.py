"""The tracker checkpoint of ``xnlos run`` (``tracker_state.json``): resume without replay (issue 31).

A tracker carries state from frame to frame, so a resumed run used to replay every frame from 0
(:meth:`xnlos_core.pipeline.Pipeline.run`). With a tracker that has a checkpoint
(:attr:`xnlos_core.interfaces.Tracker.supports_state`), the runner writes after each frame it records,
atomically (temporary file, then rename)::

    {"format": 1, "frame": k, "frames_done": n, "config_sha256": …, "tracker": "<registry name>",
     "state": Tracker.state()}

k: the index of the frame whose update the state follows, which is the last recorded frame; n: how
many frames results.jsonl held then. On resume the state is loaded only when k is the last recorded
frame and n the number of recorded frames (so every frame before k was fed to the tracker): then no
recorded frame is recomputed. Otherwise — no file (a run made before this, a tracker without a
checkpoint), a crash between a frame's results line and its state, a gap in the middle — the run
falls back to the replay, which gives the same results, only slower.

A state file that cannot be used (not JSON, another configuration's, refused by the tracker's
``load_state``) is not an error either: the replay does not need it. It falls back too, with a
:class:`xnlos_core.errors.CheckpointWarning` naming the file and why. The file is parsed as JSON only
(no pickle, nothing executed), and every field is checked before use.
"""
from __future__ import annotations

import json
import warnings
from collections.abc import Collection
from pathlib import Path
from typing import Any

from .errors import CheckpointWarning, InputError
from .interfaces import Tracker
from .io import atomic_write_text, read_json_object

STATE_FILE = "tracker_state.json"
FORMAT = 1


def write_tracker_state(out: str | Path, tracker: Tracker, frame: int, frames_done: int, config_sha256: str,
                        name: str) -> Path:
    """Write ``tracker``'s state after frame ``frame`` (``frames_done`` frames recorded) to
    ``out/tracker_state.json`` atomically; returns the path."""
    path = Path(out) / STATE_FILE
    record = {"format": FORMAT, "frame": int(frame), "frames_done": int(frames_done),
              "config_sha256": config_sha256, "tracker": name, "state": tracker.state()}
    atomic_write_text(path, json.dumps(record, sort_keys=True))
    return path


def restore_tracker_state(out: str | Path, tracker: Tracker, done: Collection[int], config_sha256: str,
                          name: str) -> bool:
    """Load ``out/tracker_state.json`` into ``tracker`` when it belongs to the last of the recorded
    frames ``done`` (module docstring); True when loaded, False when the run must replay."""
    path = Path(out) / STATE_FILE
    if not done or not tracker.supports_state or not path.exists():
        return False
    try:
        record = read_json_object(path, "tracker state")
        _check(record, config_sha256, name)
    except InputError as exc:
        warnings.warn(f"{path}: not used, the frames are replayed instead: {exc}", CheckpointWarning, stacklevel=2)
        return False
    if record["frame"] != max(done) or record["frames_done"] != len(done):
        return False  # a crash between a frame's line and its state, or a gap: replay
    try:
        tracker.load_state(record["state"])
    except InputError as exc:
        tracker.reset()
        warnings.warn(f"{path}: not used, the frames are replayed instead: {exc}", CheckpointWarning, stacklevel=2)
        return False
    return True


def _check(record: dict[str, Any], config_sha256: str, name: str) -> None:
    if record.get("format") != FORMAT:
        raise InputError(f"format = {record.get('format')!r}; expected {FORMAT}")
    for key in ("frame", "frames_done"):
        v = record.get(key)
        if not isinstance(v, int) or isinstance(v, bool) or v < 0:
            raise InputError(f"{key} = {v!r}; expected an integer ≥ 0")
    if record.get("config_sha256") != config_sha256:
        raise InputError(f"written under another configuration (config hash {str(record.get('config_sha256'))[:12]} "
                         f"≠ {config_sha256[:12]})")
    if record.get("tracker") != name:
        raise InputError(f"the state of tracker {record.get('tracker')!r}, not {name!r}")
    if not isinstance(record.get("state"), dict):
        raise InputError("no 'state' object")
