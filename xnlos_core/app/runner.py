"""``xnlos run``: a pipeline over its frames into an output directory, resumable after a crash.

Writes ``provenance.json`` (once), ``results.jsonl`` (one fsync'd line per frame, so a killed
run resumes after the last complete frame), ``summary.md`` and ``frame_NNNN.png`` figures, and
with ``run.animation`` (:meth:`xnlos_core.config.RunConfig.wants_animation`) ``sequence.gif``
(:mod:`xnlos_core.app.plot.animation`): each frame's snapshot ``animation/frame_NNNN.npz`` is written
before its line of results.jsonl, and the GIF at the end from both, atomically; a recorded frame
without a snapshot (the run was made with the animation off) is recomputed for it.

A resume keys on the frame index, not on the number of lines: it computes exactly the frames
whose index is not recorded (a lost line in the middle included; frame k's random draws come
from child k of the seed, so it is the frame an uninterrupted run computes) and leaves
``results.jsonl`` holding each index once, in order. A torn last line and a repeated identical
line are repaired; a line that is not a JSON object, bytes that are not UTF-8, a frame index out
of range or two different records of one frame are refused with an InputError naming the line.

When the stages that carry state from frame to frame (a tracker, a wall estimator with a history)
all have a checkpoint (:attr:`xnlos_core.interfaces.FrameState.supports_state`), their states are
written after each recorded frame to ``stage_state.json`` (:mod:`xnlos_core.checkpoint`) and a resume
restores them instead of replaying the recorded frames; otherwise (no checkpoint, a gap, an unusable
file) every frame from 0 is replayed. A finished run runs no stage,
and rewrites its summary, figures and GIF only when they are not those of this config and these
results (``outputs.json``, :mod:`xnlos_core.app.run_outputs`).
"""
from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.app.plot.animation import SNAPSHOT_DIR, snapshot_path, write_sequence_gif
from xnlos_core.config import PipelineConfig
from xnlos_core.app.plot.figures import split_outlines
from xnlos_core.app.plot.frame_snapshot import FrameSnapshot
from xnlos_core.io import (append_jsonl, atomic_write_text, json_default, read_keyed_jsonl, strict_json_text,
                          write_jsonl)
from xnlos_core.pipeline import Pipeline
from xnlos_core.app.run_outputs import STAMP, outputs_current, outputs_key, write_outputs_stamp
from xnlos_core.rundir import claim, write_record
from xnlos_core.track_record import track_history
from xnlos_core.checkpoint import STATE_FILE, restore_checkpoint, write_checkpoint

GIF = "sequence.gif"


