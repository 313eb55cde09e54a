"""Where one discovery's independent tasks run: this process's threads, or a Dask cluster.

A discovery is many independent tasks (stage-1 shapes, every family's first fit, its
starts, its held-out folds, the refits with an effect); the stages hand them out through
:meth:`State.map <hystdisc.pipeline.state.State.map>` and
:meth:`State.map_after <hystdisc.pipeline.state.State.map_after>`, which call the
discovery's engine:

- :class:`ThreadTasks` (the default): up to ``n_jobs`` threads of this process
  (:func:`~hystdisc.simulation.parallel.map_tasks`);
- :class:`ClusterTasks` (``Discovery(scheduler=ADDRESS)``, ``hystdisc discover FILE
  --scheduler ADDRESS``): each task is sent to a Dask worker, which needs this version of
  hystdisc (:func:`~hystdisc.cluster.check_workers`) but no data files: the task carries
  its data. Made and closed by :func:`task_engine`.

A task is a closure over the discovery's state. On a cluster it is pickled (cloudpickle,
once per map, with the items) and run by :func:`discovery_task` on a worker, as on a
thread: floating-point warnings ignored, BLAS on one thread, the worker's batches on up to
``n_jobs`` threads, and the same arithmetic, so the results are those of the threaded run
(each task computes as in turn). What a task does besides its result comes back with it
and is replayed here in task order: the failures it recorded (a pickled
:class:`~hystdisc.faults.Failures` is a copy) and its progress messages (a pickled
:class:`Say` keeps them), said when its result arrives; an exception it raised is raised
here once every task of the map has ended, as the thread pool does. A task that hands out
tasks of its own runs them on its worker's threads (a pickled :class:`ClusterTasks` is a
:class:`ThreadTasks`).

Examples
--------
>>> tasks = ThreadTasks(n_jobs=2)
>>> tasks.map(lambda k: k * k, [1, 2, 3])
[1, 4, 9]
>>> say = Say(print)
>>> say("stage 1")
stage 1
>>> import pickle
>>> kept = pickle.loads(pickle.dumps(say))  # sent to a worker: keeps what it is told
>>> kept("stage 2"); kept.take()
['stage 2']
"""

from __future__ import annotations

import contextlib
import functools
import pickle
import threading
from collections.abc import Callable, Iterator, Sequence
from typing import Any, Protocol

import numpy as np
from threadpoolctl import threadpool_limits

from hystdisc.cluster import check_workers, connect
from hystdisc.faults import Failures
from hystdisc.simulation.parallel import limit_threads, map_tasks, map_tasks_after

#: One progress callback at a time, whichever discovery of the process calls it.
_SAY_LOCK = threading.Lock()


class Say:
    """Progress messages passed to ``progress`` (None: dropped), one call at a time.

    Pickled (a task sent to a Dask worker), it becomes a ``Say`` that keeps its messages
    for :meth:`take`: the worker's runner hands them back, to be said here.

    Parameters
    ----------
    progress : callable, optional
        Receives each message (``str``).
    keep : bool
        Keep the messages instead (what a pickled ``Say`` does).
    """

    def __init__(self, progress: Callable[[str], None] | None = None, keep: bool = False):
        self.progress = progress
        self.kept: list[str] | None = [] if keep else None

    def __call__(self, msg: str) -> None:
        with _SAY_LOCK:
            if self.kept is not None:
                self.kept.append(msg)
            elif self.progress is not None:
                self.progress(msg)

    def __reduce__(self):
        return (Say, (None, True))  # the callback stays here: the messages come back

    def take(self) -> list[str]:
        """The messages kept since the last call, and forget them.

        Returns
        -------
        list of str
            The messages, in the order said (empty unless ``keep``).
        """
        with _SAY_LOCK:
            out, self.kept = list(self.kept or []), ([] if self.kept is not None else None)
            return out


