"""Dataset directory layout and ``manifest.json``: written, read (format and schema checked), hashed.

``manifest.json`` keys: format ("xnlos-dataset"), schema_version, name, config_sha256, config
(the resolved config: full radar, forward-model parameters with defaults), radar, versions
(package versions), n_maps, n_scenes, frames_per_scene, complete, splits (per split: n_scenes,
n_maps, scene_seeds), scenes (scene_seed, family, split per scene in ascending scene index, and for
a reduced dataset (``full_n_maps`` set), whose indices are those of its full plan, scene_index), shards (per planned
shard: name, split, n_maps, n_scenes, scene_index, sha256 and bytes once written, else null),
created, updated, and ``checksum_sha256``: the sha256 of the manifest's own canonical content
(:func:`manifest_checksum`).

Integrity: :func:`read_manifest` (every open) refuses a manifest whose checksum does not match,
whose bytes are not those xnlos writes for its content (so even an edit that parses to the same
content, e.g. ``1e-05`` → ``1E-05``, is seen), that has keys xnlos does not write, or whose map
counts disagree (total, per split, per shard, shards listed at all): a wrong ``len()`` of a
dataset cannot go unnoticed. A manifest written before the checksum existed is read with a
warning; ``xnlos simulate --repair DIR`` (or any resume) rewrites it with one.
"""
from __future__ import annotations

import hashlib
import json
import time
import warnings
from pathlib import Path
from typing import Any

from xnlos_core.io import atomic_write_text, read_keyed_jsonl

from .config import DatasetConfig
from .plan import Plan
from .shard import READABLE_VERSIONS, SCHEMA_VERSION, DatasetError

MANIFEST, LOG, SHARD_DIR = "manifest.json", "completed.jsonl", "shards"
FORMAT = "xnlos-dataset"
CHECKSUM = "checksum_sha256"
KEYS = frozenset({"format", "schema_version", "name", "config_sha256", "config", "radar", "versions", "n_maps",
                  "n_scenes", "frames_per_scene", "complete", "splits", "scenes", "shards", "created", "updated",
                  CHECKSUM})


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

    try:
        old = json.loads((out / MANIFEST).read_bytes())
    except (OSError, ValueError, RecursionError):  # none yet, or damaged (being repaired)
        old = {}
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
                   "split": list(plan.split),
                   # a reduced dataset's scenes keep the full plan's indices (not 0 … S−1 in general)
                   **({} if cfg.full_n_maps is None else {"scene_index": list(plan.scene_index)})},
        "shards": shards, "created": old.get("created", now) if isinstance(old, dict) else now, "updated": now,
    }
    manifest[CHECKSUM] = manifest_checksum(manifest)
    atomic_write_text(out / MANIFEST, render_manifest(manifest))


def manifest_checksum(man: dict[str, Any]) -> str:
    """sha256 of the canonical JSON (sorted keys, no spaces, ASCII) of ``man`` without its checksum."""
    body = {k: v for k, v in man.items() if k != CHECKSUM}
    return hashlib.sha256(json.dumps(body, sort_keys=True, separators=(",", ":")).encode()).hexdigest()


def render_manifest(man: dict[str, Any]) -> str:
    """The text of manifest.json exactly as :func:`write_manifest` writes it."""
    return json.dumps(man, indent=1, sort_keys=True)


def read_manifest(out: str | Path, *, check: bool = True) -> dict[str, Any]:
    """The manifest of dataset directory ``out``, checked for format and schema version and, unless
    ``check`` is False (``--verify`` and ``--repair`` collect the problems themselves), for
    integrity (:func:`integrity_problems`): any problem is a DatasetError naming the file."""
    path = Path(out) / MANIFEST
    if not path.is_file():
        raise DatasetError(f"{out}: not an xnlos dataset (no {MANIFEST})")
    try:
        text = path.read_bytes().decode("utf-8")
        man = json.loads(text)
    except (OSError, ValueError, RecursionError) as exc:
        raise DatasetError(f"{path}: unreadable manifest ({type(exc).__name__}: {exc}); repair with: "
                           f"xnlos simulate CONFIG --out {out} --repair") from None
    if not isinstance(man, dict):
        raise DatasetError(f"{path}: the manifest holds a JSON {type(man).__name__}, expected an object")
    if man.get("format") != FORMAT:
        raise DatasetError(f"{path}: not an xnlos dataset manifest (format {man.get('format')!r})")
    if man.get("schema_version") not in READABLE_VERSIONS:
        raise DatasetError(f"{path}: dataset schema version {man.get('schema_version')}; this xnlos reads "
                           f"versions {', '.join(map(str, READABLE_VERSIONS))} (regenerate it with this "
                           "version's xnlos simulate)")
    if check:
        problems = integrity_problems(man, text)
        if problems:
            raise DatasetError(f"{path}: {'; '.join(problems)}; check with: xnlos simulate --verify {out}, "
                               f"repair with: xnlos simulate --repair {out}")
        if CHECKSUM not in man:
            warnings.warn(f"{path}: manifest written before manifests carried a checksum; its integrity is not "
                          f"checked (add one with: xnlos simulate --repair {out})", UserWarning, stacklevel=2)
    return man