def run_to_dir(config: PipelineConfig, out: str | Path, *, source: str = "<config>", progress: bool = True,
               overwrite: bool = False, registry=None) -> dict[str, Any]:
    """Run ``config`` writing into ``out``; returns the summary dict (also in summary.md)."""
    out = Path(out)
    pipe = Pipeline(config, registry=registry, source=source)
    prov = pipe.provenance()
    res_path = out / "results.jsonl"
    n = config.run.frames
    done: dict[int, dict] = {}
    animate = config.run.wants_animation("tracker" in pipe.stages)
    # run_sha256 (frames left out: more frames extend a run) decides; config_sha256 for older run directories
    old = claim(out, "provenance.json", {"run_sha256": prov["run_sha256"], "config_sha256": prov["config_sha256"]},
                overwrite=overwrite,
                what="results", clear=[res_path.name, GIF, f"{SNAPSHOT_DIR}/frame_*.npz", "frame_*.png", STATE_FILE, STAMP],
                state=prov["state_sha256"])
    if old is not None:
        done = read_results(res_path, n if "forward_model" in pipe.stages else None)
        # Make the repairs durable (torn last line, repeated lines dropped) before appending.
        write_jsonl(res_path, done.values())
        resumed = old.get("resumed", 0)
        prov = {**old, "config_sha256": prov["config_sha256"], "run_sha256": prov["run_sha256"],  # frames may grow
                "resumed": (resumed if isinstance(resumed, int) and not isinstance(resumed, bool) else 0) + 1}
    write_record(out, "provenance.json", prov)
    # As a resume reads it back (keys sorted, JSON types), so that a fresh run and a rerun of it render
    # the same summary (the plugin and version lists in key order) and the rerun need not rewrite it.
    prov = json.loads(json.dumps(prov, sort_keys=True, default=str))

    records = dict(done)
    bar = _progress(total=n, initial=len(done), enabled=progress, desc=f"run {config.name}")
    # Figures drawn as frames come (no result is held): those ``run.figures`` wants among frames
    # 0 … n−1 (with a simulated source the last one too: frames come in order, so the records before
    # it are complete); one still missing at the end is recomputed for its figure.
    simulated = "forward_model" in pipe.stages
    early = set(config.run.figure_frames(range(n))) if simulated or config.run.figures != "last" else set()
    # Stages that carry state (a tracker, a wall estimator with a history), all with a checkpoint:
    # restored after the last recorded frame, nothing is replayed (xnlos_core.checkpoint); otherwise
    # (or with an unusable checkpoint) Pipeline.run replays from frame 0.
    stateful = pipe.stateful()
    names = {kind: config.stages()[kind].name for kind in stateful}
    checkpoint = bool(stateful) and all(stage.supports_state for stage in stateful.values())
    restored = checkpoint and restore_checkpoint(out, stateful, names, done, prov["run_sha256"])
    # Only the frames not recorded, by index: a gap in the middle (a lost line) is recomputed too.
    for res in pipe.run(skip=done, restored=restored):
        if animate:  # before the record: a recorded frame always has its snapshot
            FrameSnapshot.from_result(res).save(snapshot_path(out, res.frame.index))
        rec = json.loads(json.dumps(res.record(), default=json_default))
        append_jsonl(res_path, rec)
        records[rec["frame"]] = rec
        if checkpoint and rec["frame"] == max(records):  # the stages have seen every recorded frame
            write_checkpoint(out, stateful, names, rec["frame"], len(records), prov["run_sha256"])
        if res.frame.index in early:
            plot_result(pipe, res, out, list(records.values()))
        bar.update(1)
    bar.close()
    ordered = [records[k] for k in sorted(records)]
    if list(records) != sorted(records):  # a gap was filled after later frames: store in frame order
        write_jsonl(res_path, ordered)
    records = ordered
    wanted = config.run.figure_frames(r["frame"] for r in records)
    figures = [figure_path(out, k) for k in wanted]
    summary = summarise(records)
    summary["figure"] = figures[-1].name if figures else None
    if len(figures) > 1:
        summary["figures"] = [p.name for p in figures]
    if animate:
        summary["animation"] = GIF
    summary["state_sha256"] = prov.get("state_sha256", {})
    texts = {"summary.md": render_summary(summary, prov, config),
             "summary.json": strict_json_text(summary, indent=2, sort_keys=True)}  # null: no finite value
    # A rerun of a finished run whose summary, figures and GIF on disk are those of this config and
    # these results (xnlos_core.app.run_outputs) writes none of them again.
    names = [*texts, *(p.name for p in figures), *([GIF] if animate else [])]
    key = outputs_key(config, prov, res_path, texts.values())
    if outputs_current(out, key, names):
        return summary
    _write_figures(pipe, out, records, wanted)
    if animate:
        _write_animation(pipe, out, records, progress)
    for name, text in texts.items():
        atomic_write_text(out / name, text)
    write_outputs_stamp(out, key, names)
    return summary


def figure_path(out: str | Path, index: int) -> Path:
    """Where ``xnlos run`` writes frame ``index``'s figure under its output directory ``out``."""
    return Path(out) / f"frame_{index:04d}.png"


