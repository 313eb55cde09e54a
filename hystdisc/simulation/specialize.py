"""Compiled kernels specialized to a model's compiled functions, cached on disk.

The error-controlled integrator (:mod:`hystdisc.simulation.ode`) works for any
state-space model: it calls the model's compiled ``rate`` and ``observe``. Passed as
first-class function arguments, numba cannot cache the compiled integrator, and compiling
it costs seconds to tens of seconds per model class in every new process (measured: 36 s
for Spencer's driven model on a loaded 2-core machine, then 0.01 s per call).
:func:`specialize` instead builds, once per process and model, a copy of a kernel
*template* whose free names (``rate``, ``observe``) are bound as globals to the model's
functions, with a name of its own; numba then caches it like any module-level kernel.

The name carries a digest of the source files of the bound functions' modules, so a
change of a model's equations compiles afresh instead of loading a stale kernel (numba's
own cache only watches the template's file).

Examples
--------
>>> import numba
>>> @numba.njit
... def twice(x):
...     return 2.0 * x
>>> def apply_template(x):
...     return rate(x) + 1.0  # noqa: F821 - bound by specialize
>>> k = specialize(apply_template, rate=twice)
>>> k(3.0)
7.0
>>> specialize(apply_template, rate=twice) is k  # built once per process
True
"""

from __future__ import annotations

import hashlib
import inspect
import os
import re
import sys
import threading
import types
from collections.abc import Callable

import numba

_BUILT: dict[tuple, Callable] = {}
#: Longest kernel name spelled out with its functions' names (the cache files add ~40
#: characters; a longer name keeps only the template's name and the digest).
MAX_NAME = 160
#: Threads (:mod:`hystdisc.simulation.parallel`) build each kernel once between them.
_LOCK = threading.Lock()


def _source_digest(fn) -> str:
    """Digest of the source file of ``fn``'s module (its equations and helpers)."""
    py = getattr(fn, "py_func", fn)
    try:
        text = inspect.getsource(sys.modules[py.__module__])
    except (OSError, TypeError, KeyError):  # no source (an interactive definition)
        text = py.__module__ + py.__qualname__
    return hashlib.sha1(text.encode()).hexdigest()[:10]


def specialize(template: Callable, **bound: Callable) -> Callable:
    """A cached, compiled copy of ``template`` with its free names bound to ``bound``.

    Parameters
    ----------
    template : callable
        A plain Python function (or a numba dispatcher: its ``py_func`` is used) whose
        global names in ``bound`` are left free.
    **bound : numba functions
        The compiled functions to bind, by the names the template uses.

    Returns
    -------
    numba dispatcher
        ``njit(cache=True, nogil=True)`` of the bound copy (not cached on disk when the
        template has no source file, as in an interactive session); the same object for
        the same template and functions within a process.
    """
    py = getattr(template, "py_func", template)
    key = (py, *sorted((k, id(v)) for k, v in bound.items()))
    if key in _BUILT:
        return _BUILT[key]
    with _LOCK:
        if key not in _BUILT:
            _BUILT[key] = _build(py, bound)
    return _BUILT[key]


def _build(py, bound: dict) -> Callable:
    """The compiled copy of the template ``py`` with ``bound`` (see :func:`specialize`)."""
    names, ident = [], []
    for name, fn in sorted(bound.items()):
        f = getattr(fn, "py_func", fn)
        names.append(re.sub(r"\W", "_", f.__qualname__))
        ident.append(f"{name}={f.__module__}.{f.__qualname__}:{_source_digest(fn)}")
    digest = hashlib.sha1(";".join(ident).encode()).hexdigest()[:12]
    # the cache file is named after it: short, unique per functions and their sources
    qual = f"{py.__name__}__{'__'.join(names)}__{digest}"
    if len(qual) > MAX_NAME:  # file systems limit a name to 255 bytes
        qual = f"{py.__name__}__{digest}"
    scope = dict(py.__globals__)
    scope.update(bound)
    fn = types.FunctionType(py.__code__, scope, qual, py.__defaults__, py.__closure__)
    fn.__qualname__ = qual
    fn.__module__ = py.__module__
    fn.__doc__ = py.__doc__
    on_disk = os.path.isfile(py.__code__.co_filename)
    return numba.njit(cache=on_disk, nogil=True)(fn)
