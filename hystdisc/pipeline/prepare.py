"""Stage: the data prepared, and what is compared decided.

One current (a rig without a coil, the hysteretic benchmark) is accepted: the families
are compared at it, and the current dependence is reported as not identifiable.
"""

from __future__ import annotations

import warnings

from hystdisc.data import Dataset, distinct_currents, validate, with_detected_filter
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.fitting.jacobian import check_jacobian_mode
from hystdisc.measurement.motion import MOTION_MODES
from hystdisc.measurement.prepare import prepare_data
from hystdisc.models import FAMILIES
from hystdisc.pipeline.state import State
from hystdisc.registry import get_experiment


def prepare(state: State) -> None:
    """Validate the runs, prepare both stages' data (noise model, glitches, derivatives,
    the imposed motion), choose stage 1's library and the families compared."""
    dataset, opts = state.dataset, state.options
    if not isinstance(dataset, Dataset):
        raise TypeError("Discovery.fit expects a hystdisc.data.Dataset (see hystdisc.load)")
    families = opts.family_list()
    validate(dataset, need_currents=1)
    if opts.detect_filter:
        # a moving average the records went through, read in them when none is declared
        dataset, state.prefilter = with_detected_filter(dataset)
        if state.prefilter is not None:
            state.dataset = dataset
            warnings.warn(
                f"{dataset.source}: {state.prefilter.describe()}: the fits see the model "
                "through it (declare it in a rig file's [filter], or --no-detect-filter to "
                "fit the records as they are)",
                HystdiscWarning,
                stacklevel=4,
            )
    levels = distinct_currents(dataset.currents)
    state.single_current = len(levels) < 2
    if state.single_current and not opts.single_current:  # declared: no warning needed
        check = (
            " (if the runs were recorded at different currents, check the current column "
            "and its unit: --column current=NAME, --units current=mA)"
            if levels[0] == 0.0 and len(dataset.runs) > 1
            else ""
        )
        what = "the family is fitted" if opts.model is not None else "the families are compared"
        warnings.warn(
            f"{dataset.source}: all runs share one current ({levels[0]:g} A); {what} at "
            "it, and the current dependence is not identifiable: the current-dependent "
            f"parameters are fixed at 0 and the i* terms left out of the library{check}",
            HystdiscWarning,
            stacklevel=4,
        )
    state.say("preparing data (noise, derivatives)")
    check_jacobian_mode(opts.jacobian)  # before any fit, not in each one's failure
    if opts.motion not in MOTION_MODES:
        raise HystdiscError(f"unknown motion estimate '{opts.motion}'; fix: use auto or legacy")
    eq, fd, state.glitches, state.noise = prepare_data(
        dataset, opts.experiment, opts.input_hold, motion=opts.motion,
        motion_errors=opts.motion_errors, jacobian=opts.jacobian, integration=opts.integration,
    )  # fmt: skip
    state.eq_data, state.fit_data, state.experiment = eq, fd, eq.experiment
    exp = get_experiment(eq.experiment)
    terms = list(opts.torque_terms)
    if exp.motion_imposed and "theta" not in terms:
        terms = ["theta", *terms]
    if state.single_current:
        terms = [t for t in terms if not t.startswith("i")]
    state.library = terms
    # the lazily built arrays the workers share are built before they start
    eq.row_index  # noqa: B018
    fd.bulk()
    if exp.has_input and fd.hold == "cubic":
        fd.input_slopes()
    state.systems = [n for n in families if FAMILIES[n].is_system]
    if opts.model is None and opts.families is None and not exp.motion_imposed:
        # by default the state-space families are compared on driven data, where the
        # force shows their internal state; name them to compare them on a rig
        state.systems = []
    state.compared = [n for n in families if not FAMILIES[n].is_system]
