"""``xnlos eval``: pipelines scored on a dataset split (the paper's Table 2), per run and per scene family.

A CONFIG is a pipeline file, optionally with a ``[sweep]`` grid and/or ``[[sweep.cases]]``
(:func:`xnlos_core.config.expand_sweep`); each sweep point is one *run*. Every run reads the maps of
a dataset split through the ``dataset`` backend (sims/dataset/backend.py): the config's own
``[backend] name = "dataset"`` table when it has one, else ``out/data/default``, split ``test``; the
``dataset`` / ``split`` / ``limit`` / ``start`` arguments override either. ``run.frames`` is not used:
a run reads every selected map.

Per map (Pipeline.process, ground truth thinned to the radar's resolution, match radius
``run.match_radius`` [m]): dense-prediction F1 and Chamfer distance CD [m²] per class (LOS, mNLOS),
their macro mean and the class-agnostic "all", reconstruction F1 / CD of the complete reflected
cloud (LOS detections plus reconstructed hidden points against LOS plus hidden ground truth,
:func:`xnlos_core.metrics.scene_metrics`), and the wall time of every stage. Aggregation over
maps (AGGREGATION below) is the one of benchmarks/detectors.py.

Output (``OUT``): ``run-NNN/frames.jsonl`` (one fsync'd line per map: a killed eval rerun with the
same command resumes after the last complete map; a larger ``limit`` extends a finished one; a
changed config or changed learned weights — a model retrained into the same file — is refused
rather than mixed with the old records),
``run-NNN/run.json`` (config and provenance), ``run-NNN/map_MMMMM.png`` (Fig. 6-style panels of
the first ``figures`` maps), ``eval.json`` (atomic) and ``eval.md``.

Sequences: a pipeline with a tracker is scored sequence by sequence, the pipeline reset at
each sequence start, with tracking and prediction metrics per run, family and motion kind beside the
map metrics (:mod:`xnlos_core.app.sequence_eval`; ``run-NNN/sequences.jsonl``, resumed per whole sequence).
"""
from __future__ import annotations

import json
import math
import warnings
from pathlib import Path
from typing import Any

import numpy as np

from xnlos_core.config import PipelineConfig, expand_sweep, load_toml, parse_pipeline
from xnlos_core.errors import GridMismatchWarning, InputError
from xnlos_core.io import append_jsonl, atomic_write_text, read_keyed_jsonl, write_jsonl
from xnlos_core.rundir import claim, write_record
from xnlos_core.app.sequence_eval import render_tracking

DEFAULT_DATASET = "out/data/default"
DEFAULT_SPLIT = "test"

AGGREGATION = (
    "F1: the mean over maps of each map's F1 (Macro F1 of a map = mean of its LOS and mNLOS F1). "
    "CD [m²]: the mean over the maps where it is finite, i.e. where prediction and ground truth are both "
    "non-empty (a map's Macro CD is finite only when its LOS and mNLOS CD both are); the number of such "
    "maps is kept in `cd_maps`. Empty sets (xnlos_core.metrics): no prediction and no ground truth → "
    "F1 = 1, CD = 0 m²; ground truth but no prediction, or prediction but no ground truth → F1 = 0, CD = "
    "+inf (left out of the CD mean). A detector that cannot classify (plain CFAR) is reported with its "
    "class-agnostic F1 / CD in the Macro columns and '-' per class, as the paper does. Time: median and "
    "mean over maps of each stage's wall time [ms]; 'processing' is their sum without the frame source.")

# The metric keys of a per-map record (dotted paths into FrameResult.metrics).
DENSE_KEYS = tuple(f"dense.{c}.{m}" for c in ("macro", "los", "mnlos", "all") for m in ("f1", "cd"))
RECON_KEYS = ("reconstruction.f1", "reconstruction.cd", "reconstruction.precision", "reconstruction.recall")
METRIC_KEYS = DENSE_KEYS + RECON_KEYS

