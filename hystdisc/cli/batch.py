"""Discover many datasets at once: serially, on local processes, or on a Dask cluster.

``hystdisc discover A.csv B.csv --each --jobs 2`` treats every file (or folder) as a
dataset of its own and runs :class:`~hystdisc.Discovery` on each, in parallel
over datasets. The work of one dataset is always done by the same function,
:func:`discover_one`, in a fresh :class:`~hystdisc.Discovery` whose options are
passed by value, and the ``results.json`` text is produced where the fit ran; the parent
process only writes files. So the results of a parallel run are byte-identical to those of
the serial run (discovery is deterministic for a given ``seed``, and it limits BLAS to one
thread).

Backends
--------
- serial (``jobs=1``, the default): in this process, with progress messages;
- local processes (``jobs=N``): :class:`joblib.Parallel` with the ``loky`` backend;
- a Dask cluster (``scheduler=ADDRESS`` or a :class:`distributed.Client`): the datasets
  are mapped on the cluster's workers, which need ``hystdisc`` installed and the data
  files readable at the same paths (the files are read by the workers). Install the
  optional extra with ``pip install hystdisc[dask]``. A scheduler that does not answer
  within :data:`~hystdisc.cluster.CONNECT_TIMEOUT` seconds, a malformed address, and a
  connected worker that cannot import this version of ``hystdisc`` are one-line errors
  before any work is sent (:mod:`hystdisc.cluster`); Ctrl-C cancels the datasets still
  queued or running on the cluster. (To run the tasks of *one* discovery on a cluster
  instead, see :mod:`hystdisc.pipeline.tasks`.)

A dataset that fails with a :class:`~hystdisc.errors.HystdiscError` (bad input) does not
stop the others: its one-line message is returned in :attr:`BatchItem.error`.

Examples
--------
>>> import tempfile, pathlib
>>> from hystdisc.data import write_csv
>>> from hystdisc.simulation.synth import generate
>>> with tempfile.TemporaryDirectory() as d:
...     f = pathlib.Path(d, "dahl.csv")
...     _ = write_csv(generate("dahl", currents=(0, 1), duration=2, seed=1), f)
...     items = discover_many([f], discovery_options={"families": ["dahl"], "heldout": False,
...                                                   "close_loop": False})
...     items[0].family, items[0].error
('dahl', None)
"""

from __future__ import annotations

import contextlib
import os
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from hystdisc.cluster import CONNECT_TIMEOUT, DASK_MISSING, check_workers, connect
from hystdisc.errors import HystdiscError, HystdiscWarning

__all__ = [
    "CONNECT_TIMEOUT", "DASK_MISSING", "BatchItem", "discover_many", "discover_one",
    "output_paths",
]  # fmt: skip


@dataclass
class BatchItem:
    """Outcome of the discovery of one dataset.

    Attributes
    ----------
    source : str
        The file or folder the dataset was read from.
    results_json : str or None
        The ``results.json`` text (None when the dataset failed).
    report : str or None
        The console summary (``Results.report()``).
    family : str or None
        The selected (or declared) family.
    error : str or None
        The one-line message of a :class:`~hystdisc.errors.HystdiscError`, if any.
    warnings : list of str
        Messages of the :class:`~hystdisc.errors.HystdiscWarning` raised on the way.
    """

    source: str
    results_json: str | None = None
    report: str | None = None
    family: str | None = None
    error: str | None = None
    warnings: list[str] = field(default_factory=list)


def discover_one(
    source: str | os.PathLike[str],
    load_options: Mapping[str, Any] | None = None,
    discovery_options: Mapping[str, Any] | None = None,
) -> BatchItem:
    """Load one dataset and discover its model (the unit of work of every backend).

    Parameters
    ----------
    source : path-like
        A data file or a folder of runs (see :func:`hystdisc.data.load`).
    load_options : dict, optional
        Keyword arguments of :func:`hystdisc.data.load` (``experiment``, ``rig``, ...).
    discovery_options : dict, optional
        Keyword arguments of :class:`~hystdisc.Discovery`.

    Returns
    -------
    BatchItem
        The ``results.json`` text and the report, or the error message.
    """
    from hystdisc.cli.common import fit_discovery, make_discovery
    from hystdisc.data import load

    item = BatchItem(str(source))
    options = dict(discovery_options or {})
    progress = options.pop("progress", None)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", HystdiscWarning)
        try:
            data = load(str(source), **dict(load_options or {}))
            disc = fit_discovery(make_discovery(options), data, progress)
        except HystdiscError as exc:
            item.error = str(exc)
        else:
            item.results_json = disc.results_.to_json()
            item.report = disc.results_.report()
            item.family = disc.family_
    item.warnings = [str(w.message) for w in caught if issubclass(w.category, HystdiscWarning)]
    return item


