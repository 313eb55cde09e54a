"""Stage: the families' fits made global, their held-out errors, the state-space families.

A first fit at the noise floor that does not predict the held-out runs is no proof of the
optimum (a seed-form Bouc-Wen at 1.009x the noise with ``n = 0.01`` predicted them at 164x,
where its true optimum, 66 sigma^2 lower in RSS, predicts them at 1x); a family above the
floor is fitted from more starts, its related families' optima among them (fitted as
starts only when they were not asked for), and no family ends worse than a model it
contains (:func:`~hystdisc.fitting.multistart.nesting_pass`). A fit that diverges at its
optimum is no result and is dropped (:func:`~hystdisc.fitting.multistart.drop_diverged`).
"""

from __future__ import annotations

from hystdisc.closing.residual import NOISE_RATIO
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OEFit, OutputErrorFitter
from hystdisc.fitting.multistart import (
    best_of_starts,
    drop_diverged,
    helper_families,
    mapped_starts,
    nesting_pass,
    poor_predictions,
    term_starts,
)
from hystdisc.models import FAMILIES
from hystdisc.pipeline.families import family_par, first_fit, system_family_fit
from hystdisc.pipeline.state import State
from hystdisc.selection.staged import levels_start


def _starts_of(state: State, name: str, first: OEFit, poor: dict, mapper) -> OEFit:
    """Family ``name`` from its other starts (its first fit is the first)."""
    opts, fd = state.options, state.fd
    pars = []
    n = max(int(opts.n_starts), 1)
    for label, start in term_starts(
        state.eq, name, n, opts.seed, state.shape0(name), state.single_current,
        first.par.params(first.par.x0),
    ):  # fmt: skip
        pars.append((label, family_par(state, name, start)))
    if (lv := levels_start(fd, first.par, first.params)) is not None:
        pars.append(("current levels", first.par.like(lv, first.par.effects)))
    # the optima of the related families, read in this one (no stage 1 involved)
    for other in FAMILIES[name].start_from:
        ofit = state.family_fits.get(other)
        readings = [] if ofit is None else mapped_starts(name, ofit)
        for k, reading in enumerate(readings):
            label = f"{other}'s optimum" + (f" {k + 1}" if len(readings) > 1 else "")
            pars.append((label, family_par(state, name, reading)))
    # a first start at the floor that predicts poorly is not trusted (no good_rms)
    good = None if name in poor else NOISE_RATIO * fd.noise_std
    return best_of_starts(
        fd, pars, opts.max_nfev, mapper=mapper, say=state.say, name=name, good_rms=good,
        first=first, failures=state.failures,
    )  # fmt: skip


def _more_starts(state: State, name: str, poor: dict, mapper=None) -> OEFit:
    """Family ``name`` from its other starts, screened on the threads of ``mapper`` when
    given; its first fit when they fail (recorded)."""
    first = state.family_fits[name]
    found = state.failures.guard(f"{name} more starts", _starts_of, state, name, first, poor,
                                 mapper)  # fmt: skip
    return first if found is None else found


def _with_heldout(state: State, name: str) -> OEFit:
    """Family ``name``'s fit with its held-out error (as it is when not asked or failed)."""
    fit = state.family_fits[name]
    if not state.options.heldout or fit.heldout_rms is not None:
        return fit
    fitter = OutputErrorFitter(state.fd, fit.par, max_nfev=state.options.max_nfev)
    found = state.failures.guard(f"{name} held-out folds", fitter.heldout_at, fit)
    return fit if found is None else found  # no held-out error: said in failed


