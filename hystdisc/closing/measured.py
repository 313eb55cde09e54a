"""A measurement effect found before the families are compared, and judged after.

A delay between the recorded channels makes every family miss; compared without it, the
families are judged on how well they absorb the lag (:mod:`hystdisc.discovery.delay`
finds it from stage 1). Every family is therefore refitted with the effect
(:func:`add_to_fits`) before the comparison, and once a family is selected the effect is
judged on it like any effect of the closing loop (:func:`judge`): the fit without it is
made, and the effect stays only if it lowers BIC by the loop's margin and does not
predict the held-out conditions worse.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np

from hystdisc.closing.records import AcceptedEffect
from hystdisc.closing.refit import EFFECT_BIC_MARGIN, fit_ok
from hystdisc.faults import Failures
from hystdisc.fitting import OEFit, OutputErrorFitter


@dataclass
class MeasuredVerdict:
    """The judgement of a measurement effect on the selected family (:func:`judge`).

    Attributes
    ----------
    entry : AcceptedEffect or None
        The effect, when it is kept (an entry of ``results.json``'s ``effects``).
    note : str
        The verdict in words (``"<name> (<why>): accepted"`` or why it is rejected).
    """

    entry: AcceptedEffect | None
    note: str


def add_to_fits(
    data,
    fits: Mapping[str, OEFit | None],
    name: str,
    values: Mapping[str, float],
    max_nfev: int,
    mapper: Callable,
    failures: Failures,
) -> dict[str, OEFit | None]:
    """Each fit of ``fits`` refitted with the effect ``name`` added, started at its optimum
    and the effect's ``values`` (a fit without a family parametrization, or None, is kept
    as it is; a refit that fails keeps the fit without the effect, recorded)."""

    def one(item):
        key, fit = item
        if fit is None or not hasattr(fit.par, "like") or name in fit.par.effects:
            return fit
        par = fit.par.like({**fit.params, **values}, (*fit.par.effects, name))
        new = failures.guard(
            f"{key} with {name}", OutputErrorFitter(data, par, max_nfev=max_nfev).fit, False
        )
        return fit if new is None else new

    return dict(zip(fits, mapper(one, list(fits.items())), strict=True))


def judge(
    data, fit: OEFit, name: str, max_nfev: int, heldout: bool, why: str
) -> tuple[OEFit, MeasuredVerdict]:
    """The effect ``name`` of ``fit`` judged against the fit without it.

    Returns the fit to go on with (``fit``, or the one without the effect) and the
    verdict: the accepted effect's entry (None when rejected) and a note.
    """
    keep = tuple(e for e in fit.par.effects if e != name)
    par = fit.par.like(dict(fit.params), keep)
    with np.errstate(all="ignore"):
        without = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
    if heldout and fit.heldout_rms is None:
        fit = OutputErrorFitter(data, fit.par, max_nfev=max_nfev).heldout_at(fit)
    better = without.bic - fit.bic > EFFECT_BIC_MARGIN
    predicts = not heldout or (
        fit.heldout_rms is not None
        and (without.heldout_rms is None or fit.heldout_rms <= without.heldout_rms)
    )
    accepted = better and predicts and fit_ok(fit, without)
    verdict = "accepted" if accepted else (
        "rejected: " + ("it does not lower BIC by the margin" if not better
                        else "it does not predict the held-out conditions better")
    )  # fmt: skip
    note = f"{name} ({why}): {verdict}"
    entry = AcceptedEffect.between(name, fit, without, fit) if accepted else None
    return (fit if accepted else without), MeasuredVerdict(entry, note)
