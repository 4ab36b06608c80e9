"""Dataset directory layout and ``manifest.json``: written, read (format and schema checked), hashed.

``manifest.json`` keys: format ("xnlos-dataset"), schema_version, name, config_sha256, config
(the resolved config: full radar, forward-model parameters with defaults), radar, versions
(package versions), n_maps, n_scenes, frames_per_scene, complete, splits (per split: n_scenes,
n_maps, scene_seeds), scenes (scene_seed, family, split by scene index), shards (per planned
shard: name, split, n_maps, n_scenes, scene_index, sha256 and bytes once written, else null),
created, updated.
"""
from __future__ import annotations

import hashlib
import json
import time
from pathlib import Path
from typing import Any

from xnlos_core.io import atomic_write_text, read_jsonl

from .config import DatasetConfig
from .plan import Plan
from .shard import READABLE_VERSIONS, SCHEMA_VERSION, DatasetError

MANIFEST, LOG, SHARD_DIR = "manifest.json", "completed.jsonl", "shards"
FORMAT = "xnlos-dataset"


def file_sha256(path: Path) -> str:
    """sha256 (hex) of a file, read in 4 MiB chunks."""
    h = hashlib.sha256()
    with path.open("rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 22), b""):
            h.update(chunk)
    return h.hexdigest()


def check_files(shard_dir: Path, records: dict[str, dict]) -> dict[str, str]:
    """name → "missing" | "corrupt (...)" for recorded shards whose file does not verify."""
    bad = {}
    for name, rec in records.items():
        path = shard_dir / name
        if not path.is_file():
            bad[name] = "missing"
        else:
            got = file_sha256(path)
            if got != rec["sha256"]:
                bad[name] = f"corrupt (sha256 {got[:12]}…, recorded {rec['sha256'][:12]}…)"
    return bad


def describe(bad: dict[str, str]) -> str:
    return "shard " + "; shard ".join(f"{SHARD_DIR}/{n} is {why}" for n, why in sorted(bad.items()))


def write_manifest(out: Path, cfg: DatasetConfig, digest: str, plan: Plan, done: dict[str, dict]) -> None:
    """Rewrite ``out/manifest.json`` atomically from the plan and the finished shards ``done``."""
    from xnlos_core.provenance import package_versions

    old = {}
    if (out / MANIFEST).exists():
        old = json.loads((out / MANIFEST).read_text())
    now = time.strftime("%Y-%m-%dT%H:%M:%S%z")
    shards = []
    for s in plan.shards:
        rec = done.get(s.name, {})
        shards.append({"name": s.name, "split": s.split, "n_maps": s.n_maps, "n_scenes": len(s.scenes),
                       "scene_index": list(s.scenes), "sha256": rec.get("sha256"), "bytes": rec.get("bytes")})
    manifest = {
        "format": FORMAT, "schema_version": SCHEMA_VERSION, "name": cfg.name,
        "config_sha256": digest, "config": cfg.model_dump(mode="json", exclude={"base_dir"}),
        "radar": cfg.radar, "versions": package_versions(),
        "n_maps": cfg.n_maps, "n_scenes": cfg.n_scenes, "frames_per_scene": cfg.frames_per_scene,
        "complete": len(done) == len(plan.shards),
        "splits": {sp: {"n_scenes": sum(1 for x in plan.split if x == sp),
                        "n_maps": sum(s.n_maps for s in plan.shards if s.split == sp),
                        "scene_seeds": seeds} for sp, seeds in plan.split_seeds().items()},
        "scenes": {"scene_seed": [int(x) for x in plan.scene_seed], "family": list(plan.family),
                   "split": list(plan.split)},
        "shards": shards, "created": old.get("created", now), "updated": now,
    }
    atomic_write_text(out / MANIFEST, json.dumps(manifest, indent=1, sort_keys=True))


def read_manifest(out: str | Path) -> dict[str, Any]:
    """The manifest of dataset directory ``out``, checked for format and schema version."""
    path = Path(out) / MANIFEST
    if not path.is_file():
        raise DatasetError(f"{out}: not an xnlos dataset (no {MANIFEST})")
    try:
        man = json.loads(path.read_text())
    except (OSError, ValueError) as exc:
        raise DatasetError(f"{path}: unreadable manifest ({exc})") from None
    if man.get("format") != FORMAT:
        raise DatasetError(f"{path}: not an xnlos dataset manifest (format {man.get('format')!r})")
    if man.get("schema_version") not in READABLE_VERSIONS:
        raise DatasetError(f"{path}: dataset schema version {man.get('schema_version')}; this xnlos reads "
                           f"versions {', '.join(map(str, READABLE_VERSIONS))} (regenerate it with this "
                           "version's xnlos simulate)")
    return man


def completed_records(out: str | Path, man: dict[str, Any]) -> dict[str, dict]:
    """name → {sha256, …} of finished shards: the manifest's, plus log lines it may not show yet."""
    recs = {s["name"]: {"sha256": s["sha256"], "n_maps": s["n_maps"]} for s in man["shards"] if s.get("sha256")}
    names = {s["name"] for s in man["shards"]}
    for r in read_jsonl(Path(out) / LOG):
        if r.get("config_sha256") == man["config_sha256"] and r.get("shard") in names:
            recs[r["shard"]] = r
    return recs


def manifest_config(out: str | Path) -> DatasetConfig:
    """The (resolved) config stored in ``out``'s manifest, e.g. to repair without the TOML file."""
    from xnlos_core.config import validate_model

    man = read_manifest(out)
    return validate_model(DatasetConfig, man["config"], source=str(Path(out) / MANIFEST), prefix="config")