# Table 2 of the paper, simulation rows, keyed by run name (the `name` of each [[sweep.cases]] in
# configs/ablations/table2.toml): dense Macro / LOS / mNLOS F1, Macro / LOS / mNLOS CD [m²],
# reconstruction F1, CD [m²]. None: '-' in the paper (CFAR cannot classify).
PAPER_TABLE2: dict[str, tuple[float | None, ...]] = {
    "NLOS-CFAR": (0.23, None, None, 68.6, None, None, 0.03, 29.7),
    "RTN": (0.57, 0.68, 0.47, 104.0, 140.6, 67.2, 0.20, 14.0),
    "Further Than CFAR": (0.41, 0.52, 0.31, 65.9, 47.6, 84.2, 0.16, 13.5),
    "Proposed + UNet": (0.67, 0.73, 0.61, 44.0, 43.0, 44.9, 0.27, 11.9),
    "Proposed w/o residual": (0.85, 0.88, 0.82, 17.3, 11.6, 23.0, 0.40, 9.2),
    "Proposed": (0.85, 0.88, 0.82, 17.3, 11.6, 23.0, 0.45, 8.2),
}
TABLE_COLUMNS = ("Macro F1", "LOS F1", "mNLOS F1", "Macro CD", "LOS CD", "mNLOS CD", "recon F1", "recon CD")


# --- configuration --------------------------------------------------------------------------------

def with_dataset(table: dict[str, Any], *, dataset: str | None = None, split: str | None = None,
                 limit: int | None = None, start: int | None = None) -> tuple[dict[str, Any], str | None]:
    """``table`` reading its frames from the ``dataset`` backend; returns (table, note or None).

    Keeps a ``[backend] name = "dataset"`` table (overriding the given params); any other frame
    source is replaced by the default dataset (the note says so). A given ``dataset`` is a path on
    the command line: relative to the working directory (like ``--out``), not to the config's folder
    as the config's own paths are."""
    t = dict(table)
    note = None
    src = t.get("backend")
    if isinstance(src, dict) and src.get("name") == "dataset":
        params = dict(src.get("params") or {})
    else:
        params = {"path": DEFAULT_DATASET, "split": DEFAULT_SPLIT}
        if src is not None or t.get("forward_model") is not None:
            what = f"backend {src.get('name')!r}" if isinstance(src, dict) else "the forward model"
            note = f"eval reads a dataset: {what} replaced by the dataset backend"
        t.pop("forward_model", None)
    for k, v in (("path", dataset), ("split", split), ("limit", limit), ("start", start)):
        if v is not None:
            params[k] = str(Path(v).resolve()) if k == "path" else v
    t["backend"] = {"name": "dataset", "params": params}
    return t, note


def resume_digest(config: PipelineConfig) -> str:
    """Config hash without the backend's ``limit``: a larger limit resumes the same records."""
    params = {k: v for k, v in config.backend.params.items() if k != "limit"}
    return config.model_copy(update={"backend": config.backend.model_copy(update={"params": params})}).digest()


def plan_runs(path: str | Path, **dataset_kw) -> list[dict[str, Any]]:
    """The runs of eval config ``path``: [{run, name, assignment, config, source, note}], each validated."""
    path = Path(path)
    table = load_toml(path)
    source, base_dir = str(path), path.resolve().parent
    runs = []
    for i, (assignment, t) in enumerate(expand_sweep(table, source)):
        t, note = with_dataset(t, **dataset_kw)
        label = f"{source} (sweep point {i}: {assignment})" if assignment else source
        cfg = parse_pipeline(t, label, base_dir)
        runs.append({"run": i, "name": cfg.name, "assignment": assignment, "config": cfg, "source": label,
                     "note": note})
    return runs


# --- per-map records and aggregation -------------------------------------------------------------

