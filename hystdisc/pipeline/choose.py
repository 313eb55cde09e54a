"""Stage: a family selected from the table, its measurement effects judged, its glitches
confirmed, the seed's staged flowchart.

Selection: a conclusion counts only if it predicts data the fit did not see, with
physically admissible parameters. The candidates are the families that are admissible
(they dissipate energy and their spring stiffens over twice the training envelope; all
families when none is) and whose held-out error is not clearly worse than the best one's;
among them the lowest BIC wins (:func:`~hystdisc.selection.families.select_family`).
"""

from __future__ import annotations

import warnings

from hystdisc.closing.measured import judge as judge_measured
from hystdisc.data import distinct_currents
from hystdisc.data.envelope import Envelope
from hystdisc.errors import HystdiscWarning
from hystdisc.measurement import confirm_glitches
from hystdisc.pipeline.state import State
from hystdisc.selection import MIN_STAGED_LEVELS, select_family, staged_fit
from hystdisc.simulation.admissibility import check_admissible


def choose(state: State) -> None:
    """Envelope, admissibility, the selection, the measurement effects judged on the
    selected family, the confirmed glitches and (``staged``) the staged fit."""
    opts, fd, say, failures = state.options, state.fd, state.say, state.failures
    state.envelope = Envelope.from_runs(fd.names, fd.t, fd.theta, fd.theta_dot, fd.currents)
    state.admissibility = {
        n: check_admissible(f.model, state.envelope) for n, f in state.family_fits.items()
    }
    state.family, state.selection_note = select_family(state.family_fits, state.admissibility)
    state.declared = opts.model is not None
    selected = state.family_fits[state.family]
    for name in state.chain_effects:  # each measurement effect judged on the selected family
        why = "found by the delay scan of stage 1, in every family of the table"
        found = failures.guard(f"effect {name}", judge_measured, fd, selected, name,
                               opts.max_nfev, opts.heldout, why)  # fmt: skip
        if found is not None:
            selected, verdict = found
            state.family_fits[state.family] = selected
            state.measured.append(verdict)
    # a glitch the selected model reproduces is a feature: it enters the fits again
    state.outliers = confirm_glitches(state.glitches, fd, selected.predictions)
    if state.outliers.count:
        say(state.outliers.summary())
    n_levels = distinct_currents(fd.currents).size
    if opts.staged and n_levels >= MIN_STAGED_LEVELS:
        state.staged = failures.guard(
            "staged fit", staged_fit, fd, selected, opts.max_nfev, opts.heldout, say
        )
        if state.staged is not None and state.staged.changed:
            # the chosen laws predict the held-out conditions better: they are the
            # selected family's model from here on (loop, results.json, predict)
            selected = state.staged.joint
            state.family_fits[state.family] = selected
            state.admissibility[state.family] = check_admissible(selected.model, state.envelope)
    elif opts.staged:
        warnings.warn(
            f"{state.dataset.source}: {n_levels} current level(s); the staged fit needs "
            f"{MIN_STAGED_LEVELS} and did not run (fix: record runs at more currents)",
            HystdiscWarning,
            stacklevel=4,
        )
