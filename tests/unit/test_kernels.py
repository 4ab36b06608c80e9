"""The discrete outcomes of the numerically sensitive stages are the same under every OpenBLAS
kernel this processor can run and under one or two BLAS threads (``tests/kernels/outcomes.py`` in a
subprocess per combination), and they are the right ones (pinned)."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

KERNELS_DIR = Path(__file__).resolve().parents[1] / "kernels"
sys.path.insert(0, str(KERNELS_DIR))
from coretypes import runnable  # noqa: E402

EXPECTED = {
    "association": {"pairs": [[0, 0], [1, 1], [2, 2]]},
    "cfar": {"peaks": 339, "strong": 2},
    "corners": {"L_exact": [40, 40], "L_noisy": [40, 40], "line_exact": [60]},
    "motion": {"braking": ["vx'=vx", "vy'=vy"], "braking_doppler": ["vx'=vx", "vy'=vy"],
               "braking_profiled": ["vx'=vx", "vy'=vy"], "noisy_braking": ["vx'=vx", "vy'=vy"],
               "straight_profiled": [], "turn": ["vx'=vy", "vy'=vx"]},
    "walls": {"L": ["line", "line"], "arc": ["arc"], "line": ["line"]},
}


def outcomes(kernel: str | None, threads: int) -> dict:
    env = dict(os.environ, OPENBLAS_NUM_THREADS=str(threads))
    env.pop("OPENBLAS_CORETYPE", None)
    if kernel:
        env["OPENBLAS_CORETYPE"] = kernel
    out = subprocess.run([sys.executable, str(KERNELS_DIR / "outcomes.py")], env=env, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, f"{kernel} × {threads}: {out.stderr[-2000:]}"
    return json.loads(out.stdout)


def test_outcomes_are_right_with_the_default_kernel():
    assert outcomes(None, 1) == EXPECTED


@pytest.mark.skipif(not runnable()[0], reason="no OpenBLAS kernel can be forced on this processor")
def test_same_outcomes_under_every_runnable_kernel():
    kernels, _ = runnable()
    runs = {(k, 1): outcomes(k, 1) for k in kernels}
    runs[(kernels[-1], 2)] = outcomes(kernels[-1], 2)  # the widest kernel with two BLAS threads
    differ = {key: got for key, got in runs.items() if got != EXPECTED}
    assert not differ, f"outcomes differ from the pinned ones under {sorted(differ)}: {differ}"
