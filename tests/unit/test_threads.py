"""Thread policy: the process policy (thread counts from the available cores, OpenMP's wait policy left
to the user)
in force in a fresh interpreter that starts the CLI, a user's own settings kept; BLAS limited to
``[run] blas_threads`` while the pipeline's stages run, the caller's limits restored afterwards."""
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from xnlos_core import Detections, Detector, hookimpl
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import PluginManager
from xnlos_core.testing import small_pipeline_table
from xnlos_core import threads
from xnlos_core.threads import _blas_controller, available_cores, blas_limit, policy_environment

OUTSIDE = 3  # a BLAS limit set around the pipeline, unlike both the default policy (1) and 2 below


def blas_threads() -> set[int]:
    """Thread counts of every loaded BLAS library now."""
    return {i["num_threads"] for i in threadpool_info() if i["user_api"] == "blas"}


class _SpyDetector(Detector):
    """Records the BLAS thread counts in force while it detects; optionally fails."""

    seen: list[set[int]] = []
    fail = False

    def detect(self, frame):
        _SpyDetector.seen.append(blas_threads())
        if _SpyDetector.fail:
            raise RuntimeError("spy detector failure")
        return Detections.empty()


class _SpyPlugin:
    @hookimpl
    def xnlos_register_components(self, registry):
        registry.add("detector", "blas_spy", _SpyDetector)


@pytest.fixture
def spy_pipeline():
    """pipeline(**run) → Pipeline of the small corner with the spy detector; its forward model's
    simulate also records the BLAS thread counts (in ``seen_source``)."""
    mgr = PluginManager(autoload=True)
    mgr.register(_SpyPlugin(), name="blas_spy", provider="tests")
    _SpyDetector.seen, _SpyDetector.fail = [], False
    seen_source = []

    def make(**run):
        table = small_pipeline_table(detector={"name": "blas_spy"}, run={"frames": 2, "figure": False, **run})
        pipe = Pipeline(parse_pipeline(table, "t"), registry=mgr.registry)
        fm = pipe.stages["forward_model"]
        simulate = fm.simulate

        def spy(*args, **kwargs):
            seen_source.append(blas_threads())
            return simulate(*args, **kwargs)

        fm.simulate = spy
        return pipe

    make.seen_source = seen_source
    return make


def test_blas_is_one_thread_inside_the_stages_and_restored_outside(spy_pipeline):
    pipe = spy_pipeline()
    assert pipe.config.run.blas_threads == 1  # the default policy
    with threadpool_limits(OUTSIDE, user_api="blas"):
        assert blas_threads() == {OUTSIDE}
        results = list(pipe.run())
        assert blas_threads() == {OUTSIDE}, "the pipeline left its BLAS limit behind"
    assert len(results) == 2
    assert _SpyDetector.seen == [{1}, {1}]
    assert spy_pipeline.seen_source == [{1}, {1}]


def test_configured_count_and_zero_leaves_blas_alone(spy_pipeline):
    with threadpool_limits(OUTSIDE, user_api="blas"):
        list(spy_pipeline(blas_threads=2).run())
        list(spy_pipeline(blas_threads=0).run())
        assert blas_threads() == {OUTSIDE}
    assert _SpyDetector.seen == [{2}, {2}, {OUTSIDE}, {OUTSIDE}]


def test_limits_restored_when_a_stage_raises(spy_pipeline):
    pipe = spy_pipeline()
    _SpyDetector.fail = True
    with threadpool_limits(OUTSIDE, user_api="blas"):
        frame = next(pipe.frames())
        with pytest.raises(RuntimeError, match="spy detector failure"):
            pipe.process(frame)
        assert blas_threads() == {OUTSIDE}
    assert _SpyDetector.seen == [{1}]


def test_bad_thread_counts_are_refused():
    with pytest.raises(ConfigError, match=r"t.toml: \[run.blas_threads\] .*greater than or equal to 0"):
        parse_pipeline(small_pipeline_table(run={"frames": 1, "blas_threads": -1}), "t.toml")
    with pytest.raises(ConfigError, match="blas threads -2"):
        blas_limit(-2)


def test_controller_refreshed_when_modules_are_imported(monkeypatch):
    # A BLAS library loaded by a later import (scipy.linalg, torch) must be found: the cached
    # controller is rebuilt when sys.modules changes, and only then.
    first = _blas_controller()
    assert _blas_controller() is first
    monkeypatch.setitem(sys.modules, "_xnlos_threads_test_module", object())
    assert _blas_controller() is not first


def test_thread_count_leaves_the_config_digest_alone():
    # Speed only: a finished run resumes under another blas_threads, and old runs keep their hash.
    digest = lambda **run: parse_pipeline(small_pipeline_table(run={"frames": 1, **run}), "t").digest()  # noqa: E731
    assert digest(blas_threads=4) == digest() == digest(blas_threads=0)
    assert digest(frames=2) != digest()
    run = lambda **r: parse_pipeline(small_pipeline_table(run={"frames": 1, **r}), "t").run_digest()  # noqa: E731
    assert run(frames=2) == run() != run(frame_interval=0.5)  # more frames extend a run