def plot_result(pipe: Pipeline, result, out: Path, records: list[dict]) -> Path:
    """Write frame ``result``'s figure (:func:`xnlos_core.app.plot.figures.plot_frame`) with its tracks'
    history from ``records``, the tracker's region and the hidden objects' outlines."""
    from xnlos_core.app.plot.figures import plot_frame

    k = result.frame.index
    return plot_frame(result, figure_path(out, k), title=pipe.config.name, history=track_history(records, k),
                      region=tracker_region(pipe.config), unobservable=unobservable_outlines(pipe, result),
                      objects=object_outlines(pipe, result))


def _write_figures(pipe: Pipeline, out: Path, records: list[dict], wanted) -> None:
    """Draw the figures of frames ``wanted`` (what ``run.figures`` asks for among the recorded
    frames) that are not on disk yet (a resumed run, a finished one whose ``figures`` was changed),
    recomputing those frames."""
    missing = {k for k in wanted if not figure_path(out, k).exists()}
    if missing:
        for res in pipe.run(skip={r["frame"] for r in records} - missing):
            if res.frame.index in missing:
                plot_result(pipe, res, out, records)


def _scene_outlines(pipe: Pipeline, result) -> dict[str, np.ndarray]:
    """Object name → bird's-eye outline (K, 2) [m] (``ObjectSpec.footprint``) at the frame's time of
    every object of the run's scene; empty without a simulated scene."""
    if pipe.scene is None:
        return {}
    return {o.name: o.footprint(result.frame.timestamp) for o in pipe.scene.objects}


def object_outlines(pipe: Pipeline, result) -> dict[str, np.ndarray]:
    """Object name → bird's-eye outline (K, 2) [m] (``ObjectSpec.footprint``) at the frame's time of
    each scene object that has a mirror path in ``result`` (or whose paths were not counted): the
    true outline the figure draws and zooms on (:func:`xnlos_core.app.plot.figures.split_outlines`). Empty
    without a simulated scene."""
    return split_outlines(_scene_outlines(pipe, result), result.metrics)[0]


def unobservable_outlines(pipe: Pipeline, result) -> dict[str, np.ndarray]:
    """Object name → bird's-eye outline (K, 2) [m] at the frame's time of each scene object that
    has no mirror path in ``result`` (``metrics.mirror_paths`` 0) and is not in line of sight either
    (``metrics.los_points`` 0 or not recorded): what the figure draws so that an object nothing
    could reconstruct does not vanish. Empty without a simulated scene."""
    return split_outlines(_scene_outlines(pipe, result), result.metrics)[1]


def tracker_region(config: PipelineConfig):
    """The configured tracker's arrival region (its ``region`` parameter, a polygon [[x, y], …] [m])
    or None."""
    region = config.tracker.params.get("region") if config.tracker is not None else None
    return None if region is None else np.asarray(region, float).reshape(-1, 2)


def _write_animation(pipe: Pipeline, out: Path, records: list[dict], progress: bool) -> Path:
    """sequence.gif from ``records`` and their snapshots; first the snapshots a recorded frame
    lacks (run before with the animation off) are made by recomputing those frames."""
    missing = {r["frame"] for r in records if not snapshot_path(out, r["frame"]).exists()}
    if missing:
        bar = _progress(total=len(missing), initial=0, enabled=progress, desc="animation snapshots")
        for res in pipe.run(skip={r["frame"] for r in records} - missing):
            FrameSnapshot.from_result(res).save(snapshot_path(out, res.frame.index))
            bar.update(1)
        bar.close()
    return write_sequence_gif(out / GIF, records, out / SNAPSHOT_DIR, region=tracker_region(pipe.config),
                              title=pipe.config.name, progress=progress)


