"""Independent compiled simulations on threads.

The compiled integrators release the GIL (``nogil``), so the entries of a batch (one
model on one run: the columns of a forward-difference Jacobian, the runs of a residual)
can be integrated side by side on threads. Each entry is integrated on its own, exactly
as in turn, so the results do not depend on the number of threads.

The number of threads is the usable CPUs (at most :data:`MAX_THREADS`), or the limit set
by :func:`limit_threads` around a piece of work (:class:`hystdisc.Discovery` sets its
``n_jobs``; ``n_jobs=1`` runs everything in turn). The limit is a context variable: two
discoveries on two threads each keep their own, and the work this module hands to its
threads (:func:`map_entries`, :func:`map_tasks`, :func:`map_after`) runs in a copy of the
caller's context, so it sees the caller's limit.

Examples
--------
>>> with limit_threads(1):
...     map_entries(lambda k: k * k, [1, 2, 3])
[1, 4, 9]
>>> with limit_threads(2):
...     map_entries(lambda k: k * k, [1, 2, 3])
[1, 4, 9]
"""

from __future__ import annotations

import os
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from contextvars import ContextVar, copy_context
from typing import Any

import numpy as np

#: At most this many threads per batch.
MAX_THREADS = 4

#: The :func:`limit_threads` limit of the current context (None: the usable CPUs).
_LIMIT: ContextVar[int | None] = ContextVar("hystdisc_thread_limit", default=None)


