"""``xnlos simulate --verify``: re-hash every finished shard; list corrupt, missing and pending ones."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from .manifest import SHARD_DIR, check_files, completed_records, read_manifest


@dataclass
class VerifyReport:
    """Shard names by state: ok (verified), corrupt, missing (recorded, file gone), pending (not built)."""

    out: str
    ok: list[str] = field(default_factory=list)
    corrupt: dict[str, str] = field(default_factory=dict)
    missing: list[str] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)

    @property
    def healthy(self) -> bool:
        """No corrupt or missing shard (pending ones are a run still to finish)."""
        return not self.corrupt and not self.missing

    def render(self) -> str:
        lines = [f"{self.out}: {len(self.ok)} shard(s) ok, {len(self.corrupt)} corrupt, "
                 f"{len(self.missing)} missing, {len(self.pending)} not yet generated"]
        lines += [f"corrupt: {SHARD_DIR}/{n}: {why}" for n, why in sorted(self.corrupt.items())]
        lines += [f"missing: {SHARD_DIR}/{n}" for n in self.missing]
        if self.pending:
            more = " …" if len(self.pending) > 5 else ""
            lines.append(f"not yet generated: {', '.join(self.pending[:5])}{more}")
        if not self.healthy:
            lines.append("repair with: xnlos simulate --repair " + self.out)
        return "\n".join(lines)


def verify_dataset(out: str | Path) -> VerifyReport:
    """Re-hash every finished shard of ``out`` against its recorded sha256."""
    man = read_manifest(out)
    recs = completed_records(out, man)
    rep = VerifyReport(str(out))
    bad = check_files(Path(out) / SHARD_DIR, recs)
    for s in man["shards"]:
        n = s["name"]
        if n not in recs:
            rep.pending.append(n)
        elif n not in bad:
            rep.ok.append(n)
        elif bad[n] == "missing":
            rep.missing.append(n)
        else:
            rep.corrupt[n] = bad[n]
    return rep
