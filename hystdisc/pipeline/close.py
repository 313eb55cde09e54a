"""Stage: the closing loop on the selected family, the families compared again with its
effects, the final model.

When the loop accepts effects with a term form, every family is compared again with them
(:mod:`hystdisc.closing.reselect`); when the selected family's intervals hold the values
where it is a smaller family plus effects, the smaller model is fitted and selected by
the same rule (:mod:`hystdisc.closing.reduction`). Families whose BIC lies within
:data:`EQUAL_FIT_BIC` of the selected one's fit equally well.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable

from hystdisc.closing import LoopResult, close_loop
from hystdisc.closing.again import compare_again
from hystdisc.closing.library_refit import TermsRefit, refit_admissible
from hystdisc.closing.motion_restart import motion_restart
from hystdisc.closing.open_library import (
    ResidualTerms,
    regress_output_residual,
    regress_residual,
)
from hystdisc.closing.refit import has_spring
from hystdisc.closing.reselect import Context
from hystdisc.closing.share_restart import first_of, share_restart
from hystdisc.discovery.delay import MIN_DBIC
from hystdisc.errors import HystdiscWarning
from hystdisc.fitting import OEFit
from hystdisc.models import EFFECTS
from hystdisc.pipeline.families import first_fit
from hystdisc.pipeline.state import State
from hystdisc.simulation.admissibility import check_admissible

#: Families whose BIC lies within this of the selected one "fit equally well".
EQUAL_FIT_BIC = 6.0


def decided_by_staged(state: State) -> dict[str, str]:
    """Effects the staged fit decided (name -> why): the effects whose role is a current
    law (the staged fit chose the laws, and they are the selected family's model)."""
    if state.staged is None:
        return {}
    chosen = ", ".join(f"{d['parameter']} {d['law']}" for d in state.staged.laws.values())
    why = f"the staged fit chose the current laws ({chosen})"
    return {name: why for name, eff in EFFECTS.items() if eff.has_role("current_law")}


def decided_by_spring(fit: OEFit) -> dict[str, str]:
    """Effects the rig's spring decides (name -> why): on a rig with a spring, an effect
    whose role is ``no_spring`` is a spring effect in other words (a constant force is
    the spring's neutral angle, which the spring effects try)."""
    if not has_spring(fit):
        return {}
    why = "the rig has a spring: a constant force is its neutral angle (tried as such)"
    return {name: why for name, eff in EFFECTS.items() if eff.has_role("no_spring")}


def _loop(state: State, fit: OEFit, restart: Callable | None) -> LoopResult:
    """The closing loop on ``fit``."""
    state.say("closing the loop: residual -> catalogued effects")
    return close_loop(
        fit,
        state.fd,
        state.noise_std,
        state.eq,
        state.stage1_shape(fit),
        max_nfev=state.options.max_nfev,
        heldout=True,
        progress=state.say,
        envelope=state.envelope,
        decided={**decided_by_staged(state), **decided_by_spring(fit)},
        noise_samples=state.noise.samples if state.noise is not None else None,
        restart=restart,
        failures=state.failures,
        first=seen_delay(state),
        library=lambda f: library_effects(state, f),
    )


def library_effects(state: State, fit: OEFit) -> dict[str, dict[str, float]]:
    """The loop's open library (:func:`~hystdisc.closing.loop.augment`'s ``library``):
    the catalogued effects the open library finds in ``fit``'s residual, each with start
    values (a play term: the catalogued play at the term's width); nothing when the
    library fails.

    The catalogue's own diagnosis ranks an effect by its local signature at the current
    optimum, which a play's misses: on the UTFSM damper its secant evidence was 0.012,
    while the library selected a play term in every bootstrap refit."""
    lib = state.failures.guard("open library", open_library, state, fit)
    if lib is None:
        return {}
    state.open_library = lib  # the final fit's, when the loop ends on ``fit``
    state.open_library_of = fit
    out: dict[str, dict[str, float]] = {}
    width = lib.play_found()
    for name in lib.effects:
        eff = EFFECTS[name]
        out[name] = {}
        if eff.play_param and width is not None:
            out[name][eff.play_param] = width
    return out


def seen_delay(state: State) -> tuple[str, ...]:
    """The channel-delay effect, when stage 1's scan saw a lag (its BIC fell by more than
    :data:`~hystdisc.discovery.delay.MIN_DBIC`) too small a share of the equation error to
    enter every family (:data:`~hystdisc.discovery.delay.MIN_SHARE`): the structure's own
    misfit can remove as large a share (a tanh or Spencer damper's, without any delay:
    8-23 % on the driven suite's sets), so the closing loop refits it whatever its rank
    and its held-out error decides."""
    scan = state.delay_scan
    if scan is None or scan.found or not scan.dbic < -MIN_DBIC:
        return ()
    return tuple(name for name, eff in EFFECTS.items() if eff.delay_param)


def seen_values(state: State) -> dict[str, dict[str, float]]:
    """The effects of :func:`seen_delay`, each with its delay at the scan's optimum (the
    start of the delay when the families are compared again with it)."""
    scan = state.delay_scan
    return {name: {EFFECTS[name].delay_param: scan.best} for name in seen_delay(state)}


def open_library(state: State, fit: OEFit) -> ResidualTerms | None:
    """The open library on the final model's residual (:mod:`hystdisc.closing.open_library`):
    the force residual of a driven test (any family), else the equation residual of a
    model with a term form; None for a state-space model of a test that measures no force."""
    state.say("closing the loop: the residual regressed on the open library")
    if state.fd.exp.output == "torque":
        return regress_output_residual(state.fd, fit, seed=state.options.seed)
    if fit.is_system:
        return None
    return regress_residual(state.eq, fit.term_part, seed=state.options.seed)


def refit_library(state: State, lib: ResidualTerms, fit: OEFit) -> TermsRefit | None:
    """The open library's stable terms refitted into ``fit``'s model by output error and
    judged on held-out conditions (:func:`~hystdisc.closing.library_refit.refit_admissible`),
    when the linearized screen (:attr:`ResidualTerms.heldout`) says they predict the
    held-out conditions better; None otherwise (a test whose output is not the force has
    no such screen)."""
    h = lib.heldout
    if not lib.terms or h is None or not h.after < h.before:
        return None
    state.say("closing the loop: the open library's terms refitted into the model, held out")
    return refit_admissible(
        state.fd, fit, [t.name for t in lib.terms], floor=state.noise_std,
        max_nfev=state.options.max_nfev, envelope=state.envelope,
    )  # fmt: skip


def term_fit(state: State, name: str) -> OEFit | None:
    """The term family ``name``'s fit: the table's, else its first fit (made now); the
    start of a state-space family's restart with a share its force carries
    (:func:`~hystdisc.closing.share_restart.share_restart`)."""
    fit = state.family_fits.get(name)
    return fit if fit is not None else first_fit(state, name)


def close(state: State, fit_family: Callable) -> None:
    """The loop, the comparison again, equal fits, the final model and its admissibility.

    ``fit_family(dataset, family)`` fits one family with all its starts and no loop (the
    restart of a shift or a play effect:
    :func:`~hystdisc.closing.motion_restart.motion_restart`); a share a state-space
    family's force carries is restarted from its start family's fit
    (:func:`~hystdisc.closing.share_restart.share_restart`).
    """
    opts, fd, failures = state.options, state.fd, state.failures
    selected = state.family_fits[state.family]
    restart = None
    if opts.close_loop:
        motion = fd.motion_noise.std if fd.motion_noise is not None else 0.0
        restart = first_of(
            motion_restart(
                state.dataset, fit_family, state.say, min_shift=fd.noise_std, min_play=motion
            ),
            share_restart(
                fd, state.eq, lambda name: term_fit(state, name), state.stage1_shape,
                opts.max_nfev, state.say, state.map,
            ),
        )  # fmt: skip
        state.loop = _loop(state, selected, restart)
    state.bics = {n: f.bic for n, f in state.family_fits.items()}
    # the staged laws belong to the selected family alone: no other family replaces it
    staged_changed = state.staged is not None and state.staged.changed
    compare = opts.model is None and len(state.compared) > 1 and not staged_changed
    if compare and state.loop is not None:
        ctx = Context(fd, state.eq, state.envelope, lambda fit: _loop(state, fit, restart),
                      state.stage1_shape, opts.max_nfev, opts.heldout, state.map,
                      state.say)  # fmt: skip
        again = failures.guard("comparison with the effects", compare_again,
                               dict(state.family_fits), state.family, state.loop,
                               ctx, seen_values(state))  # fmt: skip
        if again is not None:
            state.reselection, state.reduction = again.reselection, again.reduction
        if again is not None and again.bics is not None:  # outliers as first confirmed
            state.family, state.selection_note = again.family, again.note
            state.loop, state.bics = again.loop, again.bics
            selected = state.family_fits[state.family]
    # equal fits: among the fits of the comparison that made the selection
    ref = state.bics[state.family]
    state.equal_fits = sorted(
        n for n, b in state.bics.items() if b - ref < EQUAL_FIT_BIC and n != state.family
    )
    state.final_fit = selected if state.loop is None else state.loop.fit
    if state.loop is not None and state.loop.unexplained:
        if state.open_library_of is not state.final_fit:  # (the loop's last one is kept)
            state.open_library = state.failures.guard(
                "open library", open_library, state, state.final_fit
            )
    else:
        state.open_library = None
    if state.open_library is not None:
        state.open_library.refit = failures.guard(
            "open library refit", refit_library, state, state.open_library, state.final_fit
        )
    # a measurement effect judged before the loop that the final model no longer carries
    # (an effect of the loop made it redundant) is not reported as found
    for v in state.measured:
        if v.entry is not None and v.entry.name not in state.final_fit.par.effects:
            why = "the final model does not carry it"
            if state.loop is not None:
                why = state.loop.dropped.get(v.entry.name, why)
            v.note = f"{v.note}; then dropped: {why}"
            v.entry = None
    kept = [v.entry.name for v in state.measured if v.entry is not None]
    state.effects = kept + ([] if state.loop is None else list(state.loop.effects))
    final = state.final_fit
    state.final_admissibility = (
        state.admissibility[state.family]
        if final is selected  # the loop accepted nothing: already checked
        else check_admissible(
            final.model if final.is_system else final.term_part, state.envelope
        )  # fmt: skip
    )
    if not state.final_admissibility.ok:
        warnings.warn(
            f"{state.dataset.source}: THE RESULT IS NOT PHYSICAL: "
            f"{'; '.join(state.final_admissibility.violations)}; do not use the model "
            "beyond the training data (fix: see the family table for an admissible family)",
            HystdiscWarning,
            stacklevel=4,
        )