def integrity_problems(man: dict[str, Any], text: str | None = None) -> list[str]:
    """What is wrong with a parsed manifest (``text``: the file's text): checksum, bytes, unknown
    keys, structure and map counts. Empty when it is whole and consistent with itself."""
    problems = []
    unknown = sorted(set(man) - KEYS)
    if unknown:
        problems.append(f"unknown key(s) {', '.join(map(repr, unknown))} (xnlos writes {', '.join(sorted(KEYS))})")
    if CHECKSUM in man:
        got = manifest_checksum(man)
        if man[CHECKSUM] != got:
            problems.append(f"checksum mismatch (content sha256 {got[:12]}…, recorded "
                            f"{str(man[CHECKSUM])[:12]}…): edited or corrupt")
        elif text is not None and text != render_manifest(man):
            problems.append("the file's bytes are not those xnlos writes for its content: edited or corrupt")
    problems += _count_problems(man)
    return problems


def _is_count(v) -> bool:
    return isinstance(v, int) and not isinstance(v, bool) and v >= 0


def _count_problems(man: dict[str, Any]) -> list[str]:
    """Structure and map counts: shards listed, n_maps per shard, per split and in total agree."""
    shards, n = man.get("shards"), man.get("n_maps")
    if not _is_count(n):
        return [f"n_maps = {n!r}, expected an integer ≥ 0"]
    if not isinstance(shards, list) or not all(
            isinstance(s, dict) and isinstance(s.get("name"), str) and _is_count(s.get("n_maps"))
            and (s.get("sha256") is None or isinstance(s.get("sha256"), str)) for s in shards):
        return ["shards: expected a list of {name, split, n_maps, sha256, …} records"]
    out = []
    if not shards and n:
        out.append(f"no shards listed but n_maps = {n}")
    total = sum(s["n_maps"] for s in shards)
    if shards and total != n:
        out.append(f"the shards hold {total} maps in all but n_maps = {n}")
    cfg = man.get("config")
    if isinstance(cfg, dict) and cfg.get("n_maps") != n:
        out.append(f"n_maps = {n} but the config's n_maps = {cfg.get('n_maps')!r}")
    names = [s["name"] for s in shards]
    if len(set(names)) != len(names):
        out.append("a shard is listed twice")
    splits = man.get("splits")
    if isinstance(splits, dict):
        for sp, rec in splits.items():
            want = sum(s["n_maps"] for s in shards if s.get("split") == sp)
            if not isinstance(rec, dict) or rec.get("n_maps") != want:
                out.append(f"splits.{sp}.n_maps = {rec.get('n_maps') if isinstance(rec, dict) else rec!r} but "
                           f"its shards hold {want} maps")
    return out


def read_log(out: str | Path) -> dict[str, dict]:
    """shard name → record of ``out/completed.jsonl``, every line checked
    (:func:`xnlos_core.io.read_keyed_jsonl`: torn last line and repeated lines repaired, anything
    else refused naming the line)."""
    def check(v):
        return None if isinstance(v, str) and v else "a shard file name"

    return read_keyed_jsonl(Path(out) / LOG, "shard", check=check)


def completed_records(out: str | Path, man: dict[str, Any]) -> dict[str, dict]:
    """name → {sha256, …} of finished shards: the manifest's, plus log lines it may not show yet.
    A shard whose log line and manifest entry disagree (sha256 or n_maps) is a DatasetError."""
    recs = {s["name"]: {"sha256": s["sha256"], "n_maps": s["n_maps"]} for s in man["shards"] if s.get("sha256")}
    planned = {s["name"]: s for s in man["shards"]}
    for name, r in read_log(out).items():
        if r.get("config_sha256") != man.get("config_sha256") or name not in planned:
            continue
        for key in ("sha256", "n_maps"):
            if name in recs and r.get(key) != recs[name][key]:
                raise DatasetError(f"{Path(out) / LOG}: shard {name}: {key} {r.get(key)!r} but {MANIFEST} records "
                                   f"{recs[name][key]!r}; check with: xnlos simulate --verify {out}")
        if r.get("n_maps") != planned[name]["n_maps"]:
            raise DatasetError(f"{Path(out) / LOG}: shard {name} holds {r.get('n_maps')!r} maps but {MANIFEST} "
                               f"plans {planned[name]['n_maps']}; check with: xnlos simulate --verify {out}")
        recs[name] = r
    return recs


def manifest_config(out: str | Path, *, repair: bool = False) -> DatasetConfig:
    """The (resolved) config stored in ``out``'s manifest, e.g. to repair without the TOML file.

    repair: a manifest that fails its integrity check is still used when its config hashes to its
    recorded ``config_sha256`` (the rest of the manifest is then rebuilt from that config)."""
    from xnlos_core.config import validate_model

    path = Path(out) / MANIFEST
    man = read_manifest(out, check=not repair)
    try:
        cfg = validate_model(DatasetConfig, man["config"], source=str(path), prefix="config")
    except (KeyError, TypeError) as exc:
        raise DatasetError(f"{path}: no usable config ({type(exc).__name__}: {exc}); repair with the config "
                           f"file: xnlos simulate CONFIG --out {out} --repair") from None
    if repair and integrity_problems(man) and cfg.digest() != man.get("config_sha256"):
        raise DatasetError(f"{path}: the manifest is damaged and so is its config (its hash differs from the "
                           f"recorded config_sha256); repair with the config file: xnlos simulate CONFIG "
                           f"--out {out} --repair")
    return cfg
