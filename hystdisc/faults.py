"""Fault isolation: a task of a discovery that fails is dropped with its reason, and the run goes on.

A discovery is many independent tasks: stage-1 shapes, every family's fit and its starts,
held-out folds, the effects of the closing loop, the staged fit, the comparison again.
Any of them can fail on data nobody tried before (a simulation that diverges, a singular
Jacobian, NaN). :class:`Failures` records such a failure as one line, ``name -> reason``,
and :meth:`Failures.guard` runs a task so that its failure is recorded instead of raised:
the discovery reports what it could do, lists what failed (console, ``results.json``'s
``failed``, the report) and never ends with a traceback because one family could not be
fitted.

Only errors of the computation are caught: a programming error of the package is one of
them too (its type is kept in the reason, so it can be reported), but ``KeyboardInterrupt``
and ``MemoryError`` still stop the run.

Examples
--------
>>> f = Failures()
>>> f.guard("spencer", lambda: 1 / 0) is None
True
>>> f.guard("dahl", lambda: 2)
2
>>> f.items()
{'spencer': 'the computation failed (ZeroDivisionError: division by zero)'}
>>> import pickle
>>> pickle.loads(pickle.dumps(f)).items() == f.items()
True
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

from hystdisc.errors import HystdiscError

T = TypeVar("T")


def reason_of(exc: BaseException) -> str:
    """One line saying why ``exc`` stopped a task.

    A :class:`~hystdisc.errors.HystdiscError` keeps its problem and drops its ``fix:``
    part, which speaks to a user about their input: inside a fit, the values were the
    fit's own.

    Examples
    --------
    >>> reason_of(HystdiscError("spencer: parameter n=-8 is outside [1e-4, 10]; fix: give a value"))
    'spencer: parameter n=-8 is outside [1e-4, 10]'
    >>> reason_of(FloatingPointError("overflow"))
    'the computation failed (FloatingPointError: overflow)'
    """
    text = " ".join(str(exc).split())
    if isinstance(exc, HystdiscError):
        return text.split("; fix:")[0].strip() or type(exc).__name__
    what = f"{type(exc).__name__}: {text}" if text else type(exc).__name__
    return f"the computation failed ({what})"


class Failures:
    """The failed tasks of one discovery: name -> reason, in the order they failed.

    Thread-safe: tasks run on several threads record into one instance. It pickles as its
    record (a task sent to another process takes a copy; what it records there is handed
    back by the task's runner, :mod:`hystdisc.pipeline.tasks`).
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._items: dict[str, str] = {}

    def __getstate__(self) -> dict[str, dict[str, str]]:
        return {"items": self.items()}  # a lock does not pickle: a copy gets its own

    def __setstate__(self, state: dict[str, dict[str, str]]) -> None:
        self.__init__()
        self._items.update(state["items"])

    def record(self, name: str, reason: str) -> None:
        """Record that the task ``name`` failed for ``reason`` (the first reason stays)."""
        with self._lock:
            self._items.setdefault(str(name), str(reason))

    def guard(self, task: str, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> T | None:
        """``fn(*args, **kwargs)``, or None with the failure recorded under ``task``."""
        try:
            return fn(*args, **kwargs)
        except (KeyboardInterrupt, MemoryError):
            raise
        except Exception as exc:  # noqa: BLE001 - every failure of a task is isolated
            self.record(task, reason_of(exc))
            return None

    def summary(self) -> str:
        """Every failure as ``name: reason``, the failures separated by semicolons."""
        return "; ".join(f"{k}: {v}" for k, v in self.items().items())

    def items(self) -> dict[str, str]:
        """A copy of the record: task name -> reason."""
        with self._lock:
            return dict(self._items)

    def __len__(self) -> int:
        with self._lock:
            return len(self._items)

    def __bool__(self) -> bool:
        return len(self) > 0