ROOT = Path(__file__).resolve().parents[2]
# What the child reports: the policy's variables as the environment holds them once the CLI module is
# imported, then the thread counts of torch and numba imported after it (as `xnlos run` imports them).
PROBE = """
import json, os, sys
import xnlos_core.app.cli
from xnlos_core import threads
env = {k: os.environ.get(k) for k in ("OMP_WAIT_POLICY", "KMP_BLOCKTIME", "OMP_NUM_THREADS", "NUMBA_NUM_THREADS")}
import numba, torch
print(json.dumps({"env": env, "cores": threads.available_cores(), "torch": torch.get_num_threads(),
                  "numba": numba.config.NUMBA_NUM_THREADS, "policy": threads.POLICY}))
"""


def probe(**env) -> dict:
    """Run :data:`PROBE` in a fresh interpreter whose environment has none of the policy's variables
    but those given."""
    base = {k: v for k, v in os.environ.items() if k not in policy_environment(1) and k != threads.OPT_OUT}
    base["PYTHONPATH"] = os.pathsep.join([str(ROOT), base.get("PYTHONPATH", "")])
    out = subprocess.run([sys.executable, "-c", PROBE], env={**base, **env}, cwd=ROOT, capture_output=True,
                         text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


def test_process_policy_in_force_when_the_cli_starts():
    got = probe()
    n = got["cores"]
    assert got["env"] == {"OMP_WAIT_POLICY": None, "KMP_BLOCKTIME": None, "OMP_NUM_THREADS": str(n),
                          "NUMBA_NUM_THREADS": str(n)}
    assert got["torch"] == n and got["numba"] == n
    assert got["policy"]["loaded_before"] == [], "numpy, numba or torch loaded before the policy was set"
    assert got["policy"]["kept"] == {} and not got["policy"]["off"]


def test_users_own_settings_win():
    got = probe(OMP_WAIT_POLICY="ACTIVE", OMP_NUM_THREADS="1")
    assert got["env"]["OMP_WAIT_POLICY"] == "ACTIVE" and got["env"]["OMP_NUM_THREADS"] == "1"
    assert got["env"]["NUMBA_NUM_THREADS"] == str(got["cores"])  # those the user did not set follow the policy
    assert got["torch"] == 1
    assert got["policy"]["kept"] == {"OMP_NUM_THREADS": "1"}


def test_policy_can_be_switched_off():
    got = probe(XNLOS_THREAD_POLICY="0")
    assert set(got["env"].values()) == {None}  # nothing set
    assert got["policy"]["off"] and got["policy"]["set"] == {}


def _fake_sysfs(monkeypatch, files: dict[str, str], cpus: set[int]):
    monkeypatch.setattr(threads, "_read", lambda path: files.get(str(path)))
    monkeypatch.setattr(os, "sched_getaffinity", lambda pid: cpus, raising=False)
    monkeypatch.setattr(sys, "platform", "linux")


def test_available_cores_counts_physical_cores_of_the_affinity_mask(monkeypatch):
    # CPUs 0-3 are two cores with two hyper-threads each; the process may run on 0, 1 and 2.
    topo = {}
    for cpu, core in [(0, 0), (1, 0), (2, 1), (3, 1)]:
        topo[f"/sys/devices/system/cpu/cpu{cpu}/topology/physical_package_id"] = "0"
        topo[f"/sys/devices/system/cpu/cpu{cpu}/topology/core_id"] = str(core)
    _fake_sysfs(monkeypatch, topo, {0, 1, 2})
    assert available_cores() == 2
    _fake_sysfs(monkeypatch, {}, {0, 1, 2})  # no topology: every CPU counts
    assert available_cores() == 3


def test_available_cores_capped_by_a_cgroup_quota(monkeypatch):
    v2 = {"/proc/self/cgroup": "0::/job", "/sys/fs/cgroup/job/cpu.max": "150000 100000",
          "/sys/fs/cgroup/cpu.max": "max 100000"}
    _fake_sysfs(monkeypatch, v2, {0, 1, 2, 3, 4, 5, 6, 7})
    assert threads.cgroup_cpu_quota() == 1.5
    assert available_cores() == 2  # 1.5 CPUs' worth of time: two threads, rounded up
    v1 = {"/proc/self/cgroup": "4:cpu,cpuacct:/\n3:memory:/x", "/sys/fs/cgroup/cpu/cpu.cfs_quota_us": "100000",
          "/sys/fs/cgroup/cpu/cpu.cfs_period_us": "100000"}
    _fake_sysfs(monkeypatch, v1, {0, 1, 2, 3})
    assert available_cores() == 1
    _fake_sysfs(monkeypatch, {**v1, "/sys/fs/cgroup/cpu/cpu.cfs_quota_us": "-1"}, {0, 1, 2, 3})
    assert threads.cgroup_cpu_quota() is None and available_cores() == 4
