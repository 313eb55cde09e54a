"""The families compared again with the effects the closing loop accepted.

The family table compares the families without any effect, and an effect the data carry
distorts each family's fit differently. On a Bouc-Wen release whose spring rests 20 mrad
off the sensor zero (an effect of the rig, :attr:`hystdisc.models.Effect.rig`), both
Bouc-Wen forms were bent into generating energy (not physical), LuGre was selected, and
the loop covered the rest of its misfit with quadratic damping and a compliant wheel, at
1.13x the noise. On a standard-form Bouc-Wen damper with quadratic damping (an effect of
the damper), the seed form mimicked the standard form's missing term better, was selected
by 290 BIC, and the loop then found the quadratic damping on the wrong form (and, with
exact Jacobians, a Coulomb friction to trim the form's misfit).

When the loop accepts effects with a term form, :func:`reselect` has every family fitted
with those it can carry (:func:`refit_families`: from stage 1's start of family plus
effects and from the family's own optimum with the effects at the loop's values, each
judged on held-out data; the loop's own final model stands for the selected family when
it fits better than that family's refit, since the loop may have reached it from more
starts, e.g. an offset restarted on the shifted angle) and picks one by the family
table's rule (:func:`~hystdisc.selection.families.select_family`: admissible, held-out
error, BIC);
when that is another family, the loop is closed again from that family's fit, and the
switch is kept only when the same rule, applied to the two final models, selects the new
one (:class:`Reselection` records both). A structural effect (a compliant wheel)
is not carried to another family: it is fitted as its own state-space system.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from hystdisc.closing.refit import candidate_effects, refit_with, stage1_start
from hystdisc.closing.residual import NOISE_RATIO
from hystdisc.fitting import OEFit
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS
from hystdisc.selection.families import select_family
from hystdisc.simulation.admissibility import check_admissible


def term_effects(effects: Sequence[str]) -> list[str]:
    """The effects in ``effects`` that have a term form (not a structural one): the ones
    every family is fitted with again.

    Examples
    --------
    >>> term_effects(["offset", "quadratic_damping", "series_compliance"])
    ['offset', 'quadratic_damping']
    """
    return [e for e in effects if not EFFECTS[e].structural]


def _silent(msg: str) -> None:
    """Drop a progress message (the default of :attr:`Context.say`)."""


@dataclass(frozen=True)
class Context:
    """What comparing the families again after the loop needs (the estimator's data and
    its callbacks), shared by :func:`reselect`,
    :func:`~hystdisc.closing.reduction.reduce_family` and
    :func:`~hystdisc.closing.again.compare_again`.

    Attributes
    ----------
    data : FitData
        The output-error data.
    eq : EqData
        The equation-error data (stage 1's start of a family plus effects).
    envelope : Envelope
        The training envelope (admissibility).
    close : callable
        Called with a family's fit, closes the loop on it and returns the ``LoopResult``.
    shapes : callable
        Called with a fit, returns its family's stage-1 shape constants.
    max_nfev : int
        Simulation budget of each refit.
    heldout : bool
        Judge the refits on held-out data.
    mapper : callable or None
        ``mapper(fn, items) -> list`` for independent refits (default: in turn).
    say : callable
        Progress messages.
    """

    data: FitData
    eq: Any
    envelope: Any
    close: Callable[[OEFit], Any]
    shapes: Callable[[OEFit], Any]
    max_nfev: int = 60
    heldout: bool = True
    mapper: Callable | None = None
    say: Callable[[str], None] = _silent


def refit_families(
    family_fits: Mapping[str, OEFit],
    effects: Sequence[str],
    data: FitData,
    eq: Any,
    values: Mapping[str, float],
    shapes: Callable[[OEFit], Any],
    max_nfev: int = 60,
    heldout: bool = True,
    mapper: Callable | None = None,
) -> dict[str, OEFit]:
    """Each family's fit with the ``effects`` it can carry, judged on held-out data.

    Parameters
    ----------
    family_fits : mapping of str to OEFit
        Each family's output-error fit without the effects (term families).
    effects : sequence of str
        The effects (term form) to add; each family takes the ones that are candidates
        for it (:func:`~hystdisc.closing.refit.candidate_effects`: a family that already
        has an effect's terms keeps its own).
    data : FitData
        The output-error data.
    eq : EqData
        The equation-error data (stage 1's start of each family plus the effects).
    values : mapping of str to float
        The effects' parameters where the loop found them (the second start).
    shapes : callable
        Called with a fit, returns the stage-1 shape constants of its family (where the
        start's shape search begins).
    max_nfev : int
        Simulation budget of each fit.
    heldout : bool
        Compute each refit's held-out error (leave one test condition out).
    mapper : callable, optional
        ``mapper(fn, items) -> list`` (the estimator's threads); default: in turn.

    Returns
    -------
    dict of str to OEFit
        Family name -> its fit with the effects, in the order of ``family_fits`` (its
        table fit when it can carry none of them).
    """
    names = list(family_fits)
    good = NOISE_RATIO * data.noise_std

    def one(name: str) -> OEFit:
        fit = family_fits[name]
        can = set(candidate_effects(fit, data)[0])
        added = [e for e in effects if e in can]
        if not added:
            return fit
        # a state-space family has no stage-1 form: its refit starts at its own optimum
        start = None if fit.is_system else stage1_start(eq, fit, added, data, s0=shapes(fit))
        return refit_with(
            data,
            fit,
            added,
            estimate=dict(values),
            max_nfev=max_nfev,
            heldout=heldout,
            start=start,
            good_rms=good,
        )

    fits = mapper(one, names) if mapper is not None else [one(n) for n in names]
    return dict(zip(names, fits, strict=True))


@dataclass
class Reselection:
    """The families compared again with the effects the loop accepted.

    Attributes
    ----------
    effects : list of str
        The effects every family was refitted with (those it can carry).
    fits : dict of str to OEFit
        Each family's fit with them.
    admissible : dict of str to bool
        Whether each of those fits is physically admissible.
    before : str
        The family selected without the effects.
    pick : str
        The family the usual rules select among ``fits``.
    switched : bool
        True when ``pick`` differs from ``before`` and its final model (the loop closed
        again from it) is selected over ``before``'s by the same rule: it is the selected
        family.
    final_heldout : dict of str to float or None
        The held-out RMS of the final model of ``before`` and (when the loop was closed
        again) of ``pick``.
    note : str
        What was compared and decided, in one sentence.
    loop : LoopResult or None
        The loop closed again from ``pick`` (None when ``pick`` is ``before``).
    """

    effects: list[str]
    fits: dict[str, OEFit]
    admissible: dict[str, bool]
    before: str
    pick: str
    switched: bool = False
    final_heldout: dict[str, float | None] = field(default_factory=dict)
    note: str = ""
    loop: Any = None

    def to_dict(self) -> dict[str, Any]:
        """The ``reselection`` entry of ``results.json``."""
        return {
            "effects": list(self.effects),
            "families": {
                n: {
                    "rms": f.rms,
                    "heldout_rms": f.heldout_rms,
                    "bic": f.bic,
                    "admissible": self.admissible[n],
                }
                for n, f in self.fits.items()
            },
            "before": self.before,
            "pick": self.pick,
            "switched": self.switched,
            "final_heldout": dict(self.final_heldout),
            "note": self.note,
        }


def reselect(
    family_fits: Mapping[str, OEFit],
    before: str,
    loop: Any,
    effects: Sequence[str],
    ctx: Context,
    starts: Mapping[str, float] | None = None,
) -> Reselection:
    """Compare the families again with the ``effects`` the loop accepted on ``before``.

    Every family is refitted with them (:func:`refit_families`; ``before``'s refit gives
    way to ``loop``'s final model when that has the same effects and a lower BIC) and the
    usual rule picks one (:func:`~hystdisc.selection.families.select_family`). When that
    is another family, the loop is closed again from its fit (``ctx.close``), and the
    switch is made (``switched``) only when the same rule, applied to the new final model
    and ``loop``'s, selects the new one and it is admissible.

    Parameters
    ----------
    family_fits : mapping of str to OEFit
        The family table's fits (every family, state-space ones included), without
        effects.
    before : str
        The family selected from the table.
    loop : LoopResult
        The loop closed on ``before`` (its final fit carries the effects' values).
    effects : sequence of str
        The accepted effects with a term form (:func:`term_effects`), and any the loop
        passed every test but the held-out one (:func:`~hystdisc.closing.again.absorbed`).
    ctx : Context
        The data and the callbacks.
    starts : mapping of str to float, optional
        Start values of the parameters of effects that ``loop`` did not accept (a delay
        stage 1's scan saw).

    Returns
    -------
    Reselection
    """
    say, envelope = ctx.say, ctx.envelope
    final = loop.fit
    values = {**(starts or {}), **effect_values(final, effects)}
    names = ", ".join(effects)
    rejected = [e for e in effects if e not in loop.effects]
    how = (
        "which the loop then found"
        if not rejected
        else f"which the loop tried on {before} and did not accept ({', '.join(rejected)})"
    )
    say(f"selection again: every family with {names}")
    fits = refit_families(family_fits, effects, ctx.data, ctx.eq, values, ctx.shapes,
                          ctx.max_nfev, ctx.heldout, ctx.mapper)  # fmt: skip
    # the loop's final model is a fit of ``before`` with these effects too, and the loop
    # may have reached it from more starts (an offset restarted on the shifted angle):
    # the family's refit from its own starts must not stand for it when it fits worse
    own = fits[before]
    if (
        type(final.par) is type(own.par)
        and set(final.par.effects) == set(own.par.effects)
        and final.bic < own.bic
    ):
        fits[before] = final
    adm = {n: check_admissible(_admissible_form(f), envelope) for n, f in fits.items()}
    pick, _ = select_family(fits, adm)
    res = Reselection(list(effects), fits, {n: a.ok for n, a in adm.items()}, before, pick)
    res.final_heldout[before] = final.heldout_rms
    if pick == before:
        res.note = f"with {names} in every family, {before} is still selected"
        return res
    say(f"selection again: {pick} is selected with {names}; closing the loop from it")
    res.loop = ctx.close(family_fits[pick])
    new = res.loop.fit
    res.final_heldout[pick] = new.heldout_rms
    # the two final models, judged by the same rule
    winner, fadm = judge({before: final, pick: new}, envelope)
    table = versus(fits[pick], fits[before])
    if winner != pick or not fadm[pick].ok:
        why = "" if fadm[pick].ok else f", not physical: {fadm[pick].violations[0]}"
        res.note = (
            f"with {names} in every family {pick} was selected over {before} ({table}), "
            f"but its final model was not ({versus(new, final)}{why}): {before} kept"
        )
        return res
    res.switched = True
    res.note = (
        f"{before} was selected without {names}, {how}; with {names} "
        f"in every family {pick} is selected ({table}), and so is its final model "
        f"({versus(new, final)}): {pick} selected"
    )
    return res


def effect_values(final: OEFit, effects: Sequence[str]) -> dict[str, float]:
    """Starting values of the effects' parameters: the final fit's own (an effect the loop
    accepted), or the final model's coefficient of a one-term effect's term (an effect
    whose term the family carries natively: :mod:`hystdisc.closing.reduction`); the
    finite ones."""
    torque = {} if final.is_system else final.term_part.torque
    out = {}
    for e in effects:
        eff = EFFECTS[e]
        for p in eff.params:
            if p.name in final.params:
                out[p.name] = float(final.params[p.name])
            elif len(eff.params) == 1 and len(eff.terms) == 1 and eff.terms[0] in torque:
                out[p.name] = float(torque[eff.terms[0]])
    return {k: v for k, v in out.items() if np.isfinite(v)}


def judge(fits: Mapping[str, OEFit], envelope: Any) -> tuple[str, dict[str, Any]]:
    """The family table's rule (:func:`~hystdisc.selection.families.select_family`) on
    ``fits`` (final models: a state-space one judged as a system), with each one's
    admissibility."""
    adm = {n: check_admissible(_admissible_form(f), envelope) for n, f in fits.items()}
    return select_family(fits, adm)[0], adm


def _admissible_form(fit: OEFit) -> Any:
    """What the admissibility check takes of ``fit``: a state-space model as a system,
    any other as its term part."""
    return fit.model if fit.is_system else fit.term_part


def versus(a: OEFit, b: OEFit) -> str:
    """``held-out A vs B, BIC A vs B`` of two fits, for a note."""
    ha, hb = (f"{h:.4g}" if h is not None else "-" for h in (a.heldout_rms, b.heldout_rms))
    return f"held-out {ha} vs {hb}, BIC {a.bic:.1f} vs {b.bic:.1f}"
