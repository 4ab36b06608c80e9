"""``xnlos simulate --verify``: the manifest's integrity, then every finished shard re-hashed and its
maps counted; lists problems and corrupt, missing and pending shards."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from xnlos_core.errors import XnlosError

from .manifest import (CHECKSUM, LOG, MANIFEST, SHARD_DIR, check_files, completed_records, integrity_problems,
                       manifest_config, read_log, read_manifest)


@dataclass
class VerifyReport:
    """Shard names by state: ok (verified), corrupt, missing (recorded, file gone), pending (not built);
    problems: inconsistencies of the manifest with itself, its config, the log or the shard files."""

    out: str
    ok: list[str] = field(default_factory=list)
    corrupt: dict[str, str] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    problems: list[str] = field(default_factory=list)

    @property
    def healthy(self) -> bool:
        """No problem and no corrupt or missing shard (pending ones are a run still to finish)."""
        return not self.corrupt and not self.missing and not self.problems

    def render(self) -> str:
        lines = [f"{self.out}: {len(self.ok)} shard(s) ok, {len(self.corrupt)} corrupt, "
                 f"{len(self.missing)} missing, {len(self.pending)} not yet generated, "
                 f"{len(self.problems)} problem(s)"]
        lines += [f"problem: {p}" for p in self.problems]
        lines += [f"corrupt: {SHARD_DIR}/{n}: {why}" for n, why in sorted(self.corrupt.items())]
        lines += [f"missing: {SHARD_DIR}/{n}" for n in self.missing]
        if self.pending:
            more = " …" if len(self.pending) > 5 else ""
            lines.append(f"not yet generated: {', '.join(self.pending[:5])}{more}")
        if not self.healthy:
            lines.append("repair with: xnlos simulate --repair " + self.out)
        return "\n".join(lines)


def verify_dataset(out: str | Path) -> VerifyReport:
    """Check ``out``: the manifest's checksum and counts, its shard list against the plan of its own
    config, completed.jsonl against the manifest, and every finished shard's sha256 and map count."""
    from .plan import make_plan

    out = Path(out)
    man = read_manifest(out, check=False)
    rep = VerifyReport(str(out))
    text = (out / MANIFEST).read_bytes().decode("utf-8")
    rep.problems += [f"{MANIFEST}: {p}" for p in integrity_problems(man, text)]
    if CHECKSUM not in man:
        rep.problems.append(f"{MANIFEST}: no checksum (written by an older xnlos); --repair adds one")
    shards = man.get("shards")
    if not isinstance(shards, list) or not all(isinstance(s, dict) and isinstance(s.get("name"), str)
                                               and isinstance(s.get("n_maps"), int) for s in shards):
        return rep  # no usable shard list to go on with (already a problem)
    try:  # what the shard list should be, from the manifest's own config
        plan = make_plan(manifest_config(out, repair=True))
        want = [(s.name, s.split, s.n_maps, list(s.scenes)) for s in plan.shards]
        have = [(s["name"], s.get("split"), s["n_maps"], s.get("scene_index")) for s in shards]
        if want != have:
            rep.problems.append(f"{MANIFEST}: the shards listed differ from the plan of its config "
                                f"({len(have)} listed, {len(want)} planned)")
    except XnlosError as exc:
        rep.problems.append(str(exc))
    try:
        recs = completed_records(out, man)
        log = read_log(out)
    except XnlosError as exc:
        rep.problems.append(str(exc))
        recs, log = {s["name"]: s for s in man["shards"] if s.get("sha256")}, {}
    listed = {s["name"]: s for s in man["shards"]}
    for name, s in listed.items():
        if s.get("sha256") and name not in log:
            rep.problems.append(f"{LOG}: no line for shard {name}, which {MANIFEST} records as finished")
    bad = check_files(out / SHARD_DIR, recs)
    for s in man["shards"]:
        n = s["name"]
        if n not in recs:
            rep.pending.append(n)
        elif n in bad:
            if bad[n] == "missing":
                rep.missing.append(n)
            else:
                rep.corrupt[n] = bad[n]
        else:
            why = _shard_problem(out / SHARD_DIR / n, s, man)
            if why:
                rep.problems.append(f"{SHARD_DIR}/{n}: {why}")
            else:
                rep.ok.append(n)
    complete = not rep.pending
    if man.get("complete") is not complete:
        rep.problems.append(f"{MANIFEST}: complete = {man.get('complete')!r} but {len(rep.pending)} shard(s) are "
                            "not generated")
    return rep


def _shard_problem(path: Path, s: dict, man: dict) -> str | None:
    """Why a shard file whose hash verifies disagrees with its manifest entry (None if it agrees):
    its own name, split, config digest and number of maps."""
    try:
        with np.load(path, allow_pickle=False) as z:
            n = int(z["map_index"].shape[0])
            own = (str(z["shard"]), str(z["split"]), str(z["config_sha256"]))
    except (OSError, KeyError, ValueError) as exc:
        return f"unreadable ({type(exc).__name__}: {exc})"
    if n != s["n_maps"]:
        return f"holds {n} maps but {MANIFEST} records n_maps = {s['n_maps']}"
    if own != (s["name"], s.get("split"), man.get("config_sha256")):
        return f"names itself {own[0]} of split {own[1]}, config {own[2][:12]}…, unlike its {MANIFEST} entry"
    return None