def usable_cpus() -> int:
    """The CPUs this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # pragma: no cover - not on Linux
        return os.cpu_count() or 1


def n_threads() -> int:
    """Threads a batch may use now (the :func:`limit_threads` limit, else the usable CPUs;
    at most :data:`MAX_THREADS`)."""
    limit = _LIMIT.get()
    n = limit if limit is not None else usable_cpus()
    return max(1, min(n, MAX_THREADS))


@contextmanager
def limit_threads(n: int | None) -> Iterator[None]:
    """Limit the threads of every batch inside the ``with`` block to ``n`` (None: no
    limit beyond the usable CPUs), in the current context only (another thread's limit
    is its own; the threads of this module's maps inherit their caller's)."""
    token = _LIMIT.set(None if n is None else max(1, int(n)))
    try:
        yield
    finally:
        _LIMIT.reset(token)


def _in_context(fn: Callable) -> Callable:
    """``fn`` bound to a copy of the calling thread's context (its :func:`limit_threads`
    limit): call this in the thread that hands the work out, once per task (a context
    can be entered by one thread at a time)."""
    ctx = copy_context()
    return lambda *args: ctx.run(fn, *args)


_pool: ThreadPoolExecutor | None = None
_pool_pid = -1  # a forked child has none of its parent's threads: it starts its own pool
_pool_lock = threading.Lock()


def _shared_pool() -> ThreadPoolExecutor:
    """The process's pool (kept: a fit makes thousands of small batches, and starting
    threads for each would cost more than it saves)."""
    global _pool, _pool_pid
    with _pool_lock:
        if _pool is None or _pool_pid != os.getpid():
            _pool = ThreadPoolExecutor(max_workers=MAX_THREADS, thread_name_prefix="hystdisc")
            _pool_pid = os.getpid()
        return _pool


def chunk_bounds(offsets: np.ndarray, min_samples: int) -> list[int]:
    """Entry bounds splitting a batch (entries ``e`` own the samples
    ``offsets[e]:offsets[e + 1]``) into up to :func:`n_threads` contiguous chunks of about
    equal samples, each at least ``min_samples`` (one chunk: ``[0, entries]``).

    Examples
    --------
    >>> with limit_threads(2):
    ...     chunk_bounds(np.array([0, 10, 20, 30, 40]), 5)
    [0, 2, 4]
    >>> with limit_threads(2):
    ...     chunk_bounds(np.array([0, 10, 20, 30, 40]), 100)
    [0, 4]
    """
    ne = len(offsets) - 1
    total = int(offsets[-1] - offsets[0])
    n = min(n_threads(), ne, max(1, total // max(min_samples, 1)))
    if n <= 1:
        return [0, ne]
    # each cut at the entry boundary nearest its share of the samples
    target = offsets[0] + total * np.arange(1, n) / n
    hi = np.clip(np.searchsorted(offsets, target), 1, ne)
    cuts = np.where(target - offsets[hi - 1] <= offsets[hi] - target, hi - 1, hi)
    return sorted({0, ne, *(int(c) for c in cuts if 0 < c < ne)})


def map_entries(fn: Callable[[Any], Any], items: Sequence[Any]) -> list[Any]:
    """``fn`` over ``items``, in order, on up to :func:`n_threads` threads of the shared
    pool, each taking the next item when it is free (entries of unequal cost); each keeps
    the caller's floating-point error state (numpy's is per thread) and its context (the
    thread limit). ``fn`` must not wait on this pool itself."""
    n = min(n_threads(), len(items))
    if n <= 1:
        return [fn(x) for x in items]
    out: list[Any] = [None] * len(items)
    order = iter(range(len(items)))
    lock = threading.Lock()
    state = np.geterr()

    def lane() -> None:
        with np.errstate(**state):
            while True:
                with lock:
                    k = next(order, None)
                if k is None:
                    return
                out[k] = fn(items[k])

    for f in [_shared_pool().submit(_in_context(lane)) for _ in range(n)]:
        f.result()
    return out


def map_after(
    before: Callable[[Any], Any],
    before_items: Sequence[Any],
    after: Callable[[Any, Callable[[int], Any]], Any],
    after_items: Sequence[Any],
    n: int,
    serial_before: bool = False,
) -> tuple[list[Any], list[Any]]:
    """``before`` over ``before_items``, then ``after(item, ready)`` over ``after_items``,
    on ``n`` threads of a pool of their own; ``ready(k)`` waits for the ``k``-th
    ``before`` result and returns it. An ``after`` task thus starts as soon as a thread is
    free, not once every ``before`` task has ended (a family's first fit needs only its
    own shape's stage-1 search). The ``before`` tasks are queued first and the pool starts
    its tasks in turn, so a waiting task never holds up one it waits for.

    ``serial_before`` runs the ``before`` tasks in turn on the calling thread first (work
    that must not run beside itself); ``n <= 1`` runs everything in turn. Each task runs
    in a copy of the caller's context (its thread limit). Returns both lists of results,
    in order (each task is computed as in turn).

    Examples
    --------
    >>> map_after(lambda k: k * k, [1, 2, 3], lambda j, ready: ready(j) + 1, [2, 0], 2)
    ([1, 4, 9], [10, 2])
    >>> map_after(lambda k: k * k, [1, 2, 3], lambda j, ready: ready(j) + 1, [2, 0], 1)
    ([1, 4, 9], [10, 2])
    """
    if serial_before or n <= 1:
        firsts = [before(x) for x in before_items]
        if n <= 1 or len(after_items) <= 1:
            return firsts, [after(x, firsts.__getitem__) for x in after_items]
        with ThreadPoolExecutor(max_workers=n) as pool:
            rest = [pool.submit(_in_context(after), x, firsts.__getitem__) for x in after_items]
            return firsts, [f.result() for f in rest]
    with ThreadPoolExecutor(max_workers=max(1, n)) as pool:
        futs = [pool.submit(_in_context(before), x) for x in before_items]
        ready = lambda k: futs[k].result()  # noqa: E731
        rest = [pool.submit(_in_context(after), x, ready) for x in after_items]
        return [f.result() for f in futs], [f.result() for f in rest]


def job_threads(n_jobs: int | None) -> int:
    """Threads of one discovery's independent fits: ``n_jobs``, else the usable CPUs (at
    most :data:`MAX_THREADS`)."""
    if n_jobs is not None:
        return max(1, int(n_jobs))
    return max(1, min(usable_cpus(), MAX_THREADS))


def _quiet(fn: Callable) -> Callable:
    """``fn`` with floating-point warnings ignored (numpy's error state is per thread: a
    worker thread does not inherit the caller's)."""

    def call(*args):
        with np.errstate(all="ignore"):
            return fn(*args)

    return call


def map_tasks(fn: Callable, items: Sequence[Any], n_jobs: int | None, serial: bool = False) -> list:
    """``fn`` over ``items`` (independent fits) on up to :func:`job_threads` threads, in
    order, each worker ignoring floating-point warnings (the compiled kernels release the
    GIL) and in a copy of the caller's context (its thread limit).

    Examples
    --------
    >>> map_tasks(lambda k: k + 1, [1, 2, 3], n_jobs=2)
    [2, 3, 4]
    """
    work = _quiet(fn)
    n = job_threads(n_jobs)
    if serial or n <= 1 or len(items) <= 1:
        return [work(x) for x in items]
    with ThreadPoolExecutor(max_workers=min(n, len(items))) as pool:
        futs = [pool.submit(_in_context(work), x) for x in items]
        return [f.result() for f in futs]


def map_tasks_after(
    before: Callable, before_items: Sequence[Any], after: Callable, after_items: Sequence[Any],
    n_jobs: int | None, serial_before: bool = False,
) -> tuple[list[Any], list[Any]]:  # fmt: skip
    """:func:`map_after` on :func:`job_threads` threads, each worker ignoring
    floating-point warnings as :func:`map_tasks`'s do."""
    n = job_threads(n_jobs)
    return map_after(_quiet(before), before_items, _quiet(after), after_items, n, serial_before)