class Tasks(Protocol):
    """An engine of one discovery's independent tasks (both return results in order)."""

    n_jobs: int | None

    def map(self, fn: Callable, items: Sequence[Any], serial: bool = False) -> list:
        """``fn`` over ``items``; ``serial``: in turn, in this thread."""

    def map_after(
        self, before: Callable, before_items: Sequence[Any], after: Callable,
        after_items: Sequence[Any], serial_before: bool = False,
    ) -> tuple[list, list]:  # fmt: skip
        """``before`` over ``before_items``, then ``after(item, ready)`` over
        ``after_items`` (``ready(k)``: the ``k``-th ``before`` result), as
        :func:`~hystdisc.simulation.parallel.map_after`."""


class ThreadTasks:
    """The tasks on up to ``n_jobs`` threads of this process (None: the usable CPUs).

    Parameters
    ----------
    n_jobs : int, optional
        As :func:`~hystdisc.simulation.parallel.map_tasks`.
    """

    def __init__(self, n_jobs: int | None = None) -> None:
        self.n_jobs = n_jobs

    def map(self, fn: Callable, items: Sequence[Any], serial: bool = False) -> list:
        """:func:`~hystdisc.simulation.parallel.map_tasks`."""
        return map_tasks(fn, items, self.n_jobs, serial)

    def map_after(
        self, before: Callable, before_items: Sequence[Any], after: Callable,
        after_items: Sequence[Any], serial_before: bool = False,
    ) -> tuple[list, list]:  # fmt: skip
        """:func:`~hystdisc.simulation.parallel.map_tasks_after`."""
        return map_tasks_after(before, before_items, after, after_items, self.n_jobs,
                               serial_before)  # fmt: skip


class ClusterTasks:
    """The tasks on the workers of a Dask cluster (see the module docstring).

    Parameters
    ----------
    client : distributed.Client
        The connected client.
    n_jobs : int, optional
        The threads of each task's batches on its worker, and of the work run here.
    failures : Failures
        The discovery's record, where the tasks' failures are replayed.
    say : callable
        The discovery's progress, where the tasks' messages are replayed.
    """

    def __init__(
        self, client: Any, n_jobs: int | None, failures: Failures, say: Callable[[str], None]
    ) -> None:
        self.client = client
        self.n_jobs = n_jobs
        self.failures = failures
        self.say = say

    def __reduce__(self):
        return (ThreadTasks, (self.n_jobs,))  # on a worker: its own threads

    def map(self, fn: Callable, items: Sequence[Any], serial: bool = False) -> list:
        """``fn`` over ``items`` on the workers (see the module docstring).

        Parameters
        ----------
        fn : callable
            One task: ``fn(item)``; pickled with cloudpickle, with what it closes over.
        items : sequence
            The items (pickled with ``fn``).
        serial : bool
            Run the tasks in turn here instead (work that must not run beside itself).

        Returns
        -------
        list
            ``fn(item)`` for each item, in order.

        Raises
        ------
        Exception
            The first exception a task raised, in task order, once every task has ended
            (the others' failures and messages replayed).
        """
        items = list(items)
        if serial or not items:
            return map_tasks(fn, items, self.n_jobs, serial)
        import cloudpickle  # a dependency of dask.distributed

        # one pickle: the tasks' closures share their state (and its Failures and Say)
        payload = cloudpickle.dumps((fn, items, self.failures, self.say))
        [data] = self.client.scatter([payload], hash=False)
        futures = self.client.map(
            discovery_task, range(len(items)), payload=data, n_jobs=self.n_jobs, pure=False
        )
        try:
            out, raised = [], None
            for fut in futures:
                value, error, failed, said = fut.result()
                for msg in said:
                    self.say(msg)
                for name, reason in failed.items():
                    self.failures.record(name, reason)
                if raised is None:
                    raised = error  # the first in task order, as the thread pool's
                out.append(value)
        except BaseException:
            # Ctrl-C or a lost worker: leave nothing of this map running on the cluster
            with contextlib.suppress(Exception):
                self.client.cancel(futures)
            raise
        if raised is not None:
            raise raised
        return out

    def map_after(
        self, before: Callable, before_items: Sequence[Any], after: Callable,
        after_items: Sequence[Any], serial_before: bool = False,
    ) -> tuple[list, list]:  # fmt: skip
        """``before`` over ``before_items``, then ``after`` over ``after_items``, on the
        workers.

        Unlike :func:`~hystdisc.simulation.parallel.map_after` on threads, the ``after``
        tasks start once every ``before`` task has ended (the same results).

        Parameters
        ----------
        before : callable
            ``before(item)``.
        before_items : sequence
            Its items.
        after : callable
            ``after(item, ready)``, ``ready(k)`` returning the ``k``-th ``before`` result.
        after_items : sequence
            Its items.
        serial_before : bool
            Run the ``before`` tasks in turn here (numpy's global generator).

        Returns
        -------
        tuple of list
            The ``before`` results and the ``after`` results, each in order.
        """
        firsts = self.map(before, before_items, serial=serial_before)
        return firsts, self.map(functools.partial(_after, after, firsts), after_items)


