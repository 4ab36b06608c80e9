"""``xnlos simulate``: write a sharded dataset, resumable after a kill, verifiable and repairable.

Directory layout::

    DIR/manifest.json      schema version, config (+ digest), radar, versions, splits, shards
    DIR/completed.jsonl    one fsync'd line per finished shard: name, sha256, counts, config digest
    DIR/shards/*.npz       one file per shard (:mod:`sims.dataset.shard`)

Workers (local processes or Dask) build shard bytes and return them; only this process writes
files: each shard atomically (temporary file, fsync, rename, directory fsync), then its line in
``completed.jsonl``, then the manifest. A killed run therefore leaves complete shards, at most
one shard without its log line (rebuilt identically on resume) and perhaps a temporary file
(removed on resume). Resuming re-hashes every logged shard: a mismatch or a missing file stops
the run naming the shard; ``repair=True`` rebuilds those shards.
"""
from __future__ import annotations

import json
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from xnlos_core.errors import ConfigError
from xnlos_core.executor import map_unordered
from xnlos_core.io import append_jsonl, atomic_write_bytes, atomic_write_text

from .config import SPLITS, DatasetConfig, generator_classes, resolve
from .manifest import (FORMAT, LOG, MANIFEST, SHARD_DIR, check_files, describe, integrity_problems, read_log,
                       write_manifest)
from .plan import make_plan
from .shard import READABLE_VERSIONS, SCHEMA_VERSION, DatasetError, run_shard_job


def simulate_dataset(config: DatasetConfig, out: str | Path, *, source: str = "<config>",
                     workers: int | None = None, scheduler: str | None = None, overwrite: bool = False,
                     repair: bool = False, progress: bool = True,
                     on_shard: Callable[[dict], None] | None = None, registry=None) -> dict[str, Any]:
    """Generate (or finish) the dataset of ``config`` in ``out``; returns a summary dict.

    workers: local processes (1 = in this process, None = every core); scheduler: a Dask
    scheduler address (workers need this package installed; only this process touches ``out``).
    overwrite: discard a dataset of another config in ``out``. repair: rebuild logged shards
    whose file is missing or corrupt instead of stopping. on_shard(record): called after each
    shard is durably recorded (an exception raised there stops the run, as a kill would).
    registry: where the forward model and the scene generators (``families``) are looked up
    (default: the process-wide one); workers get each family's class as resolved here.
    """
    t0 = time.perf_counter()
    cfg = resolve(config, source, registry)
    classes = generator_classes(cfg, source, registry)
    digest = cfg.digest()
    plan = make_plan(cfg)
    out = Path(out)
    shard_dir = out / SHARD_DIR
    _check_existing(out, digest, overwrite, repair)
    shard_dir.mkdir(parents=True, exist_ok=True)
    for pattern in (f"{SHARD_DIR}/.*.tmp", f".{MANIFEST}.*.tmp", f".{LOG}.*.tmp"):
        for tmp in out.glob(pattern):  # left by a kill during a write; never a complete file
            tmp.unlink(missing_ok=True)
    names = {s.name for s in plan.shards}
    done = {n: r for n, r in read_log(out).items() if r.get("config_sha256") == digest and n in names
            and r.get("n_maps") == plan.shard(n).n_maps}
    bad = check_files(shard_dir, done)
    if bad and not repair:
        raise DatasetError(f"{out}: {describe(bad)}; rerun with --repair (repair=True) to rebuild "
                           f"{'it' if len(bad) == 1 else 'them'}")
    for name in bad:
        done.pop(name)
    # Rewrite the log with exactly the verified records (drops a torn last line and duplicates).
    atomic_write_text(out / LOG, "".join(json.dumps(done[s.name], sort_keys=True) + "\n"
                                         for s in plan.shards if s.name in done))
    write_manifest(out, cfg, digest, plan, done)

    todo = [s for s in plan.shards if s.name not in done]
    jobs = [{"config": cfg.model_dump(mode="json"), "digest": digest, "generators": classes, "shard": s.name,
             "split": s.split,
             "scenes": [(k, *plan.scene(k)[:2]) for k in s.scenes]} for s in todo]
    from tqdm import tqdm

    bar = tqdm(total=cfg.n_maps, initial=sum(r["n_maps"] for r in done.values()), disable=not progress,
               desc=f"simulate {cfg.name}", unit="map")
    try:
        for _, res in map_unordered(run_shard_job, jobs, scheduler=scheduler, workers=workers):
            _write_shard(shard_dir / res["shard"], res["data"])
            rec = {"shard": res["shard"], "split": plan.shard(res["shard"]).split, "sha256": res["sha256"],
                   "bytes": len(res["data"]), "n_maps": res["n_maps"], "n_scenes": res["n_scenes"],
                   "seconds": round(res["seconds"], 3), "cpu_seconds": round(res["cpu_seconds"], 3),
                   "config_sha256": digest}
            append_jsonl(out / LOG, rec)
            done[rec["shard"]] = rec
            write_manifest(out, cfg, digest, plan, done)
            bar.update(rec["n_maps"])
            if on_shard is not None:
                on_shard(rec)
    finally:
        bar.close()
    return {"out": str(out), "n_maps": cfg.n_maps, "n_shards": len(plan.shards), "generated": len(todo),
            "maps_generated": sum(s.n_maps for s in todo),
            "skipped": len(plan.shards) - len(todo), "repaired": sorted(bad), "config_sha256": digest,
            "seconds": time.perf_counter() - t0,
            "splits": {sp: sum(s.n_maps for s in plan.shards if s.split == sp) for sp in SPLITS}}


