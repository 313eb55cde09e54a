"""Connecting to a Dask cluster, with one-line errors (``--scheduler``, ``scheduler=``).

Two kinds of work run on a Dask cluster: whole datasets (``hystdisc discover --each
--scheduler ADDRESS``, :mod:`hystdisc.cli.batch`) and the independent tasks of one
discovery (``Discovery(scheduler=ADDRESS)``, ``hystdisc discover FILE --scheduler
ADDRESS``, :mod:`hystdisc.pipeline.tasks`). Both connect here: :func:`connect` makes the
client and :func:`check_workers` refuses workers that lack this version of hystdisc,
before any work is sent. Each problem is a one-line
:class:`~hystdisc.errors.HystdiscError` naming its fix:

- dask.distributed not installed: :data:`DASK_MISSING`;
- a malformed address (checked before a client is made);
- no scheduler answering within :data:`CONNECT_TIMEOUT` seconds;
- a connected worker that cannot import hystdisc, or has another version of it.

This module imports nothing heavy: dask.distributed is imported inside the functions.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from hystdisc.errors import HystdiscError

#: One-line error when ``--scheduler`` is used without dask.distributed installed.
DASK_MISSING = "--scheduler needs dask.distributed; fix: pip install hystdisc[dask]"

#: Seconds to wait for a Dask scheduler to answer before giving up with a one-line error.
CONNECT_TIMEOUT = 5.0


def check_address(address: str) -> None:
    """Raise ValueError, with dask's reason, if ``address`` cannot name a Dask scheduler."""
    from distributed.comm.addressing import get_address_host_port, parse_address
    from distributed.comm.registry import get_backend

    scheme, _ = parse_address(address)
    get_backend(scheme)  # unknown scheme -> ValueError listing the known ones
    if scheme != "inproc":  # in-process addresses have no host and port
        _, port = get_address_host_port(address)
        if not 0 < int(port) < 65536:
            raise ValueError(f"port {port} is not between 1 and 65535")


def connect(scheduler: Any) -> tuple[Any, bool]:
    """A dask.distributed Client for an address (or the Client given), and whether the
    caller owns it (and must close it).

    The address is checked before a Client is made (a Client whose constructor fails on a
    malformed address is left half-open, and its finaliser prints a traceback after a
    40 s wait), and the connection waits at most :data:`CONNECT_TIMEOUT` seconds.

    Parameters
    ----------
    scheduler : str or distributed.Client
        A scheduler's address (``tcp://host:8786``) or a connected client.

    Returns
    -------
    client : distributed.Client
        The client.
    own : bool
        The client was made here (False: ``scheduler`` itself).

    Raises
    ------
    HystdiscError
        dask.distributed is missing (:data:`DASK_MISSING`), the address is malformed, or
        no scheduler answers there within :data:`CONNECT_TIMEOUT` seconds.
    """
    try:
        from distributed import Client
    except ImportError:
        raise HystdiscError(DASK_MISSING) from None
    if isinstance(scheduler, Client):
        return scheduler, False
    address = str(scheduler)
    try:
        check_address(address)
    except ValueError as exc:
        raise HystdiscError(
            f"--scheduler {address}: not a Dask scheduler address ({exc}); fix: give the "
            "address the scheduler prints, e.g. tcp://10.0.0.5:8786"
        ) from None
    try:
        return Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False), True
    except (OSError, TimeoutError) as exc:
        msg = " ".join(str(exc).split())
        why = "" if not msg or msg.startswith("Timed out") else f" ({msg})"
        raise HystdiscError(
            f"--scheduler {address}: cannot connect: no Dask scheduler answered within "
            f"{CONNECT_TIMEOUT:g} s{why}; fix: start one with 'dask scheduler' (and workers with 'dask worker "
            "ADDRESS'), or check the address"
        ) from None


def worker_version() -> str:
    """hystdisc's version, run on a Dask worker (unpickling this function imports hystdisc)."""
    from hystdisc import __version__

    return __version__


def check_workers(client: Any, say: Callable[[str], None]) -> None:
    """Fail in one line if a connected Dask worker lacks this version of hystdisc.

    A worker that cannot import hystdisc cannot even read a task, and the work would wait
    for ever; a worker with another version would compute other results. Workers that
    join later are not checked.

    Parameters
    ----------
    client : distributed.Client
        The connected client.
    say : callable
        Receives a message when no worker has joined yet.

    Raises
    ------
    HystdiscError
        A worker cannot import hystdisc or has another version of it.
    """
    from hystdisc import __version__

    address = client.scheduler.address
    found = client.run(worker_version, on_error="return")
    if not found:
        say(f"waiting for Dask workers to join the scheduler at {address}")
    for worker, version in sorted(found.items()):
        if isinstance(version, BaseException):
            why = " ".join(str(version).split()) or type(version).__name__
            # errors of client.run come back as Exception('Name("message")')
            why = re.sub(r"^(\w+)\((['\"])(.*)\2\)$", r"\1: \3", why)
            raise HystdiscError(
                f"--scheduler {address}: the Dask worker {worker} cannot import hystdisc "
                f"({why}); fix: pip install hystdisc=={__version__} on every worker and "
                "restart the workers"
            )
        if version != __version__:
            raise HystdiscError(
                f"--scheduler {address}: the Dask worker {worker} has hystdisc {version}, "
                f"this machine {__version__}, so its results would differ; fix: pip install "
                f"hystdisc=={__version__} on every worker and restart the workers"
            )
