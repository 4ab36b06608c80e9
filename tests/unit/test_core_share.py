"""torch threads that follow the cores other processes leave free: the measurement (per-CPU busy time
minus the process's own, over wall time), the count's way down (at once) and up (after quiet
intervals in a row), explicit counts capped, and the pipeline asking once per frame."""
import multiprocessing
import time

import pytest

from xnlos_core import core_share
from xnlos_core.core_share import MIN_INTERVAL, RESTORE_AFTER, CoreShare, TorchThreads, read_proc_stat

STAT = """cpu  100 0 50 1000 10 0 5 0 0 0
cpu0 60 0 20 500 5 0 3 0 0 0
cpu1 40 0 30 500 5 0 2 0 0 0
intr 12345
ctxt 999
"""


def test_proc_stat_parsed_per_cpu(tmp_path):
    p = tmp_path / "stat"
    p.write_text(STAT)
    # busy = total − idle − iowait: cpu0 60+20+3 = 83 of 588
    assert read_proc_stat(str(p)) == {0: (83, 588), 1: (72, 577)}
    p.write_text("cpu0 x y\n")
    assert read_proc_stat(str(p)) is None
    assert read_proc_stat(str(tmp_path / "missing")) is None


class Fake:
    """Clock [s], own CPU time [s] and per-CPU busy ticks (100 per s) advanced by the test."""

    def __init__(self, cpus=(0, 1)):
        self.t, self.own, self.busy = 0.0, 0.0, dict.fromkeys(cpus, 0)

    def advance(self, wall: float, others: float, own: float = 0.0):
        """``wall`` seconds in which other processes ran ``others`` CPUs' worth and this one ``own``."""
        self.t += wall
        self.own += own * wall
        per_cpu = (others + own) * wall * 100 / len(self.busy)
        for c in self.busy:
            self.busy[c] += per_cpu

    def share(self) -> CoreShare:
        return CoreShare(set(self.busy), read=lambda: {c: (round(b), 10**9) for c, b in self.busy.items()},
                         clock=lambda: self.t, cpu_time=lambda: self.own, ticks_per_second=100)


def test_others_measured_over_the_interval_without_the_process_itself():
    f = Fake()
    s = f.share()
    assert s.sample() is None  # the first call only starts the interval
    f.advance(0.5, others=1.5, own=0.5)
    assert s.sample() == pytest.approx(1.5)
    f.advance(0.5, others=0.0, own=2.0)  # this process alone, both cores: nobody else
    assert s.sample() == pytest.approx(0.0)
    f.advance(MIN_INTERVAL / 2, others=2.0)  # too short: nothing measured, the interval goes on
    assert s.sample() is None
    f.advance(0.5, others=2.0)
    assert s.sample() == pytest.approx(2.0, abs=0.05)  # clock ticks: 1/100 s per CPU


def test_unreadable_statistics_measure_nothing():
    s = CoreShare({0, 1}, read=lambda: None)
    assert s.sample() is None and s.sample() is None
    s = CoreShare({0, 5}, read=lambda: {0: (1, 2), 1: (1, 2)})  # a CPU of the mask is missing
    assert s.sample() is None


def test_threads_go_down_at_once_and_up_after_quiet_intervals():
    f = Fake()
    gov = TorchThreads(2, f.share())
    assert gov.update(2) == 2  # first call: nothing measured yet
    f.advance(0.2, others=1.6, own=0.4)
    assert gov.update(2) == 1 and gov.cap == 1
    for _ in range(RESTORE_AFTER - 1):
        f.advance(0.2, others=0.1, own=0.9)
        assert gov.update(2) == 1  # quiet, but not yet long enough
    f.advance(0.2, others=0.1, own=0.9)
    assert gov.update(2) == 2 and gov.cap is None
    # A burst that ends within the quiet intervals starts the count again.
    f.advance(0.2, others=1.9, own=0.1)
    assert gov.update(2) == 1
    f.advance(0.2, others=0.0, own=1.0)
    f.advance(0.2, others=1.9, own=0.1)
    assert gov.update(2) == 1
    f.advance(0.2, others=0.0, own=1.0)
    assert gov.update(2) == 1


