"""Stage: stage 1's sparse regression for each hysteresis shape, and every family's first
output-error fit from it.

A family's first fit starts as soon as its own shape's stage-1 search has ended, on the
threads the other shapes leave free (:func:`~hystdisc.simulation.parallel.map_after`; on a
Dask cluster, once every shape's has: :class:`~hystdisc.pipeline.tasks.ClusterTasks`).
The discovered structure is fitted too when no family has it. A delay between the recorded
channels that stage 1 sees (:mod:`hystdisc.discovery.delay`) enters every family before
they are compared: compared without it, the family that best absorbs the lag would win.
"""

from __future__ import annotations

from hystdisc.closing.measured import add_to_fits
from hystdisc.discovery import FAMILY_SHAPE, SHAPES, describe_structure, fit_shape
from hystdisc.discovery.delay import scan_delay
from hystdisc.errors import HystdiscError
from hystdisc.fitting import OutputErrorFitter, TermParametrization
from hystdisc.models import EFFECTS, FAMILIES
from hystdisc.pipeline.families import first_fit
from hystdisc.pipeline.state import State
from hystdisc.registry import get_experiment


def _delay_effect():
    """The catalogued effect that delays the recorded output (its ``delay_param``)."""
    return next((e for e in EFFECTS.values() if e.delay_param), None)


def _same_structure(state: State, best) -> list[str]:
    """The compared families whose structure stage 1 discovered (``best``)."""
    return [
        n
        for n in state.compared
        if FAMILY_SHAPE[n] == best.shape
        and set(FAMILIES[n].torque_terms) == set(best.terms) - {"theta"}
    ]


def first_fits(state: State) -> None:
    """Stage 1 for each shape, the first fit of each family (and of the discovered
    structure when no family has it), the delay scan."""
    opts, eq, fd, say, failures = state.options, state.eq, state.fd, state.say, state.failures
    shapes, fams = list(opts.shapes), list(state.compared)

    def shape_fit(shape):
        say(f"stage 1: sparse regression with hysteresis shape '{shape}'")
        return failures.guard(
            f"stage 1 shape {shape}",
            fit_shape, eq, shape, state.library, opts.threshold, opts.ensemble, opts.seed,
        )  # fmt: skip

    def family_fit(k, ready):
        """The first fit of family ``k`` from its shape's stage-1 search (``ready``: the
        stage-1 fits, waited for), or (``k = len(fams)``) of the discovered structure
        when no family has it."""
        if k == len(fams):
            done = [f for f in (ready(j) for j in range(len(shapes))) if f is not None]
            if not done:
                return None
            best = min(done, key=lambda f: f.bic)
            if _same_structure(state, best):
                return None
            say("stage 2: output-error fit of the discovered structure")
            tpar = TermParametrization(
                best.terms, best.shape, best.coefs, best.s, best.J, eq.experiment
            )
            fitter = OutputErrorFitter(fd, tpar, max_nfev=opts.max_nfev)
            return failures.guard("discovered structure", fitter.fit, heldout=False)
        name = fams[k]
        shape = FAMILY_SHAPE[name]
        say(f"stage 2: output-error fit of {name} ({k + 1}/{len(fams)})")
        own = ready(shapes.index(shape)) if shape in shapes else None  # its search ended
        return first_fit(state, name, None if own is None else own.s)

    # the ensemble draws from numpy's global generator: one shape after the other
    fits, firsts = state.map_after(
        shape_fit, shapes, family_fit, list(range(len(fams) + 1)), opts.ensemble
    )
    state.stage1 = {s: f for s, f in zip(shapes, fits, strict=True) if f is not None}
    if not state.stage1:
        raise HystdiscError(
            f"{state.dataset.source}: stage 1 failed for every hysteresis shape "
            f"({failures.summary()}); fix: check that the runs move and the output "
            "responds to the motion"
        )
    best = min(state.stage1.values(), key=lambda f: f.bic)
    exp = get_experiment(eq.experiment)
    state.discovered_shape = best.shape
    state.discovered = best.term_model()
    state.terms = {
        "torque": [t for t in best.terms if not (t == "theta" and not exp.motion_imposed)],
        "hysteresis": list(SHAPES[best.shape].terms),
    }
    state.discovered_name = describe_structure(best.terms, best.shape)
    state.same = _same_structure(state, best)
    if exp.motion_imposed and not any(fd.run_filters()):  # (stage 1 sees no filter)
        state.delay_scan = failures.guard(
            "delay scan", scan_delay, eq, best.terms, best.s, best.shape
        )
    found = dict(zip(fams, firsts, strict=False))
    delay = _delay_effect()
    if state.delay_scan is not None and state.delay_scan.found and delay is not None:
        say(f"stage 2: a channel delay of {state.delay_scan.tau:.3g} s enters every family")
        state.chain_effects.append(delay.name)
        state.chain[delay.delay_param] = state.delay_scan.tau
        found = add_to_fits(fd, found, delay.name, state.chain, opts.max_nfev, state.map, failures)
    # a family whose first fit failed is dropped (its reason is in failed)
    state.family_fits = {n: f for n, f in found.items() if f is not None}
    state.compared = [n for n in fams if n in state.family_fits]
    state.same = [n for n in state.same if n in state.family_fits]
    state.first_discovered = firsts[-1]
