"""Thread policy: BLAS thread pools limited while the pipeline's stages run, so BLAS and torch never
oversubscribe the cores.

Why: OpenBLAS worker threads, once woken by a numpy call (the forward model, the wall fit), keep
spinning for a while after the call returns; a torch forward pass that follows competes with them
for the same cores. On 2 shared cores the Swin-UNet detector of the demo took ~65 ms (median) per
frame in a running pipeline against ~25–30 ms with one BLAS thread (``benchmarks/pipeline_speed.py``,
see ``benchmarks/pipeline_speed.md``); the numpy stages themselves were no slower with one thread.

The policy (``[run] blas_threads``, default 1): every BLAS library loaded in the process (numpy's and
scipy's OpenBLAS, MKL, …) runs with at most that many threads while a frame is simulated and while
:meth:`xnlos_core.pipeline.Pipeline.process` runs; the previous limits are restored afterwards, so code
around the pipeline keeps its own setting. ``blas_threads = 0`` leaves BLAS alone (its own default or
``OPENBLAS_NUM_THREADS`` / ``OMP_NUM_THREADS`` from the environment). Torch's intra-op threads are the
learned detector's business (its ``threads`` parameter): the core imports no torch. Dataset workers
use the same limit (:mod:`sims.dataset.shard`).

BLAS limits are process-wide, not per thread: two pipelines processing frames at once in threads of
one process would restore each other's limits out of order. Nothing in xnlos does that (parallel
work runs in processes); code that does should set ``blas_threads = 0`` and limit BLAS itself.
"""
from __future__ import annotations

import sys
from contextlib import AbstractContextManager, nullcontext

from threadpoolctl import ThreadpoolController

from .errors import ConfigError

_cache: tuple[int, ThreadpoolController] | None = None


def _blas_controller() -> ThreadpoolController:
    """Controller of the BLAS libraries loaded now. Finding them walks every loaded shared object
    (~1 ms), so the controller is kept until the set of imported modules changes: a BLAS library is
    loaded by an import (numpy, scipy.linalg, torch), and one loaded later would otherwise be missed."""
    global _cache
    n = len(sys.modules)
    if _cache is None or _cache[0] != n:
        _cache = (n, ThreadpoolController().select(user_api="blas"))
    return _cache[1]


def blas_limit(threads: int) -> AbstractContextManager:
    """Context in which every loaded BLAS library uses at most ``threads`` threads (≥ 1); the limits
    in force before are restored on exit. ``threads = 0``: a no-op context (BLAS left as it is).

    Raises ConfigError for a negative count (the config bounds it; this guards direct callers)."""
    if threads < 0:
        raise ConfigError(f"blas threads {threads}: must be ≥ 0 (0 leaves BLAS as it is)")
    if threads == 0:
        return nullcontext()
    return _blas_controller().limit(limits=threads, user_api="blas")
