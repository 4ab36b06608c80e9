"""Thread policy: BLAS limited to ``[run] blas_threads`` while the pipeline's stages run,
the caller's limits restored afterwards."""
import sys

import pytest
from threadpoolctl import threadpool_info, threadpool_limits

from xnlos_core import Detections, Detector, hookimpl
from xnlos_core.config import parse_pipeline
from xnlos_core.errors import ConfigError
from xnlos_core.pipeline import Pipeline
from xnlos_core.registry import PluginManager
from xnlos_core.testing import small_pipeline_table
from xnlos_core.threads import _blas_controller, blas_limit

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