def _get(d: dict, dotted: str):
    for part in dotted.split("."):
        if not isinstance(d, dict) or part not in d:
            return None
        d = d[part]
    return d


def _num(v) -> float | None:
    """float, with NaN → None (JSON); ±inf stays (json writes Infinity, a CD with an empty side)."""
    if v is None:
        return None
    v = float(v)
    return None if math.isnan(v) else v


def frame_record(result, position: int) -> dict[str, Any]:
    """One line of frames.jsonl for a FrameResult with ground truth."""
    det, meta = result.detections, result.frame.meta
    m = result.metrics
    return {
        "position": position, "map": int(result.frame.index),
        "family": str(meta.get("family", "unknown")), "scene": meta.get("scene"),
        "metrics": {k: _num(_get(m, k)) for k in METRIC_KEYS},
        "classified": bool(m["dense"]["classified"]),
        "counts": {"LOS": int((det.label == 0).sum()), "mNLOS": int((det.label == 1).sum()),
                   "unclassified": int((det.label == 2).sum()), "walls": len(result.walls),
                   "hidden": len(result.hidden)},
        "timings_ms": {k: 1e3 * v for k, v in result.timings.items()},
        "notes": list(result.notes),
    }


def note_summary(records: list[dict[str, Any]], extra: str | None = None) -> list[str]:
    """Per stage, how many maps carry a pipeline note, with the first as an example (plus ``extra``)."""
    first: dict[str, str] = {}
    count: dict[str, int] = {}
    for r in records:
        for stage in dict.fromkeys(n.split(":", 1)[0] for n in r["notes"]):
            count[stage] = count.get(stage, 0) + 1
            first.setdefault(stage, next(n for n in r["notes"] if n.startswith(stage)))
    out = [f"{count[s]} of {len(records)} map(s) with a {s} note, e.g. “{first[s]}”" for s in count]
    return ([extra] if extra else []) + out


def _mean(vals: list[float]) -> float | None:
    return float(np.mean(vals)) if vals else None


def aggregate(records: list[dict[str, Any]]) -> dict[str, Any]:
    """Metrics and time over the maps of ``records`` (AGGREGATION): {maps, classified, metrics
    {key: value or None}, cd_maps {key: maps with a finite CD}, time_ms {stage: {median, mean}}}."""
    out: dict[str, Any] = {"maps": len(records), "classified": all(r["classified"] for r in records),
                           "metrics": {}, "cd_maps": {}, "time_ms": {}}
    for key in METRIC_KEYS:
        vals = [r["metrics"].get(key) for r in records]
        if key.endswith(".cd"):
            finite = [v for v in vals if v is not None and math.isfinite(v)]
            out["metrics"][key] = _mean(finite)
            out["cd_maps"][key] = len(finite)
        else:
            out["metrics"][key] = _mean([v for v in vals if v is not None])
    stages = list(dict.fromkeys(s for r in records for s in r["timings_ms"]))
    per_map = {s: [r["timings_ms"][s] for r in records if s in r["timings_ms"]] for s in stages}
    per_map["processing"] = [sum(v for s, v in r["timings_ms"].items() if s != "source") for r in records]
    out["time_ms"] = {s: {"median": float(np.median(v)), "mean": float(np.mean(v))} for s, v in per_map.items() if v}
    return out


def by_family(records: list[dict[str, Any]]) -> dict[str, dict[str, Any]]:
    """:func:`aggregate` per scene family (``frame.meta["family"]``), families sorted by name."""
    fams = sorted({r["family"] for r in records})
    return {f: aggregate([r for r in records if r["family"] == f]) for f in fams}


# --- running --------------------------------------------------------------------------------------

def _progress(total, initial, enabled, desc):
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, disable=not enabled, desc=desc, unit="map")


def _figure(pipe, res, path: Path, title: str) -> None:
    from xnlos_core.app.plot.frame_figure import plot_frame_panels

    plot_frame_panels(res, path, heatmaps=pipe.stages["detector"].heatmap(res.frame), title=title,
                      detector=pipe.config.detector.name)


