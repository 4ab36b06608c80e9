"""xnlos_core.executor: results come back complete and the executor keeps none once yielded."""
from __future__ import annotations

import array
import gc
import weakref

import pytest

from xnlos_core.errors import ConfigError
from xnlos_core.executor import map_unordered


@pytest.mark.parametrize("workers", [1, 2])
def test_every_job_comes_back_once(workers):
    got = dict(map_unordered(array.array, ["d", "i", "b"], workers=workers))
    assert sorted(got) == [0, 1, 2]
    assert [got[i].typecode for i in range(3)] == ["d", "i", "b"]


@pytest.mark.parametrize("workers", [1, 2])
def test_a_yielded_result_is_not_kept_by_the_executor(workers):
    """The proxy for flat memory in ``xnlos simulate``: once the consumer drops a result (a shard's
    bytes), nothing in the executor holds it, while the remaining jobs are still pending.
    ``array.array`` is a picklable, weak-referenceable result a spawned worker can make."""
    gen = map_unordered(array.array, ["d"] * 4, workers=workers)
    refs = []
    for _ in range(3):
        _, res = next(gen)
        refs.append(weakref.ref(res))
        del res
        gc.collect()
        assert all(r() is None for r in refs)
    assert len(list(gen)) == 1


def test_workers_below_one_is_a_config_error():
    with pytest.raises(ConfigError, match="workers"):
        list(map_unordered(array.array, ["d", "d"], workers=0))