def read_results(path: str | Path, n: int | None = None) -> dict[int, dict]:
    """frame index → record of a results.jsonl (see :func:`xnlos_core.io.read_keyed_jsonl` for what
    is repaired and what refused); ``n``: the run's frame count when indices must be 0 … n−1 (a
    simulated source; a recorded one keeps its frames' own indices)."""
    if n is None:
        return read_keyed_jsonl(path, "frame")

    def check(v):
        ok = isinstance(v, int) and not isinstance(v, bool) and 0 <= v < n
        return None if ok else (f"a frame index in 0 … {n - 1} (run.frames = {n}; a run that holds more frames is "
                                f"used by asking for at least as many, and extended by asking for more)")

    return read_keyed_jsonl(path, "frame", check=check)


def _progress(total, initial, enabled, desc):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, disable=not enabled, desc=desc, unit="frame")


def _mean(values):
    vals = [v for v in values if v is not None and not (isinstance(v, float) and math.isnan(v))]
    return float(np.mean(vals)) if vals else None


OBJECT_ERROR = "reconstruction.object_error_m."
MIRROR_PATHS = "mirror_paths."
LOS_POINTS = "los_points."


def summarise(records: list[dict]) -> dict[str, Any]:
    """Means over frames of every numeric metric and per-stage time, and ``objects``
    (:func:`summarise_objects`); the per-object figures are there only, not in ``metrics``."""
    out: dict[str, Any] = {"frames": len(records)}
    stages = sorted({k for r in records for k in r.get("timings_s", {})})
    out["time_ms"] = {s: 1e3 * _mean([r["timings_s"].get(s) for r in records]) for s in stages}
    flat: dict[str, list] = {}
    for r in records:
        for key, v in _flatten(r.get("metrics") or {}).items():
            flat.setdefault(key, []).append(v)
    out["objects"] = summarise_objects(records)
    out["metrics"] = {k: _mean(v) for k, v in sorted(flat.items())
                      if not k.startswith((OBJECT_ERROR, MIRROR_PATHS, LOS_POINTS))}
    out["notes"] = sorted({n for r in records for n in r.get("notes", [])})
    return out


def summarise_objects(records: list[dict]) -> dict[str, dict[str, Any]]:
    """Object name → {frames, observable_frames, los_frames, error_m, status} over the frames whose
    ground truth lists the object.

    observable_frames: frames in which it has an open mirror path (``metrics.mirror_paths``; a
    record without that key counts as observable). los_frames: frames in which the radar sees it
    directly (``metrics.los_points`` > 0), counted over the records that hold ``los_points``; None
    when none does (records of frames read from a dataset, or written before it existed).
    error_m: mean over frames of ``reconstruction.object_error_m`` [m] where it was reconstructed,
    else None. status, for an object with a mirror path in some frame: "reconstructed", "not
    reconstructed", or "not scored" (the pipeline has no reconstructor); without one: "in line of
    sight" (seen directly in some frame: in plain view, nothing hidden to reconstruct, not a
    failure) or "not observable" (neither: nothing could be reconstructed, so no score, rather
    than a vacuous F1 of 1; also every object without a mirror path when ``los_frames`` is None)."""
    out: dict[str, dict[str, Any]] = {}
    for r in records:
        m = r.get("metrics") or {}
        paths, los = m.get("mirror_paths"), m.get("los_points")
        errors = (m.get("reconstruction") or {}).get("object_error_m")
        names = list(paths or {}) + [n for n in (errors or {}) if n not in (paths or {})]
        for name in names:
            o = out.setdefault(name, {"frames": 0, "observable_frames": 0, "los_frames": None, "errors": [],
                                      "scored": False})
            o["frames"] += 1
            o["observable_frames"] += int(paths is None or paths.get(name, 0) > 0)
            if los is not None:
                o["los_frames"] = (o["los_frames"] or 0) + int(los.get(name, 0) > 0)
            if errors is not None:
                o["scored"] = True
                o["errors"].append(errors.get(name))
    for o in out.values():
        o["error_m"] = _mean(o.pop("errors"))
        scored = o.pop("scored")
        if o["observable_frames"] == 0:
            o["status"] = "in line of sight" if o["los_frames"] else "not observable"
        else:
            o["status"] = ("not scored" if not scored else "not reconstructed" if o["error_m"] is None
                           else "reconstructed")
    return {k: out[k] for k in sorted(out)}