def evaluate_run(run: dict[str, Any], out: str | Path, *, figures: int = 2, progress: bool = True,
                 overwrite: bool = False, registry=None) -> dict[str, Any]:
    """Score one planned run (:func:`plan_runs`) into ``out``; returns its eval.json entry.

    Resumes from ``out/frames.jsonl`` when ``out/run.json`` holds the same configuration (up to the
    backend's limit) and the same learned weights (:meth:`Pipeline.state_sha256`); anything else is
    a ConfigError unless ``overwrite``."""
    from xnlos_core.pipeline import Pipeline

    cfg: PipelineConfig = run["config"]
    out = Path(out)
    pipe = Pipeline(cfg, registry=registry, source=run["source"])
    digest, state = resume_digest(cfg), pipe.state_sha256()
    log = out / "frames.jsonl"
    done: list[dict] = []
    if claim(out, "run.json", {"resume_sha256": digest}, overwrite=overwrite, what="an evaluation",
             clear=[log.name, "map_*.png", "sequences.jsonl"], state=state, label="evaluation record") is not None:
        # Keyed on the map's position: repeated lines are dropped, bad ones refused naming the line.
        done = list(read_keyed_jsonl(log, "position").values())
        write_jsonl(log, done)  # the repairs (a torn last line, repeats) made durable before appending
    prov = pipe.provenance()
    write_record(out, "run.json", {"name": cfg.name, "assignment": run["assignment"], "resume_sha256": digest,
                                   "state_sha256": state, "config": cfg.model_dump(mode="json"),
                                   "provenance": prov})
    backend = pipe.stages["backend"]
    total = backend.n_frames
    tracking = "tracker" in pipe.stages
    bar = _progress(total, 0 if tracking else len(done), progress, f"eval {cfg.name}")
    seqs = None
    backend.open(pipe.radar)
    with warnings.catch_warnings(record=True) as seen:  # grid mismatches go into the table (setup_differs)
        warnings.simplefilter("always", GridMismatchWarning)
        try:
            if tracking:
                from xnlos_core.app.sequence_eval import evaluate_sequences

                records, seqs = evaluate_sequences(
                    pipe, backend.frames(), out, done, record=frame_record, bar=bar, figures=figures, source=run["source"],
                    figure=lambda res, pos: _figure(pipe, res, out / f"map_{res.frame.index:05d}.png", cfg.name))
                n = total
            else:
                records, n = _score_maps(pipe, backend, log, done, bar, figures, out, run["source"])
        finally:
            backend.close()
            bar.close()
    for w in seen:  # emitted again, through the caller's filters, as they would have been
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    # the set-up differences the detector accepted (known before any map: a fully resumed evaluation has
    # them too) and any grid mismatch met on a frame
    accepted = [f"{kind} set-up differs from its training: {'; '.join(items)}"
                for kind, items in prov.get("accepted_mismatch", {}).items()]
    differs = list(dict.fromkeys(accepted + [str(w.message) for w in seen
                                             if issubclass(w.category, GridMismatchWarning)]))
    records = sorted((r for r in records if r["position"] < n), key=lambda r: r["position"])
    figs = [f"map_{r['map']:05d}.png" for r in records[:figures]]
    if any(not (out / f).exists() for f in figs):
        # e.g. an earlier --no-figures pass scored these maps: draw them now.
        backend.open(pipe.radar)
        if tracking:  # a tracked figure map is drawn with the tracks of its sequence's first map
            pipe.reset()
        try:
            for frame in backend.frames(figures):
                path = out / f"map_{frame.index:05d}.png"
                if not path.exists():
                    _figure(pipe, pipe.process(frame), path, cfg.name)
        finally:
            backend.close()
    if not records:
        raise InputError(f"{run['source']}: the dataset backend yielded no maps (params {cfg.backend.params})")
    return {"run": run["run"], "name": cfg.name, "assignment": run["assignment"], "dir": out.name,
            "detector": cfg.detector.name,  # a detection-only pipeline has neither of the next two
            "wall_estimator": cfg.wall_estimator.name if cfg.wall_estimator else None,
            "reconstructor": cfg.reconstructor.name if cfg.reconstructor else None, "dataset": dict(cfg.backend.params),
            "match_radius_m": cfg.run.match_radius, "overall": aggregate(records),
            "families": by_family(records), "figures": figs, "notes": note_summary(records, run["note"]) + differs,
            "setup_differs": differs,
            **({"tracker": cfg.tracker.name, "tracking": _tracking(seqs)} if tracking else {})}


