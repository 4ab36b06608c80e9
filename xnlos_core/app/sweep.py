"""``xnlos sweep``: a `[sweep]` grid and/or `[[sweep.cases]]` of pipelines (config-driven ablations), one run per point.

Each grid point runs in ``OUT/point-NNN/`` like ``xnlos run``; ``sweep.jsonl`` gets one line
per finished point, so a killed sweep resumes with the points still missing (a point is done when
its config and its stages' learned weights, :meth:`xnlos_core.pipeline.Pipeline.state_sha256`, are
those recorded and its own ``results.jsonl`` still holds every frame; ``overwrite`` runs every
point again). sweep.jsonl is read by :func:`xnlos_core.io.read_keyed_jsonl` keyed on the point. ``sweep.md`` tabulates the assignment of
every point beside its metrics and per-stage time.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from xnlos_core.config import expand_sweep, load_toml, parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.executor import map_unordered
from xnlos_core.io import append_jsonl, atomic_write_text, read_keyed_jsonl, write_jsonl
from xnlos_core.pipeline import Pipeline

COLUMNS = (
    ("dense.macro.f1", "macro F1"), ("dense.los.f1", "LOS F1"), ("dense.mnlos.f1", "mNLOS F1"),
    ("dense.all.f1", "class-agnostic F1"), ("dense.macro.cd", "macro CD [m²]"),
    ("reconstruction.f1", "recon F1"), ("reconstruction.cd", "recon CD [m²]"),
)


def _run_point(job: dict[str, Any]) -> dict[str, Any]:
    """Worker: run one grid point (module-level so processes and Dask can import it)."""
    from xnlos_core.app.runner import run_to_dir

    cfg = parse_pipeline(job["table"], job["source"], job["base_dir"])
    summary = run_to_dir(cfg, job["out"], source=job["source"], progress=False, overwrite=job["overwrite"])
    return {"point": job["point"], "assignment": job["assignment"], "config_sha256": cfg.digest(),
            "summary": summary}


def run_sweep(path: str | Path, out: str | Path, *, scheduler: str | None = None, workers: int | None = None,
              progress: bool = True, overwrite: bool = False) -> list[dict[str, Any]]:
    """Run every grid point of the sweep file ``path`` into ``out``; returns records by point.
    ``overwrite``: discard the recorded points and their directories' results and run all again."""
    from tqdm import tqdm

    path, out = Path(path), Path(out)
    table = load_toml(path)
    source, base_dir = str(path), str(path.resolve().parent)
    points = expand_sweep(table, source)
    jobs, cfgs = [], []
    for i, (assignment, t) in enumerate(points):
        label = f"{source} (sweep point {i}: {assignment})" if assignment else source
        cfgs.append(parse_pipeline(t, label, base_dir))  # every point is validated before anything runs
        jobs.append({"point": i, "assignment": assignment, "table": t, "source": label,
                     "base_dir": base_dir, "out": str(out / f"point-{i:03d}"), "digest": cfgs[-1].digest(),
                     "overwrite": overwrite})

    def current(r: dict[str, Any]) -> bool:
        """A recorded point is done when its config and its stages' learned weights are today's (the
        pipeline, which loads the weights, is built only for records whose config matches) and its
        own results are still complete in its directory."""
        i = r["point"]
        if i >= len(jobs) or r.get("config_sha256") != jobs[i]["digest"] or not isinstance(r.get("summary"), dict):
            return False
        return (r["summary"].get("state_sha256", {}) == Pipeline(cfgs[i], source=jobs[i]["source"]).state_sha256()
                and point_intact(Path(jobs[i]["out"]), cfgs[i], r["summary"]))

    out.mkdir(parents=True, exist_ok=True)
    log = out / "sweep.jsonl"
    if overwrite:
        log.unlink(missing_ok=True)
    # A later line of a point supersedes an earlier one: a point rerun (config, weights or results
    # changed) appends its new record. The log is rewritten with the points still done.
    done = {i: r for i, r in read_keyed_jsonl(log, "point", supersede=True).items() if current(r)}
    write_jsonl(log, done.values())
    todo = [j for j in jobs if j["point"] not in done]
    bar = tqdm(total=len(jobs), initial=len(done), disable=not progress, desc="sweep", unit="point")
    for _, rec in map_unordered(_run_point, todo, scheduler=scheduler, workers=workers):
        append_jsonl(log, rec)
        done[rec["point"]] = json.loads(json.dumps(rec, default=str))
        bar.update(1)
    bar.close()
    records = [done[i] for i in sorted(done)]
    atomic_write_text(out / "sweep.md", render_table(records, table.get("name", path.stem)))
    return records


def point_intact(point_dir: Path, cfg, summary: dict[str, Any]) -> bool:
    """Whether ``point_dir`` still holds the results its sweep record summarises: its provenance,
    summary.json and a results.jsonl with the recorded number of frames (frames 0 … n−1 for a
    simulated source). Damaged results are an InputError naming the file (from the reader)."""
    from xnlos_core.app.runner import read_results

    if not all((point_dir / f).is_file() for f in ("provenance.json", "summary.json", "results.jsonl")):
        return False
    n = cfg.run.frames if cfg.forward_model is not None else None
    got = read_results(point_dir / "results.jsonl", n)
    if n is not None and list(got) != list(range(n)):
        return False
    return len(got) == summary.get("frames")


def render_table(records: list[dict[str, Any]], name: str) -> str:
    """Markdown table: one row per grid point, assignment columns then metrics and time."""
    if not records:
        raise ConfigError(f"sweep {name}: no points were run")
    keys = list(dict.fromkeys(k for r in records for k in r["assignment"]))  # cases may set different keys
    head = ["point"] + keys + [c for _, c in COLUMNS] + ["ms/frame"]
    lines = [f"# Sweep: {name}", "", "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for r in records:
        m = r["summary"]["metrics"]
        t = r["summary"]["time_ms"]
        proc = sum(v for k, v in t.items() if k != "source")
        vals = [str(r["point"])] + [str(r["assignment"].get(k, "")) for k in keys]
        vals += ["n/a" if m.get(k) is None else f"{m[k]:.3g}" for k, _ in COLUMNS]
        vals.append(f"{proc:.1f}")
        lines.append("| " + " | ".join(vals) + " |")
    return "\n".join(lines) + "\n"
