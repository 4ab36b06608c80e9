"""The stage checkpoint of ``xnlos run`` (``stage_state.json``): resume without replay.

A tracker carries state from frame to frame, and so does a wall estimator that pools earlier frames'
LOS detections (:meth:`xnlos_core.pipeline.Pipeline.stateful`), so a resumed run would have to replay
every frame from 0 (:meth:`xnlos_core.pipeline.Pipeline.run`). When every such stage has a checkpoint
(:attr:`xnlos_core.interfaces.FrameState.supports_state`), the runner writes after each frame it
records, atomically (temporary file, then rename)::

    {"format": 2, "frame": k, "frames_done": n, "config_sha256": …,
     "stages": {"<kind>": {"name": "<registry name>", "state": <stage>.state()}, …}}

k: the index of the frame whose update the states follow, which is the last recorded frame; n: how
many frames results.jsonl held then. On resume the states are loaded only when k is the last recorded
frame and n the number of recorded frames (so every frame before k was fed to the stages): then no
recorded frame is recomputed. Otherwise — no file (a run made before this, a stage without a
checkpoint), a crash between a frame's results line and its state, a gap in the middle — the run
falls back to the replay, which gives the same results, only slower.

A state file that cannot be used (not JSON, another configuration's or format's, another set of
stateful stages, refused by a stage's ``load_state``) is not an error either: the replay does not
need it. It falls back too, with a :class:`xnlos_core.errors.CheckpointWarning` naming the file and
why, and every stage reset. The file is parsed as JSON only (no pickle, nothing executed), and every
field is checked before use.
"""
from __future__ import annotations

import json
import warnings
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from .errors import CheckpointWarning, InputError
from .interfaces import FrameState
from .io import atomic_write_text, read_json_object

STATE_FILE = "stage_state.json"
FORMAT = 2


def write_checkpoint(out: str | Path, stages: Mapping[str, FrameState], names: Mapping[str, str], frame: int,
                     frames_done: int, config_sha256: str) -> Path:
    """Write the states of ``stages`` (kind → stage; ``names``: kind → registry name) after frame
    ``frame`` (``frames_done`` frames recorded) to ``out/stage_state.json`` atomically; returns the path."""
    path = Path(out) / STATE_FILE
    record = {"format": FORMAT, "frame": int(frame), "frames_done": int(frames_done), "config_sha256": config_sha256,
              "stages": {kind: {"name": names[kind], "state": stage.state()} for kind, stage in stages.items()}}
    atomic_write_text(path, json.dumps(record, sort_keys=True))
    return path


def restore_checkpoint(out: str | Path, stages: Mapping[str, FrameState], names: Mapping[str, str],
                       done: Collection[int], config_sha256: str) -> bool:
    """Load ``out/stage_state.json`` into ``stages`` (kind → stage) when it belongs to the last of the
    recorded frames ``done`` (module docstring); True when loaded, False when the run must replay."""
    path = Path(out) / STATE_FILE
    if not done or not stages or not all(s.supports_state for s in stages.values()) or not path.exists():
        return False
    try:
        record = read_json_object(path, "stage state")
        _check(record, config_sha256, {kind: names[kind] for kind in stages})
    except InputError as exc:
        warnings.warn(f"{path}: not used, the frames are replayed instead: {exc}", CheckpointWarning, stacklevel=2)
        return False
    if record["frame"] != max(done) or record["frames_done"] != len(done):
        return False  # a crash between a frame's line and its state, or a gap: replay
    try:
        for kind, stage in stages.items():
            stage.load_state(record["stages"][kind]["state"])
    except InputError as exc:
        for stage in stages.values():
            stage.reset()
        warnings.warn(f"{path}: not used, the frames are replayed instead: {kind}: {exc}", CheckpointWarning,
                      stacklevel=2)
        return False
    return True


def _check(record: dict[str, Any], config_sha256: str, names: dict[str, str]) -> None:
    if record.get("format") != FORMAT:
        raise InputError(f"format = {record.get('format')!r}; expected {FORMAT}")
    for key in ("frame", "frames_done"):
        v = record.get(key)
        if not isinstance(v, int) or isinstance(v, bool) or v < 0:
            raise InputError(f"{key} = {v!r}; expected an integer ≥ 0")
    if record.get("config_sha256") != config_sha256:
        raise InputError(f"written under another configuration (config hash {str(record.get('config_sha256'))[:12]} "
                         f"≠ {config_sha256[:12]})")
    held = record.get("stages")
    if not isinstance(held, dict) or sorted(held) != sorted(names):
        got = sorted(held) if isinstance(held, dict) else held
        raise InputError(f"stages = {str(got)[:200]}; expected the states of {sorted(names)}")
    for kind, name in names.items():
        entry = held[kind]
        if not isinstance(entry, dict) or entry.get("name") != name:
            got = entry.get("name") if isinstance(entry, dict) else entry
            raise InputError(f"the state of {kind} {str(got)[:200]!r}, not {name!r}")
        if not isinstance(entry.get("state"), dict):
            raise InputError(f"stages.{kind}: no 'state' object")
