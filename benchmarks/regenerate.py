"""Regenerate the benchmark pages of ``benchmarks/pages.toml``, or check their tables against a rerun.

    python -m benchmarks.regenerate [page ...]            # rerun each page's seeded command, rewrite the page
    python -m benchmarks.regenerate --check [page ...]    # rerun into a temporary file, compare the tables
    python -m benchmarks.regenerate --list

No page named: every registered page. ``--check`` writes nothing; it compares only the tables a page
marks as deterministic (:mod:`benchmarks.pages`) and exits 1 naming each difference. The commands
run with this interpreter, the repository root on PYTHONPATH and one BLAS thread.
"""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

try:
    from benchmarks.pages import ROOT, Page, compare, registry
except ModuleNotFoundError:  # run as a file: benchmarks/regenerate.py
    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from benchmarks.pages import ROOT, Page, compare, registry


def run(page: Page, out: Path, check: bool = False) -> None:
    """Run ``page``'s seeded command writing to ``out`` (RuntimeError with its output when it fails)."""
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([str(ROOT), os.environ.get("PYTHONPATH", "")]).rstrip(os.pathsep),
           "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "MPLBACKEND": "Agg"}
    done = subprocess.run([sys.executable, *page.command(out, check)], cwd=ROOT, env=env, capture_output=True,
                          text=True)
    if done.returncode:
        raise RuntimeError(f"{page.name}: {' '.join(page.command(out, check))} failed ({done.returncode}):\n"
                           f"{done.stdout[-2000:]}{done.stderr[-4000:]}")


def check(page: Page) -> list[str]:
    """Differences of ``page``'s committed tables from a rerun ([] when they agree)."""
    if not page.path.exists():
        return [f"{page.path.name}: no committed page"]
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp) / page.path.name
        run(page, out, check=True)
        return compare(page.path.read_text(encoding="utf-8"), out.read_text(encoding="utf-8"))


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pages", nargs="*", help="page names (default: every registered page)")
    ap.add_argument("--check", action="store_true", help="compare the committed tables with a rerun; write nothing")
    ap.add_argument("--list", action="store_true", help="list the registered pages and their commands")
    args = ap.parse_args(argv)
    pages = registry()
    unknown = [p for p in args.pages if p not in pages]
    if unknown:
        ap.error(f"unknown page(s) {unknown}; registered: {sorted(pages)}")
    chosen = [pages[p] for p in args.pages] if args.pages else list(pages.values())
    if args.list:
        for p in chosen:
            print(f"{p.name}{' (slow)' if p.slow else ''}: python {' '.join([p.script, *p.args])}")
        return 0
    failed = 0
    for p in chosen:
        t0 = time.perf_counter()
        if args.check:
            diff = check(p)
            failed += bool(diff)
            print(f"{p.name}: {'differs' if diff else 'tables match'} ({time.perf_counter() - t0:.1f} s)")
            for d in diff:
                print("  " + d)
        else:
            run(p, p.path)
            print(f"{p.name}: wrote {p.path.relative_to(ROOT)} ({time.perf_counter() - t0:.1f} s)")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
