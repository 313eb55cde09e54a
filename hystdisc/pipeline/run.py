"""The pipeline of one discovery: named stages over one typed state.

=====================  ===================================================================
stage                  what it does
=====================  ===================================================================
``prepare``            the runs validated, both stages' data prepared, the families to
                       compare decided (:mod:`~hystdisc.pipeline.prepare`)
``first_fits``         stage 1 for each hysteresis shape, every family's first
                       output-error fit, the delay between the channels
                       (:mod:`~hystdisc.pipeline.first`)
``global_fits``        more starts, nesting, held-out errors (:mod:`~hystdisc.pipeline.starts`)
``system_fits``        the state-space families from their base's optimum; no diverged fit
``choose``             selection, measurement effects judged, glitches, the staged fit
                       (:mod:`~hystdisc.pipeline.choose`)
``close``              the closing loop, the comparison again, the final model
                       (:mod:`~hystdisc.pipeline.close`)
=====================  ===================================================================

:func:`run` runs them in order and returns the :class:`~hystdisc.pipeline.state.State`;
the independent tasks inside a stage run on the discovery's threads, or on a Dask cluster
(``scheduler``: :mod:`hystdisc.pipeline.tasks`). Any task inside a stage that fails is
recorded in ``state.failures`` and the run goes on (:mod:`hystdisc.faults`);
:func:`~hystdisc.pipeline.record.build_results` makes ``results.json`` of the state.
"""

from __future__ import annotations

import sys
import time
import warnings
from collections.abc import Callable
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from hystdisc.data import Dataset
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OEFit
from hystdisc.pipeline.choose import choose
from hystdisc.pipeline.close import close
from hystdisc.pipeline.first import first_fits
from hystdisc.pipeline.options import Options
from hystdisc.pipeline.prepare import prepare
from hystdisc.pipeline.starts import global_fits, system_fits
from hystdisc.pipeline.state import State
from hystdisc.pipeline.tasks import Say, ThreadTasks, task_engine
from hystdisc.simulation.parallel import limit_threads


def stderr_printer() -> Callable[[str], None]:
    """Progress on stderr as ``[  1.2 s] message`` (the command line's form)."""
    t0 = time.perf_counter()

    def say(msg: str) -> None:
        print(f"[{time.perf_counter() - t0:6.1f} s] {msg}", file=sys.stderr, flush=True)

    return say


def fit_family(dataset: Dataset, options: Options, family: str) -> OEFit | None:
    """``family`` fitted on ``dataset`` with ``options`` and all its starts, without the
    loop or the staged fit (the restart of a shift or a play effect:
    :func:`~hystdisc.closing.motion_restart.motion_restart`); None when it fails."""
    opts = options.replace(model=family, close_loop=False, staged=False, ensemble=False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            state = run(dataset, opts)
    except (HystdiscError, np.linalg.LinAlgError, ValueError, FloatingPointError):
        return None
    return state.family_fits[state.family]


def run(
    dataset: Dataset,
    options: Options,
    progress: Callable[[str], None] | None = None,
    scheduler: Any = None,
) -> State:
    """Every stage in turn on ``dataset`` (see the module docstring).

    Parameters
    ----------
    dataset : Dataset
        The runs.
    options : Options
        What to do.
    progress : callable, optional
        Receives short progress messages.
    scheduler : str or distributed.Client, optional
        Run the independent tasks on this Dask cluster (its scheduler's address or a
        client) instead of this process's threads (:mod:`hystdisc.pipeline.tasks`; the
        same results).

    Returns
    -------
    State
        Filled by the stages (``failed``: what failed and was dropped).

    Raises
    ------
    HystdiscError
        Bad data, or a ``scheduler`` that cannot be used
        (:func:`~hystdisc.pipeline.tasks.task_engine`).
    """
    state = State(dataset, options, Say(progress))
    # small dense algebra on tall matrices: extra BLAS threads only add overhead; the
    # simulations of a batch run side by side on up to n_jobs threads
    with (
        task_engine(scheduler, options.n_jobs, state.failures, state.say) as tasks,
        np.errstate(all="ignore"),
        threadpool_limits(limits=1),
        limit_threads(options.n_jobs),
    ):
        state.tasks = tasks
        try:
            prepare(state)
            first_fits(state)
            global_fits(state)
            system_fits(state)
            choose(state)
            close(state, lambda data, family: fit_family(data, options, family))
        finally:
            state.tasks = ThreadTasks(options.n_jobs)  # no client kept past its close
            if state.eq_data is not None:  # the fitted estimator keeps the data, not the memo
                state.eq_data.forget()
    state.failed = state.failures.items()
    return state