def test_count_never_above_what_was_asked_nor_below_one():
    f = Fake(cpus=range(8))
    gov = TorchThreads(8, f.share())
    gov.update(3)
    f.advance(0.2, others=0.0, own=3.0)
    assert gov.update(3) == 3
    f.advance(0.2, others=8.0)
    assert gov.update(3) == 1
    assert gov.limited(4) == 1 and gov.limited(1) == 1


def test_hyperthreads_counted_as_cores():
    # 4 logical CPUs, 2 physical cores: 2 CPUs' worth of others leaves one core.
    f = Fake(cpus=range(4))
    gov = TorchThreads(2, f.share())
    gov.update(2)
    f.advance(0.2, others=2.0, own=0.5)
    assert gov.update(2) == 1


def test_explicit_counts_capped_only_while_limited(monkeypatch):
    f = Fake()
    gov = TorchThreads(2, f.share())
    monkeypatch.setattr(core_share, "_governor", gov)
    assert core_share.limited(2) == 2
    gov.update(2)
    f.advance(0.2, others=2.0)
    gov.update(2)
    assert core_share.limited(2) == 1


def test_torch_threads_set_and_given_back(monkeypatch):
    torch = pytest.importorskip("torch")
    f = Fake()
    gov = TorchThreads(2, f.share())
    monkeypatch.setattr(core_share, "_governor", gov)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    try:
        assert core_share.adapt_torch_threads() == 2
        f.advance(0.2, others=2.0)
        assert core_share.adapt_torch_threads() == 1 and torch.get_num_threads() == 1
        assert core_share.adapt_torch_threads(enabled=False) is None and torch.get_num_threads() == 1
        for _ in range(RESTORE_AFTER):
            f.advance(0.2, others=0.0, own=2.0)
            core_share.adapt_torch_threads()
        assert torch.get_num_threads() == 2  # the count torch had before it was limited
    finally:
        torch.set_num_threads(before)


def test_off_with_the_thread_policy(monkeypatch):
    monkeypatch.setattr(core_share, "_governor", None)
    from xnlos_core import threads

    monkeypatch.setattr(threads, "POLICY", {"off": True, "cores": 2, "set": {}, "kept": {}, "loaded_before": []})
    assert core_share.governor() is None
    assert core_share.adapt_torch_threads() is None


def _spin(seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        pass


@pytest.mark.skipif(read_proc_stat() is None, reason="no /proc/stat")
def test_a_busy_process_is_seen():
    s = CoreShare()
    s.sample()
    p = multiprocessing.get_context("spawn").Process(target=_spin, args=(1.0,))
    p.start()
    p.join(30)
    assert s.sample() >= 0.25  # the child ran most of a second (bound loose: the machine may be busy)


def test_pipeline_adapts_once_per_frame(monkeypatch):
    from xnlos_core.config import parse_pipeline
    from xnlos_core.pipeline import Pipeline
    from xnlos_core.testing import small_pipeline_table
    import xnlos_core.pipeline as pipeline_module

    calls = []
    monkeypatch.setattr(pipeline_module, "adapt_torch_threads", lambda enabled=True: calls.append(enabled))
    for share in (True, False):
        calls.clear()
        pipe = Pipeline(parse_pipeline(small_pipeline_table(run={"frames": 2, "figure": False,
                                                                 "share_cores": share}), "t"))
        for frame in pipe.frames():
            pipe.process(frame)
        assert calls == [share, share]


def test_background_noise_does_not_cost_a_thread():
    # other processes at 0.6 of a core (the kernel's threads, steal time, a short job): both threads stay;
    # at 0.9 of a core, one is given up
    f = Fake()
    gov = TorchThreads(2, f.share())
    gov.update(2)
    f.advance(0.2, others=0.6, own=1.4)
    assert gov.update(2) == 2
    f.advance(0.2, others=0.9, own=1.1)
    assert gov.update(2) == 1