def _tracking(seqs: list[dict]) -> dict[str, Any] | None:
    from xnlos_core.app.sequence_eval import summarize

    return summarize(seqs) if seqs else None


def _score_maps(pipe, backend, log: Path, done: list[dict], bar, figures: int, out: Path,
                source: str) -> tuple[list[dict], int]:
    """Score the maps not in ``done`` one by one (no tracker); returns (records, maps read). Each map
    stands alone: the pipeline is reset before it (:meth:`Pipeline.reset`), so a wall estimator that
    pools earlier frames (``lsq``'s ``history_frames``) fits each map's own LOS detections, as a resumed
    eval, which skips the maps it holds, must. Walls pooled over frames are scored on sequences, with
    a tracker (:mod:`xnlos_core.app.sequence_eval`)."""
    from xnlos_core.pipeline import timed_frames

    have = {r["position"] for r in done}
    records = list(done)
    position = 0
    for frame, src in timed_frames(backend.frames()):
        if position not in have:
            if frame.ground_truth is None:
                raise InputError(f"{source}: map {frame.index} has no ground truth; eval needs a simulated dataset")
            pipe.reset()
            res = pipe.process(frame)
            res.timings = {"source": src, **res.timings}
            if position < figures:
                _figure(pipe, res, out / f"map_{frame.index:05d}.png", pipe.config.name)
            rec = frame_record(res, position)
            append_jsonl(log, rec)
            records.append(json.loads(json.dumps(rec)))
            bar.update(1)
        position += 1
    return records, position


def run_eval(config: str | Path, out: str | Path, *, dataset: str | None = None, split: str | None = None,
             limit: int | None = None, start: int | None = None, figures: int = 2, progress: bool = True,
             overwrite: bool = False, registry=None) -> dict[str, Any]:
    """Evaluate every run of ``config`` into ``out``; writes eval.json and eval.md, returns eval.json's dict."""
    if figures < 0:
        raise InputError(f"figures: the number of maps to draw must be ≥ 0, got {figures}")
    out = Path(out)
    runs = plan_runs(config, dataset=dataset, split=split, limit=limit, start=start)  # all validated first
    entries = [evaluate_run(r, out / f"run-{r['run']:03d}", figures=figures, progress=progress,
                            overwrite=overwrite, registry=registry) for r in runs]
    name = load_toml(config).get("name", Path(config).stem)
    result = {"name": name, "config": str(config), "aggregation": AGGREGATION, "runs": entries}
    atomic_write_text(out / "eval.json", json.dumps(result, indent=2, sort_keys=True, allow_nan=False))
    atomic_write_text(out / "eval.md", render_markdown(result))
    return result


# --- report ---------------------------------------------------------------------------------------

def _fmt(v, digits: int) -> str:
    return "-" if v is None or not math.isfinite(v) else f"{v:.{digits}f}"


