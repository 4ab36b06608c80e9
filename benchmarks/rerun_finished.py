"""Wall time of re-running a finished ``xnlos run`` (≤ 1 s) and of ``xnlos --help``,
old code against new, alternated back to back, and ``python -X importtime`` totals of ``--help``.

Usage (from the checkout's root): python benchmarks/rerun_finished.py OLD_ROOT [REPEATS]
OLD_ROOT: a checkout of the code to compare with (e.g. /work/main), imported through PYTHONPATH with
that folder as the working directory; the new code is this checkout. Each side first makes its own
finished run of configs/pipelines/corner_emcee.toml in a temporary folder (not timed)."""
from __future__ import annotations

import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

CONFIG = "configs/pipelines/corner_emcee.toml"


def _run(root: Path, args: list[str], env_extra: dict | None = None) -> tuple[float, str]:
    env = {**os.environ, "PYTHONPATH": str(root), **(env_extra or {})}
    t0 = time.perf_counter()
    done = subprocess.run([sys.executable, *args], cwd=root, env=env, capture_output=True, text=True, check=True)
    return time.perf_counter() - t0, done.stderr


def _importtime_s(root: Path) -> float:
    """Cumulative import time [s] of the top-level imports of ``python -X importtime -m xnlos_core --help``."""
    _, err = _run(root, ["-X", "importtime", "-m", "xnlos_core", "--help"])
    rows = [re.match(r"import time:\s+\d+ \|\s+(\d+) \|( *)(\S+)", ln) for ln in err.splitlines()]
    return sum(int(m.group(1)) for m in rows if m and len(m.group(2)) == 1) / 1e6


def main() -> None:
    old, new = Path(sys.argv[1]).resolve(), Path.cwd().resolve()
    repeats = int(sys.argv[2]) if len(sys.argv) > 2 else 5
    tmp = Path(tempfile.mkdtemp(prefix="rerun_finished_"))
    sides = {"old": old, "new": new}
    for side, root in sides.items():  # the finished runs (and the new side's outputs.json)
        for _ in range(2):
            _run(root, ["-m", "xnlos_core", "run", CONFIG, "--out", str(tmp / side), "-q"])
    times: dict[str, dict[str, list[float]]] = {s: {"rerun": [], "help": [], "importtime": []} for s in sides}
    for _ in range(repeats):
        for side, root in sides.items():
            times[side]["rerun"].append(_run(root, ["-m", "xnlos_core", "run", CONFIG, "--out", str(tmp / side), "-q"])[0])
            times[side]["help"].append(_run(root, ["-m", "xnlos_core", "--help"])[0])
            times[side]["importtime"].append(_importtime_s(root))
    print(f"load average before/after: see the .md; repeats {repeats}, alternated old/new")
    print("| what | old median [s] | new median [s] | old/new |")
    print("|---|---:|---:|---:|")
    for what in ("rerun", "help", "importtime"):
        o, n = statistics.median(times["old"][what]), statistics.median(times["new"][what])
        print(f"| {what} | {o:.2f} | {n:.2f} | {o / n:.2f}× |")
    for side in sides:
        print(side, {k: [round(x, 2) for x in v] for k, v in times[side].items()})


if __name__ == "__main__":
    main()