def _after(after: Callable, firsts: list, item: Any) -> Any:
    """``after(item, ready)`` with the ``before`` results ``firsts`` at hand."""
    return after(item, firsts.__getitem__)


_BLAS_LOCK = threading.Lock()
_blas_users = 0
_blas_limit: Any = None


@contextlib.contextmanager
def _blas_one_thread() -> Iterator[None]:
    """BLAS on one thread while any task of this process runs (as in the discovery's own
    process); the limit is process-wide, so the first task sets it and the last restores
    it (a nested ``threadpool_limits`` per task would restore it under a running one)."""
    global _blas_users, _blas_limit
    with _BLAS_LOCK:
        if _blas_users == 0:
            _blas_limit = threadpool_limits(limits=1)
        _blas_users += 1
    try:
        yield
    finally:
        with _BLAS_LOCK:
            _blas_users -= 1
            if _blas_users == 0:
                _blas_limit.restore_original_limits()
                _blas_limit = None


def discovery_task(k: int, payload: bytes, n_jobs: int | None) -> tuple:
    """Task ``k`` of a :meth:`ClusterTasks.map`, run on a worker.

    Parameters
    ----------
    k : int
        Which item.
    payload : bytes
        The pickled ``(fn, items, failures, say)``.
    n_jobs : int, optional
        The threads of the task's batches.

    Returns
    -------
    tuple
        ``fn(items[k])`` (None if it raised), the exception it raised (or None), the
        failures it recorded (name -> reason), its progress messages.
    """
    fn, items, failures, say = pickle.loads(payload)
    known = failures.items()
    value, error = None, None
    with np.errstate(all="ignore"), _blas_one_thread(), limit_threads(n_jobs):
        try:
            value = fn(items[k])
        except Exception as exc:  # noqa: BLE001 - raised on the client, as a thread's is
            error = exc
    failed = {n: r for n, r in failures.items().items() if n not in known}
    return value, error, failed, say.take()


@contextlib.contextmanager
def task_engine(
    scheduler: Any, n_jobs: int | None, failures: Failures, say: Callable[[str], None]
) -> Iterator[Tasks]:
    """The engine of one discovery's tasks inside the block.

    Parameters
    ----------
    scheduler : str or distributed.Client or None
        None: this process's threads (:class:`ThreadTasks`); else a Dask scheduler's
        address or a client (:class:`ClusterTasks`; a client made here from an address is
        closed at the end of the block).
    n_jobs : int, optional
        Threads (see :class:`ThreadTasks`, :class:`ClusterTasks`).
    failures : Failures
        The discovery's record of failed tasks.
    say : callable
        The discovery's progress messages.

    Yields
    ------
    Tasks
        The engine.

    Raises
    ------
    HystdiscError
        As :func:`~hystdisc.cluster.connect` and :func:`~hystdisc.cluster.check_workers`:
        dask.distributed missing, a malformed or unreachable address, a worker without
        this version of hystdisc.
    """
    if scheduler is None:
        yield ThreadTasks(n_jobs)
        return
    client, own = connect(scheduler)
    try:
        check_workers(client, say)
        yield ClusterTasks(client, n_jobs, failures, say)
    finally:
        if own:
            client.close()