def _ours(agg: dict[str, Any]) -> list[float | None]:
    """The eight Table 2 numbers of an aggregate (class-agnostic Macro when not classified)."""
    m = agg["metrics"]
    if agg["classified"]:
        dense = [m[f"dense.{c}.{k}"] for k in ("f1", "cd") for c in ("macro", "los", "mnlos")]
    else:
        dense = [m["dense.all.f1"], None, None, m["dense.all.cd"], None, None]
    return dense + [m["reconstruction.f1"], m["reconstruction.cd"]]


def render_markdown(result: dict[str, Any]) -> str:
    """eval.md: Table 2 beside the paper, per-family table, per-stage time, figures, conventions."""
    runs = result["runs"]
    digits = (2, 2, 2, 1, 1, 1, 2, 1)
    ds = runs[0]["dataset"] if runs else {}
    lines = [f"# xnlos eval: {result['name']}", "",
             f"Dataset `{ds.get('path')}`, split `{ds.get('split')}`"
             + (f", from map {ds['start']}" if ds.get("start") else "")
             + f"; config `{result['config']}`; match radius {runs[0]['match_radius_m'] if runs else '-'} m.", "",
             "## Table 2 (simulation): ours (paper)", "",
             "Each cell: our value, the paper's in parentheses ('-': not reported / not defined). "
             "F1 [-] ↑, CD [m²] ↓. Set-up: 'as the paper' when the run is a paper row on the grid its "
             "detector was trained on; 'DIFFERS' (the paper's numbers left out: ours are not comparable) "
             "when the maps' grid differs from it (see Notes).", "",
             "| run | method | detector → reconstructor | maps | set-up | " + " | ".join(TABLE_COLUMNS) + " |",
             "|" + "---|" * (5 + len(TABLE_COLUMNS))]
    for r in runs:
        ours = _ours(r["overall"])
        differs = r.get("setup_differs") or []
        paper = None if differs else PAPER_TABLE2.get(r["name"])
        setup = ("DIFFERS: grid ≠ the detector's training grid (see Notes)" if differs
                 else "as the paper" if paper else "-")
        cells = [_fmt(v, d) + (f" ({_fmt(paper[i], d)})" if paper else "") for i, (v, d) in enumerate(zip(ours, digits))]
        lines.append(f"| {r['run']} | {r['name']} | {r['detector']} → {r['reconstructor']} | {r['overall']['maps']} | "
                     f"{setup} | " + " | ".join(cells) + " |")
    lines += ["", "## Per scene family", "",
              "| run | method | family | maps | " + " | ".join(TABLE_COLUMNS) + " |",
              "|" + "---|" * (4 + len(TABLE_COLUMNS))]
    for r in runs:
        for fam, agg in r["families"].items():
            cells = [_fmt(v, d) for v, d in zip(_ours(agg), digits)]
            lines.append(f"| {r['run']} | {r['name']} | {fam} | {agg['maps']} | " + " | ".join(cells) + " |")
    stages = list(dict.fromkeys(s for r in runs for s in r["overall"]["time_ms"]))
    lines += ["", "## Time per map [ms] (median / mean)", "",
              "| run | method | " + " | ".join(stages) + " |", "|" + "---|" * (2 + len(stages))]
    for r in runs:
        t = r["overall"]["time_ms"]
        lines.append(f"| {r['run']} | {r['name']} | "
                     + " | ".join(f"{t[s]['median']:.1f} / {t[s]['mean']:.1f}" if s in t else "-" for s in stages) + " |")
    figs = [(r, f) for r in runs for f in r["figures"]]
    if figs:
        lines += ["", "## Figures (Fig. 6 style)", ""]
        lines += [f"- run {r['run']} ({r['name']}): [{f}]({r['dir']}/{f})" for r, f in figs]
    lines += render_tracking(runs)
    notes = [(r, n) for r in runs for n in r["notes"]]
    if notes:
        lines += ["", "## Notes", ""] + [f"- run {r['run']} ({r['name']}): {n}" for r, n in notes]
    lines += ["", "## Conventions", "", AGGREGATION, ""]
    return "\n".join(lines)
