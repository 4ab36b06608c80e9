"""Torch threads that follow the cores other processes leave free, measured as the pipeline runs.

torch runs its intra-op work on a team of OpenMP threads (one per available core, the process policy
of :mod:`xnlos_core.threads`). With OpenMP's default wait policy a thread that reaches a barrier
spins until the others arrive; when other processes share the cores the thread being waited for is
often descheduled, and the spinning thread burns the time slice that the work needs. Measured on 2
cores with one busy process per core (``benchmarks/pipeline_speed.py --loaded``): the fast
pipeline's processing went from 90 ms to 1,981 ms per frame (22×) on two torch threads, and to
255 ms on one (one thread has no team and no barrier). A passive wait policy for every process
(threads sleep at once) avoids the collapse too, but waking the threads at each of the Swin-UNet's
parallel regions costs 9–48 % of the quiet time (``benchmarks/pipeline_speed.md``).

So the thread count follows the load instead: :func:`adapt_torch_threads`, called at the start of
every frame (:meth:`xnlos_core.pipeline.Pipeline.process`) and every training step
(``plugins.training.optim.step``), measures how many of this process's CPUs other processes kept
busy since the previous call (:class:`CoreShare`: per-CPU busy time from ``/proc/stat`` minus this
process's own CPU time, over the wall time between the calls) and runs torch with the cores left
free, rounded, between 1 and the count torch had when first asked (:class:`TorchThreads`). It goes
down at once and back up only after :data:`RESTORE_AFTER` quiet intervals in a row, so a burst of
load does not make it flap. On a quiet machine nothing changes: the same threads, the same spinning,
the same speed. A user's ``OMP_WAIT_POLICY=PASSIVE`` still works on top (a machine always shared).

Where ``/proc/stat`` cannot be read (not Linux) or the process's CPU share is set by a cgroup quota
rather than by its CPUs (busy CPUs of the host then say nothing about this process's share), the
count is left alone. ``[run] share_cores = false`` and ``XNLOS_THREAD_POLICY=0`` switch it off.
"""
from __future__ import annotations

import os
import sys
import time
from collections.abc import Callable

MIN_INTERVAL = 0.05  # s: a shorter interval holds too few clock ticks (USER_HZ, 100 per s) to measure
RESTORE_AFTER = 3  # intervals in a row with more cores free before torch gets its threads back
KEEP_MARGIN = 0.25  # [cores] the free cores are rounded up from (n − 1) + this: a thread is given up only
# when other processes took more than 3/4 of a core, so background noise (the kernel's threads, a
# hypervisor's steal time, a short job) does not cost a quiet machine its second thread


def _ticks_per_second() -> int:
    try:
        return int(os.sysconf("SC_CLK_TCK"))
    except (AttributeError, ValueError, OSError):
        return 100


def read_proc_stat(path: str = "/proc/stat") -> dict[int, tuple[int, int]] | None:
    """Per logical CPU (its number → (busy, total) clock ticks since boot) from Linux's ``/proc/stat``;
    busy is every state but idle and iowait. None where the file cannot be read or parsed."""
    try:
        with open(path, encoding="ascii") as f:
            lines = f.read().splitlines()
    except (OSError, UnicodeDecodeError):
        return None
    out = {}
    for line in lines:
        if not line.startswith("cpu") or line.startswith("cpu "):
            continue
        name, *fields = line.split()
        try:
            cpu, ticks = int(name[3:]), [int(v) for v in fields[:8]]
        except ValueError:
            return None
        if len(ticks) < 5:
            return None
        total = sum(ticks)
        out[cpu] = (total - ticks[3] - ticks[4], total)
    return out or None


def own_cpu_seconds() -> float:
    """CPU time of this process, all its threads, user + system [s] (children not included)."""
    t = os.times()
    return t.user + t.system