def discover_many(
    sources: Sequence[str | os.PathLike[str]],
    *,
    load_options: Mapping[str, Any] | None = None,
    discovery_options: Mapping[str, Any] | None = None,
    jobs: int = 1,
    scheduler: Any = None,
    progress: Callable[[str], None] | None = None,
) -> list[BatchItem]:
    """Discover every source as its own dataset, serially or in parallel over datasets.

    Parameters
    ----------
    sources : sequence of path-like
        Data files or folders; each is one dataset.
    load_options, discovery_options : dict, optional
        As for :func:`discover_one` (``discovery_options`` must not hold ``progress`` when
        running in parallel: callables do not travel to other processes; it is dropped).
    jobs : int
        Number of local worker processes (joblib ``loky``); 1 runs in this process,
        -1 uses every core.
    scheduler : str or distributed.Client, optional
        Address of a Dask scheduler (``tcp://host:8786``) or a connected client; overrides
        ``jobs``.
    progress : callable, optional
        Receives one short message per finished dataset (and the serial run's messages).

    Returns
    -------
    list of BatchItem
        In the order of ``sources``, whatever the order of completion.

    Raises
    ------
    HystdiscError
        ``jobs`` is 0 or below -1, dask.distributed is missing for ``scheduler``, the
        address is malformed or no scheduler answers there within
        :data:`~hystdisc.cluster.CONNECT_TIMEOUT` seconds, or a connected worker lacks this
        version of hystdisc.
    """
    sources = [str(s) for s in sources]
    if not isinstance(jobs, int) or jobs == 0 or jobs < -1:
        raise HystdiscError(
            f"--jobs {jobs}: not a number of processes; fix: give 1, 2, ... or -1 (all cores)"
        )
    say = progress or (lambda msg: None)
    disc_opts = {k: v for k, v in dict(discovery_options or {}).items() if k != "progress"}
    load_opts = dict(load_options or {})
    n = len(sources)

    def done(k: int, item: BatchItem) -> None:
        what = f"error: {item.error}" if item.error else f"family {item.family}"
        say(f"dataset {k + 1}/{n} done: {item.source} -> {what}")

    items: list[BatchItem | None] = [None] * n
    if scheduler is not None:
        client, own = connect(scheduler)
        futures: list[Any] = []
        try:
            from distributed import as_completed

            check_workers(client, say)
            futures = client.map(
                discover_one,
                sources,
                load_options=load_opts,
                discovery_options=disc_opts,
                pure=False,
            )
            index = {f.key: k for k, f in enumerate(futures)}
            for fut in as_completed(futures, loop=client.loop):
                k = index[fut.key]
                items[k] = fut.result()
                done(k, items[k])
        except BaseException:
            # Ctrl-C or an error: do not leave the other datasets running on the cluster
            if futures:
                with contextlib.suppress(Exception):
                    client.cancel(futures)
            raise
        finally:
            if own:
                client.close()
    elif jobs == 1 or n <= 1:
        for k, src in enumerate(sources):
            opts = dict(disc_opts)
            if progress is not None:
                opts["progress"] = lambda msg, s=src: say(f"{Path(s).name}: {msg}")
            items[k] = discover_one(src, load_opts, opts)
            done(k, items[k])
    else:
        from joblib import Parallel, delayed

        par = Parallel(n_jobs=min(jobs, n) if jobs > 0 else jobs, return_as="generator")
        # one thread per dataset: the processes already fill the cores
        opts = {"n_jobs": 1, **dict(disc_opts)}
        gen = par(delayed(discover_one)(src, load_opts, opts) for src in sources)
        for k, item in enumerate(gen):
            items[k] = item
            done(k, item)
    out = [it for it in items if it is not None]
    for it in out:
        for msg in it.warnings:
            warnings.warn(msg, HystdiscWarning, stacklevel=2)
    return out


def output_paths(sources: Sequence[str | os.PathLike[str]], out_dir: str | os.PathLike[str]):
    """``DIR/<stem>.results.json`` for every source; two sources with one stem are an error.

    Examples
    --------
    >>> [p.name for p in output_paths(["a/run1.csv", "b/run2.mat"], "out")]
    ['run1.results.json', 'run2.results.json']
    """
    paths: list[Path] = []
    seen: dict[str, str] = {}
    for s in sources:
        p = Path(s)
        stem = p.name if p.is_dir() else p.stem
        if stem in seen:
            raise HystdiscError(
                f"{s}: has the same name as {seen[stem]}, so both would be written to "
                f"{stem}.results.json; fix: rename one or run them separately with --out"
            )
        seen[stem] = str(s)
        paths.append(Path(out_dir) / f"{stem}.results.json")
    return paths
