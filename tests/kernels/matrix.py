"""Run the numerically sensitive tests (marker ``kernels``) under every OpenBLAS kernel this
processor can run × OPENBLAS_NUM_THREADS ∈ {1, 2}, one pytest process each; print a table and exit
non-zero if any combination fails. ``make test-kernels`` calls it.

Usage: python tests/kernels/matrix.py [pytest args...]   (default: -q -m kernels)
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from coretypes import REQUIRED, runnable  # noqa: E402

THREADS = (1, 2)


def main(argv: list[str]) -> int:
    ok, why = runnable()
    args = argv or ["-q", "-m", "kernels", "-p", "no:cacheprovider"]
    rows, failed = [], 0
    for kernel in ok:
        for n in THREADS:
            env = dict(os.environ, OPENBLAS_CORETYPE=kernel, OPENBLAS_NUM_THREADS=str(n))
            t0 = time.monotonic()
            rc = subprocess.run([sys.executable, "-m", "pytest", "-n", "0", *args], env=env).returncode
            rows.append((kernel, n, "pass" if rc == 0 else f"FAIL (rc {rc})", time.monotonic() - t0))
            failed += rc != 0
    print("\nkernel     threads  result        time")
    for kernel, n, res, dt in rows:
        print(f"{kernel:<10} {n:>7}  {res:<12} {dt:6.1f} s")
    for kernel, reason in why.items():
        note = " (required: run the matrix on such a processor too)" if kernel in REQUIRED else ""
        print(f"{kernel:<10} skipped: {reason}{note}")
    if not rows:
        print("no OpenBLAS kernel can be forced on this processor")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