class CoreShare:
    """How many of this process's CPUs other processes kept busy between two :meth:`sample` calls.

    cpus: the logical CPUs this process runs on (default: its affinity mask); read, clock, cpu_time:
    the sources of per-CPU ticks (:func:`read_proc_stat`), wall time [s] and the process's own CPU
    time [s] (:func:`own_cpu_seconds`), replaceable for tests."""

    def __init__(self, cpus: set[int] | None = None, *,
                 read: Callable[[], dict[int, tuple[int, int]] | None] = read_proc_stat,
                 clock: Callable[[], float] = time.monotonic, cpu_time: Callable[[], float] = own_cpu_seconds,
                 ticks_per_second: int | None = None):
        if cpus is None:
            try:
                cpus = set(os.sched_getaffinity(0))
            except (AttributeError, OSError):
                cpus = set(range(os.cpu_count() or 1))
        self.cpus = frozenset(cpus)
        self._read, self._clock, self._cpu_time = read, clock, cpu_time
        self.hz = ticks_per_second or _ticks_per_second()
        self._last: tuple[float, float, int] | None = None

    def _now(self) -> tuple[float, float, int] | None:
        stat = self._read()
        if stat is None or not self.cpus <= stat.keys():
            return None
        return self._clock(), self._cpu_time(), sum(stat[c][0] for c in self.cpus)

    def sample(self) -> float | None:
        """CPUs' worth of time other processes ran on this process's CPUs since the previous sample
        (0 … ``len(cpus)``), or None: on the first call, where ``/proc/stat`` cannot be read, or when
        less than :data:`MIN_INTERVAL` passed (the earlier sample is kept, so the next call measures
        the longer interval)."""
        now = self._now()
        if now is None:
            self._last = None
            return None
        last = self._last
        if last is not None and now[0] - last[0] < MIN_INTERVAL:
            return None
        self._last = now
        if last is None:
            return None
        wall = now[0] - last[0]
        busy = (now[2] - last[2]) / self.hz
        others = (busy - (now[1] - last[1])) / wall
        return min(max(others, 0.0), float(len(self.cpus)))


class TorchThreads:
    """torch's intra-op thread count kept to the cores other processes leave free (module doc).

    cores: the cores this process may use (:func:`xnlos_core.threads.available_cores`); share: the
    measurement (:class:`CoreShare` of this process's CPUs by default)."""

    def __init__(self, cores: int, share: CoreShare | None = None):
        self.cores = max(1, int(cores))
        self.share = share if share is not None else CoreShare()
        self.wanted: int | None = None  # torch's count when first asked: the ceiling
        self.cap: int | None = None  # the count in force while limited; None: not limited
        self._ups = 0

    def update(self, wanted: int) -> int:
        """Sample the load and return the thread count to run now, 1 … ``wanted``."""
        self.wanted = wanted
        others = self.share.sample()
        current = self.cap if self.cap is not None else wanted
        if others is None:
            return min(current, wanted)
        # Others' load is measured on logical CPUs; the cores are physical (hyper-threads counted once).
        free = (len(self.share.cpus) - others) * self.cores / len(self.share.cpus)
        fit = min(max(int(free + 1.0 - KEEP_MARGIN), 1), wanted)
        if fit < current:
            self.cap, self._ups = fit, 0
        elif fit > current:
            self._ups += 1
            if self._ups >= RESTORE_AFTER:
                self.cap, self._ups = (None if fit >= wanted else fit), 0
        else:
            self._ups = 0
        return min(self.cap if self.cap is not None else wanted, wanted)

    def limited(self, threads: int) -> int:
        """``threads`` (a count a caller asks for explicitly) capped by the count in force now."""
        return threads if self.cap is None else max(1, min(threads, self.cap))


_governor: TorchThreads | None = None


def governor() -> TorchThreads | None:
    """The process's :class:`TorchThreads`, or None where the count is left alone: the thread policy
    switched off (``XNLOS_THREAD_POLICY=0``), a cgroup CPU quota below the CPUs of the affinity mask,
    or no per-CPU statistics (module doc)."""
    global _governor
    if _governor is None:
        from .threads import cgroup_cpu_quota, apply_process_policy

        policy = apply_process_policy()
        share = CoreShare()
        quota = cgroup_cpu_quota()
        if policy["off"] or (quota is not None and quota < len(share.cpus)) or read_proc_stat() is None:
            _governor = False  # type: ignore[assignment]
        else:
            _governor = TorchThreads(policy["cores"], share)
    return _governor or None


def adapt_torch_threads(enabled: bool = True) -> int | None:
    """Set torch's intra-op thread count to the cores left free now (module doc) and return it; None
    (nothing done) when torch is not loaded, ``enabled`` is false or :func:`governor` is None. Called
    once per frame and per training step; cheap (one read of ``/proc/stat``)."""
    torch = sys.modules.get("torch")
    gov = governor() if enabled else None
    if torch is None or gov is None:
        return None
    current = torch.get_num_threads()
    wanted = gov.wanted if gov.cap is not None and gov.wanted is not None else current
    n = gov.update(wanted)
    if n != current:
        torch.set_num_threads(n)
    return n


def limited(threads: int) -> int:
    """An explicitly requested torch thread count (a detector's ``threads``) capped by the count the
    load allows now (:meth:`TorchThreads.limited`); unchanged where nothing is limited."""
    gov = _governor or None
    return threads if gov is None else gov.limited(threads)