def _check_existing(out: Path, digest: str, overwrite: bool, repair: bool = False) -> None:
    """Stop unless ``out`` is empty or holds this config's dataset with an intact manifest (a
    damaged one only with ``repair``: it is rebuilt from the config and the verified shards)."""
    path = out / MANIFEST
    if not path.exists():
        return
    try:
        text = path.read_bytes().decode("utf-8")
        old = json.loads(text)
        if not isinstance(old, dict):
            raise ValueError(f"a JSON {type(old).__name__}, not an object")
    except (OSError, ValueError, RecursionError) as exc:
        if repair and not overwrite:
            return  # rebuilt from the config; only shards logged under this config's digest are kept
        if not overwrite:
            raise DatasetError(f"{path}: unreadable manifest ({exc}); pass --overwrite to start afresh") from None
        old = {}
    if old and old.get("format") != FORMAT:
        raise DatasetError(f"{path}: not an xnlos dataset manifest (format {old.get('format')!r}); "
                           "choose another --out")
    same = old.get("schema_version") == SCHEMA_VERSION and old.get("config_sha256") == digest
    problems = integrity_problems(old, text) if old.get("schema_version") in READABLE_VERSIONS else []
    if problems and repair and not overwrite:
        return  # rebuilt from the config; only shards logged under this config's digest are kept
    if same and problems and not overwrite:
        raise DatasetError(f"{path}: {'; '.join(problems)}; rerun with --repair (repair=True) to rebuild the "
                           "manifest from the config and the verified shards")
    if same:
        return
    if not overwrite:
        why = (f"schema version {old.get('schema_version')} (this xnlos writes {SCHEMA_VERSION})"
               if old.get("schema_version") != SCHEMA_VERSION else
               f"another configuration (config hash {str(old.get('config_sha256'))[:12]} ≠ {digest[:12]})")
        raise ConfigError(f"{out}: holds a dataset of {why}; choose another --out or pass --overwrite")
    for p in (out / SHARD_DIR).glob("*.npz"):
        p.unlink()
    for p in (out / SHARD_DIR).glob(".*.tmp"):
        p.unlink()
    (out / LOG).unlink(missing_ok=True)
    path.unlink()


def _write_shard(path: Path, data: bytes) -> None:
    """Atomic write, then fsync the directory so the rename survives a power cut too."""
    atomic_write_bytes(path, data)
    fd = os.open(path.parent, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)
