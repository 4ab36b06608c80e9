"""Thread policy: how many threads torch, BLAS and numba run, and how their idle threads wait, so
that the pipeline neither oversubscribes its cores nor collapses when other processes share them.

Two parts.

**Process policy** (:func:`apply_process_policy`, applied when ``xnlos_core`` is first imported, so
before numpy, numba or torch load their thread libraries: every entry point — ``xnlos``, ``python -m
xnlos_core``, the benchmarks — imports the package first). Each variable is set only where the
environment does not set it already (``os.environ.setdefault``), so a user's explicit choice wins:

- ``OMP_NUM_THREADS`` and ``NUMBA_NUM_THREADS``: the cores this process may actually use
  (:func:`available_cores`: the CPU affinity mask, one per physical core, capped by a cgroup CPU
  quota), not ``os.cpu_count()``. torch's intra-op threads, OpenBLAS's default and numba's pool
  follow them (``MKL_NUM_THREADS`` / ``OPENBLAS_NUM_THREADS`` set by the user still win for those).

Threads of the wrong count cost: torch and numba size their pools by the machine's cores, so in a
container limited to fewer cores (affinity or a CPU quota) their extra threads only wait for each
other. How the threads wait is left to OpenMP (spinning briefly at each barrier, the fastest on a
machine of one's own); when other processes share the cores, torch's count follows the cores they
leave free, measured frame by frame (:mod:`xnlos_core.core_share`), which keeps the pipeline from
collapsing without slowing a quiet machine. ``OMP_WAIT_POLICY=PASSIVE`` exported by the user (kept,
like every variable set already) trades 9–48 % of quiet speed for a little more under load
(``benchmarks/pipeline_speed.md``).

The process policy takes effect for a library only if it is set before that library is loaded:
torch or numba imported before ``xnlos_core`` keep their defaults (:data:`POLICY` records them in
``loaded_before``). Export the variables in the shell (or import ``xnlos_core`` first) in that case.
``XNLOS_THREAD_POLICY=0`` (or ``off``) in the environment leaves all of them alone.

**BLAS during the stages** (:func:`blas_limit`, ``[run] blas_threads``, default 1): every BLAS
library loaded in the process (numpy's and scipy's OpenBLAS, MKL, …) runs with at most that many
threads while a frame is simulated and while :meth:`xnlos_core.pipeline.Pipeline.process` runs; the
previous limits are restored afterwards, so code around the pipeline keeps its own setting.
``blas_threads = 0`` leaves BLAS alone (its own default or ``OPENBLAS_NUM_THREADS`` /
``OMP_NUM_THREADS`` from the environment). Why: OpenBLAS worker threads, once woken by a numpy call
(the forward model, the wall fit), keep spinning (yielding) for a while after the call returns; a
torch forward pass that follows competes with them for the same cores. On 2 shared cores the
Swin-UNet detector of the demo took ~65 ms (median) per frame in a running pipeline against
~25–30 ms with one BLAS thread; the numpy stages themselves were no slower with one thread.
Dataset workers use the same limit (:mod:`sims.dataset.shard`).

Torch's intra-op thread count is otherwise the learned detector's ``threads`` parameter and the
training configs' ``threads`` (None: the process policy's count); both set it explicitly when given.

BLAS limits are process-wide, not per thread: two pipelines processing frames at once in threads of
one process would restore each other's limits out of order. Nothing in xnlos does that (parallel
work runs in processes); code that does should set ``blas_threads = 0`` and limit BLAS itself.
"""
from __future__ import annotations

import math
import os
import sys
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path

from threadpoolctl import ThreadpoolController

from .errors import ConfigError

OPT_OUT = "XNLOS_THREAD_POLICY"  # "0" / "off" / "false" / "no": the process policy sets nothing
THREAD_LIBRARIES = ("torch", "numba", "numpy")  # loaded before the policy: they read their variables already
POLICY: dict = {}  # what apply_process_policy found and did (see there); empty until it runs


def _read(path: str | Path) -> str | None:
    try:
        return Path(path).read_text().strip()
    except (OSError, UnicodeDecodeError):
        return None


