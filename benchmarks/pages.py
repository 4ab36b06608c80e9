"""Benchmark pages whose tables a seeded command regenerates: the registry, the table markers, the check.

A page marks each deterministic table (the same on every rerun of its seeded command, up to the
rounding of its last printed digit) between two HTML comments, invisible on the rendered page::

    <!-- table:NAME -->
    | … | … |
    <!-- /table -->

Timings (machine- and load-dependent) stay outside the markers. ``benchmarks/pages.toml`` names each
page's seeded command; :func:`compare` checks a committed page against a rerun, table by table, cell
by cell: numbers equal within one unit of the committed cell's last printed digit (a value at a
rounding boundary may print either way on another processor), other text exactly.
"""
from __future__ import annotations

import dataclasses
import re
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
REGISTRY = ROOT / "benchmarks" / "pages.toml"
TABLE = re.compile(r"<!-- table:([A-Za-z0-9_.-]+) -->\n(.*?)<!-- /table -->", re.S)
NUMBER = re.compile(r"^([-+−]?)(\d+)(?:\.(\d+))?(?:[eE]([+-]?\d+))?([×%°]?)$")


def marked(name: str, lines: list[str]) -> list[str]:
    """``lines`` (a Markdown table) between the markers of table ``name``, for a page's text."""
    return [f"<!-- table:{name} -->", *lines, "<!-- /table -->"]


def tables(text: str) -> dict[str, list[str]]:
    """name → the lines of each marked table of a page's ``text`` (a page names each table once)."""
    out: dict[str, list[str]] = {}
    for m in TABLE.finditer(text):
        if m.group(1) in out:
            raise ValueError(f"table {m.group(1)!r} is marked twice")
        out[m.group(1)] = [ln.rstrip() for ln in m.group(2).strip("\n").splitlines()]
    return out


def _number(cell: str) -> tuple[float, float] | None:
    """(value, one unit of its last printed digit) of a numeric cell, or None for text."""
    m = NUMBER.match(cell.strip().replace(",", ""))
    if not m:
        return None
    sign, whole, frac, exp, _ = m.groups()
    frac = frac or ""
    value = float(f"{'-' if sign in ('-', '−') else ''}{whole}.{frac or '0'}e{exp or 0}")
    return value, 10.0 ** (int(exp or 0) - len(frac))


EMBEDDED = re.compile(r"[-+−]?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")


def cells_agree(committed: str, rerun: str) -> bool:
    """One table cell: numbers within one unit of the committed cell's last digit, text exactly.
    A cell of text with numbers in it ("11.2 dB at 82.3 m") agrees when its text between the numbers
    is the same and each number agrees so."""
    a, b = _number(committed), _number(rerun)
    if a is not None and b is not None:
        unit_a = NUMBER.match(committed.strip().replace(",", "")).group(5)
        unit_b = NUMBER.match(rerun.strip().replace(",", "")).group(5)
        return unit_a == unit_b and abs(a[0] - b[0]) <= a[1] * (1 + 1e-9)
    ca, cb = committed.strip(), rerun.strip()
    if EMBEDDED.split(ca) != EMBEDDED.split(cb):
        return False
    na, nb = EMBEDDED.findall(ca), EMBEDDED.findall(cb)
    return all((x == y) or (_number(x) is not None and _number(y) is not None and cells_agree(x, y))
               for x, y in zip(na, nb))


def compare(committed: str, rerun: str) -> list[str]:
    """Differences between the marked tables of two page texts, each a line naming the table, row and
    cell ([] when they agree). A table missing from either side is a difference."""
    old, new = tables(committed), tables(rerun)
    out = [f"table {n!r}: only in the committed page" for n in sorted(set(old) - set(new))]
    out += [f"table {n!r}: only in the rerun" for n in sorted(set(new) - set(old))]
    for name in sorted(set(old) & set(new)):
        a, b = old[name], new[name]
        if len(a) != len(b):
            out.append(f"table {name!r}: {len(a)} lines committed, {len(b)} in the rerun")
            continue
        for i, (la, lb) in enumerate(zip(a, b)):
            ca, cb = la.split("|"), lb.split("|")
            if len(ca) != len(cb) or not all(cells_agree(x, y) for x, y in zip(ca, cb)):
                out.append(f"table {name!r}, line {i + 1}:\n  committed: {la}\n  rerun:     {lb}")
    return out


@dataclasses.dataclass(frozen=True)
class Page:
    """One registry entry: page ``name`` (benchmarks/NAME.md), written by ``script`` with ``args``
    and ``--out PATH``; ``check_args`` are added when only the tables are wanted (e.g. timings
    skipped); ``slow``: the check takes more than ~10 s (its test is marked slow)."""

    name: str
    script: str
    args: tuple[str, ...] = ()
    check_args: tuple[str, ...] = ()
    slow: bool = False

    @property
    def path(self) -> Path:
        return ROOT / "benchmarks" / f"{self.name}.md"

    def command(self, out: Path, check: bool = False) -> list[str]:
        """The script's arguments (after the interpreter) that write the page to ``out``."""
        return [str(ROOT / self.script), *self.args, *(self.check_args if check else ()), "--out", str(out)]


def registry(path: Path = REGISTRY) -> dict[str, Page]:
    """The pages of ``benchmarks/pages.toml``, by name (ValueError naming an unknown key)."""
    data = tomllib.loads(path.read_text(encoding="utf-8"))
    out = {}
    for name, entry in data.get("pages", {}).items():
        extra = set(entry) - {"script", "args", "check_args", "slow"}
        if extra or "script" not in entry:
            raise ValueError(f"{path}: [pages.{name}] needs 'script' and takes args, check_args, slow; "
                             f"got {sorted(entry)}")
        out[name] = Page(name, entry["script"], tuple(entry.get("args", ())), tuple(entry.get("check_args", ())),
                         bool(entry.get("slow", False)))
    return out