def object_verdict(info: dict[str, Any]) -> str:
    """One object's result as the summary and the command line print it (one number, one rounding):
    "0.32 m", "not observable (no mirror path in any of 3 frames)", "in line of sight (…)",
    "not reconstructed", …"""
    if info["status"] == "reconstructed":
        return f"{info['error_m']:.2f} m"
    if info["status"] == "not observable":
        return f"not observable (no mirror path in any of {info['frames']} frame(s))"
    if info["status"] == "in line of sight":
        return (f"in line of sight (seen directly in {info['los_frames']} of {info['frames']} frame(s), "
                "no mirror path: nothing hidden to reconstruct)")
    if info["status"] == "not scored":
        return "not scored (no reconstructor)"
    return "n/a (not reconstructed)"


def _los_cell(info: dict[str, Any]) -> str:
    """The summary table's "frames in line of sight" cell: "k of n", or n/a when not recorded."""
    los = info.get("los_frames")
    return "n/a (not recorded)" if los is None else f"{los} of {info['frames']}"


def _flatten(d: dict, prefix: str = "") -> dict[str, float]:
    out = {}
    for k, v in d.items():
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out.update(_flatten(v, key + "."))
        elif v is None or (isinstance(v, (int, float)) and not isinstance(v, bool)):
            out[key] = None if v is None else float(v)  # None: undefined this frame (e.g. not reconstructed)
    return out


def render_summary(summary: dict, prov: dict, config: PipelineConfig) -> str:
    """Markdown summary: plugins, the hidden-object error, metrics and per-stage timing."""
    lines = [f"# xnlos run: {config.name}", "",
             f"- frames: {summary['frames']}", f"- seed: {prov['seed']}",
             f"- config sha256: `{prov['config_sha256'][:16]}`",
             "- plugins: " + ", ".join(f"{k} = `{v['name']}` ({v['provider']})" for k, v in prov["plugins"].items()),
             "- versions: " + ", ".join(f"{k} {v}" for k, v in prov["versions"].items() if v), ""]
    m = summary["metrics"]
    objects = summary.get("objects") or {}
    if objects:
        lines += ["## Scene objects", "",
                  "Reconstruction error: mean distance from the reconstructed points to the object's nearest "
                  "true (illuminated) surface point, over the frames where it was reconstructed. An object "
                  "with no mirror path (no relay wall shows it to the radar) is not scored: \"in line of sight\" "
                  "when the radar sees it directly (in plain view, nothing hidden to reconstruct, not a failure), "
                  "else \"not observable\".",
                  "", "| object | reconstruction error | frames with a mirror path | frames in line of sight |",
                  "|---|---|---|---|"]
        lines += [f"| {k} | {object_verdict(o)} | {o['observable_frames']} of {o['frames']} | {_los_cell(o)} |"
                  for k, o in objects.items()]
        lines.append("")
    if m:
        lines += ["## Metrics (mean over frames)", "", "| metric | value |", "|---|---|"]
        lines += [f"| {k} | {'n/a' if v is None else f'{v:.4g}'} |" for k, v in m.items()]
        lines.append("")
    lines += ["## Time per stage (mean per frame)", "", "| stage | ms |", "|---|---|"]
    lines += [f"| {k} | {v:.1f} |" for k, v in summary["time_ms"].items()]
    total = sum(v for k, v in summary["time_ms"].items() if k != "source")
    lines += [f"| processing total (without source) | {total:.1f} |", ""]
    if summary.get("notes"):
        lines += ["## Notes", ""] + [f"- {n}" for n in summary["notes"]] + [""]
    if summary.get("figure"):
        lines += [f"![last frame]({summary['figure']})", ""]
    if summary.get("animation"):
        lines += [f"![sequence]({summary['animation']})", ""]
    return "\n".join(lines)