def _physical_cores(cpus: set[int]) -> int:
    """Physical cores among the logical CPUs ``cpus`` (hyper-threads of one core counted once), from
    Linux's sysfs topology; ``len(cpus)`` where the topology cannot be read."""
    cores = set()
    for c in cpus:
        base = f"/sys/devices/system/cpu/cpu{c}/topology/"
        package, core = _read(base + "physical_package_id"), _read(base + "core_id")
        if package is None or core is None:
            return len(cpus)
        cores.add((package, core))
    return len(cores) or len(cpus)


def cgroup_cpu_quota() -> float | None:
    """CPUs' worth of time the process's cgroup may use (quota / period; e.g. 1.5), the smallest over
    the cgroup and its parents, v2 (``cpu.max``) or v1 (``cpu.cfs_quota_us``); None without a quota."""
    quotas = []
    lines = (_read("/proc/self/cgroup") or "").splitlines()
    for line in lines:
        _, controllers, rel = (line.split(":", 2) + ["", ""])[:3]
        if controllers == "":  # v2: unified hierarchy
            roots, files = ["/sys/fs/cgroup"], None
        elif "cpu" in controllers.split(","):
            roots, files = ["/sys/fs/cgroup/cpu", "/sys/fs/cgroup/cpu,cpuacct"], ("cpu.cfs_quota_us",
                                                                                     "cpu.cfs_period_us")
        else:
            continue
        for root in roots:
            d = Path(root + rel)
            while True:
                if files is None:
                    parts = (_read(d / "cpu.max") or "").split()
                    if len(parts) == 2 and parts[0] != "max":
                        quotas.append((parts[0], parts[1]))
                else:
                    quotas.append((_read(d / files[0]), _read(d / files[1])))
                if d == Path(root) or d.parent == d:
                    break
                d = d.parent
    best = None
    for q, p in quotas:
        try:
            q, p = int(q), int(p)
        except (TypeError, ValueError):
            continue
        if q > 0 and p > 0:
            best = q / p if best is None else min(best, q / p)
    return best


def available_cores() -> int:
    """Cores this process can run threads on (≥ 1): the physical cores in its CPU affinity mask
    (``os.sched_getaffinity``; ``os.cpu_count()`` where that does not exist), at most the cgroup CPU
    quota rounded up. One thread per physical core is also torch's own default on a machine that is
    not restricted; hyper-threads add nothing to its matrix kernels."""
    try:
        cpus = os.sched_getaffinity(0)
        n = _physical_cores(cpus) if sys.platform.startswith("linux") else len(cpus)
    except (AttributeError, OSError):
        n = os.cpu_count() or 1
    quota = cgroup_cpu_quota()
    if quota is not None:
        n = min(n, math.ceil(quota))
    return max(1, n)


def policy_environment(cores: int) -> dict[str, str]:
    """The variables of the process policy for ``cores`` threads (module doc)."""
    return {"OMP_NUM_THREADS": str(cores), "NUMBA_NUM_THREADS": str(cores)}


def apply_process_policy() -> dict:
    """Set the process policy's variables that the environment does not set (module doc); once per
    process, later calls return the same record. Returns (and keeps in :data:`POLICY`) ``cores``
    (:func:`available_cores`), ``set`` (the variables this call set, name → value), ``kept`` (those the
    environment already had, name → value), ``loaded_before`` (thread libraries imported before it,
    whose pools the variables no longer reach) and ``off`` (True under ``XNLOS_THREAD_POLICY=0``)."""
    if POLICY:
        return POLICY
    off = os.environ.get(OPT_OUT, "").strip().lower() in ("0", "off", "false", "no")
    cores = available_cores()
    done: dict[str, str] = {}
    kept: dict[str, str] = {}
    if not off:
        for name, value in policy_environment(cores).items():
            if name in os.environ:
                kept[name] = os.environ[name]
            else:
                os.environ[name] = done[name] = value
    POLICY.update(cores=cores, set=done, kept=kept, off=off,
                  loaded_before=[m for m in THREAD_LIBRARIES if m in sys.modules])
    return POLICY


def describe() -> str:
    """One line on the process policy in force, for benchmark headers and logs."""
    p = apply_process_policy()
    if p["off"]:
        return f"process thread policy off ({OPT_OUT}); {p['cores']} core(s) available"
    env = {**p["set"], **p["kept"]}
    text = ", ".join(f"{k}={env[k]}" + ("" if k in p["set"] else " (environment)") for k in env)
    late = f"; loaded before it: {', '.join(p['loaded_before'])}" if p["loaded_before"] else ""
    return f"{p['cores']} core(s) available; {text}{late}"


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
