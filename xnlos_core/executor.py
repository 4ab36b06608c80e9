"""Where independent jobs run: in this process, in local worker processes, or on a Dask cluster.

``map_unordered`` yields ``(i, result)`` as jobs finish. A scheduler address (e.g.
``tcp://127.0.0.1:8786``) sends the jobs to a Dask distributed cluster; nothing home-made.

The executor keeps no reference to a result once it is yielded (its future is dropped, on
Dask released), so a consumer that writes and forgets each result runs in flat memory however
many jobs there are (``xnlos simulate``: one shard's bytes at a time, not the whole dataset's).
"""
from __future__ import annotations

import multiprocessing as mp
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from typing import Any

from .errors import ConfigError


def map_unordered(fn: Callable, items: Sequence[Any], *, scheduler: str | None = None,
                  workers: int | None = None) -> Iterator[tuple[int, Any]]:
    """Apply the module-level function ``fn`` to each item; yield (index, result) as they finish.

    scheduler: Dask scheduler address, or None for local execution; workers: local processes
    (1 runs inline in this process; None uses every core).
    """
    if scheduler:
        yield from _dask(fn, items, scheduler)
        return
    if workers is not None and workers < 1:
        raise ConfigError(f"workers: expected ≥ 1 local processes, got {workers}")
    if workers == 1 or len(items) <= 1:
        for i, item in enumerate(items):
            yield i, fn(item)
        return
    # spawn: workers start clean (no inherited plugin state or threads), as on a cluster.
    pool = ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("spawn"))
    try:
        futures = {pool.submit(fn, item): i for i, item in enumerate(items)}
        for fut in as_completed(futures):
            # as_completed drops its reference as it yields; ours goes now and the result is handed
            # over through a box, so a suspended generator frame holds neither
            i, box = futures.pop(fut), [fut.result()]
            del fut
            yield i, box.pop()
    finally:
        # a consumer that stops early (an error, a closed generator) must not wait for the rest
        pool.shutdown(wait=True, cancel_futures=True)


def _dask(fn, items, address: str):
    try:
        from distributed import Client, as_completed as dask_completed
    except ImportError:
        raise ConfigError("a Dask scheduler was given but dask.distributed is not installed; "
                          "install it with: pip install 'xnlos[dask]'") from None
    try:
        client = Client(address, timeout="10s", set_as_default=False)
    except OSError as exc:
        raise ConfigError(f"scheduler {address!r}: cannot connect to a Dask scheduler ({exc})") from None
    try:
        with client.as_current():  # as_completed looks the client up; it is not the global default
            futures = client.map(fn, list(items), pure=False)
            index = {f.key: i for i, f in enumerate(futures)}
            pending = dask_completed(futures)
            del futures  # as_completed holds each future until it is yielded; then it is released
            for fut in pending:
                i, box = index.pop(fut.key), [fut.result()]
                fut.release()
                del fut
                yield i, box.pop()
    finally:
        client.close()