def global_fits(state: State) -> None:
    """More starts for a family above the floor, nesting kept, held-out errors."""
    opts, fd, say, failures = state.options, state.fd, state.say, state.failures
    good = NOISE_RATIO * fd.noise_std
    fams = list(state.compared)
    with_heldout = lambda n: _with_heldout(state, n)  # noqa: E731
    poor: dict[str, str] = {}
    if opts.n_starts > 1 and opts.heldout and fd.n_runs >= 2:
        poor = poor_predictions(state.family_fits, good, with_heldout, state.map)
    # a family above the floor whose related families were not asked for (a declared
    # family, a short --families list) gets them fitted too, as its starts only
    helping = helper_families(state.family_fits, good, poor) if opts.n_starts > 1 else {}
    helpers = list(dict.fromkeys(h for hs in helping.values() for h in hs))
    if helpers:
        say(f"stage 2: {', '.join(helpers)} fitted as starts (not compared)")
        fitted = state.map(lambda h: first_fit(state, h), helpers)
        state.family_fits.update(
            (h, f) for h, f in zip(helpers, fitted, strict=True) if f is not None
        )
    nest = len(state.family_fits) > 1  # no family ends worse than a model it contains
    if nest:
        state.family_fits = nesting_pass(
            fd, state.family_fits, opts.max_nfev, say, failures=failures
        )
    # every family still above the noise is fitted from more starts: however far it is
    # from the best family, it may be the true one in a wrong basin (a Bingham release on
    # an encoder stopped at 4.9x LuGre's RMS from stage 1's start and reached the floor
    # from its current-levels start)
    more = [n for n, f in state.family_fits.items() if f.rms > good or n in poor]
    if opts.n_starts > 1:
        if len(more) == 1:
            # one family alone: its starts are screened on the threads (independent fits;
            # the same answer as in turn)
            state.family_fits[more[0]] = _more_starts(state, more[0], poor, state.map)
        elif more:
            refits = state.map(lambda n: _more_starts(state, n, poor), more)
            state.family_fits.update(zip(more, refits, strict=True))
    if nest and more:
        # after the starts: a family still above the floor screens the mapped optima too
        state.family_fits = nesting_pass(
            fd, state.family_fits, opts.max_nfev, say, screen_above=good, failures=failures
        )
    for name, why in poor.items():
        state.family_fits[name].notes.append(
            f"its first start fitted at the noise floor but {why}: a wrong basin can fit "
            "the data it saw, so its other starts were run too"
        )
    for name, hs in helping.items():  # the helpers' fits only served as starts
        state.family_fits[name].notes.append(
            f"its first start ended above the noise floor: {', '.join(hs)} were fitted "
            "too, their optima as further starts (not compared)"
        )
    # the table holds the compared families only (the helpers served as starts)
    state.family_fits = dict(zip(fams, state.map(with_heldout, fams), strict=True))


def system_fits(state: State) -> None:
    """The state-space families, from the optimum of the term family each declares as
    its start (fitted for them when the table lacks it); then no diverged fit stays."""
    bases: dict[str, OEFit | None] = dict(state.family_fits)
    for name in state.systems:
        base_name = FAMILIES[name].start_base
        if base_name not in bases:
            state.say(f"stage 2: output-error fit of {base_name} (the start of {name})")
            bases[base_name] = first_fit(state, base_name)
        base = bases[base_name]
        fit = None
        if base is None:
            state.failures.record(name, f"no start: the {base_name} fit its starts map failed")
        else:
            fit = state.failures.guard(name, system_family_fit, state, name, base)
        if fit is not None:
            state.family_fits[name] = fit
    state.family_fits = drop_diverged(state.family_fits, state.failures)  # none is a result
    state.compared = [n for n in state.compared if n in state.family_fits]
    state.same = [n for n in state.same if n in state.family_fits]
    if not state.family_fits:
        raise HystdiscError(
            f"{state.dataset.source}: every family failed ({state.failures.summary()}); fix: "
            "check the data (hystdisc report shows them) or name other families"
        )
    first = state.first_discovered
    state.discovered_fit = (
        state.family_fits[state.same[0]]
        if state.same
        else first
        if first is not None
        else min(state.family_fits.values(), key=lambda f: f.bic)
    )
