"""What the closing loop records: each refit's verdict, the effects accepted, each round's
diagnosis, and the loop's whole outcome.

These are the loop's own typed records. The ``results.json`` tables
(:mod:`hystdisc.results.records`) are made from them, field by field, by the pipeline's
results builder (:func:`hystdisc.pipeline.record.build_results`): no plain table is built
here and parsed back there.

Examples
--------
>>> v = EffectVerdict("coulomb", 1, evidence=0.4, rms_before=2.0, bic_before=-10.0)
>>> v.acceptable, v.rejection()
(False, 'its refit did not converge to finite values')
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hystdisc.closing.refit import EFFECT_BIC_MARGIN, EffectSkipped
from hystdisc.closing.residual import ResidualVerdict
from hystdisc.closing.scores import EffectScore
from hystdisc.closing.structural import StartOutcome
from hystdisc.fitting import OEFit
from hystdisc.models import EFFECTS


@dataclass
class EffectVerdict:
    """The verdict on one refit of the closing loop: the current model plus one effect.

    The attributes up to :attr:`points_at` are what ``results.json`` reports of the refit
    (``effects_tried``); the tests behind the verdict follow.

    Attributes
    ----------
    name : str
        Catalogue name of the effect.
    round : int
        Round of the loop (1 first).
    evidence : float
        Output-error evidence of its diagnosis (:attr:`EffectScore.evidence`).
    evidence_eq : float or None
        Its equation-error evidence.
    start_rms : float or None
        Output-error RMS of its stage-1 start (None when not screened).
    rms_before, bic_before : float
        RMS and BIC of the current model.
    rms_after, bic_after : float or None
        RMS and BIC of the refit (None when the refit is not usable: :attr:`ok`).
    wald_chi2 : float or None
        Squared z-score of the effect's parameters in the refit (None when not finite).
    heldout_rms_before : float or None
        Held-out RMS of the current model.
    heldout_rms_after : float or None
        Held-out RMS of the refit: computed only for a refit that passes every other test.
    converged : bool
        The refit's success flag.
    accepted : bool
        The effect is in the model (False again when a later effect removed it).
    admissible : bool
        The refit is physically admissible.
    excess_share : float
        Share of the residual's excess over the noise that the refit removes.
    starts : list of StartOutcome or None
        A structural refit: how the fit from each of its starts ended
        (:class:`~hystdisc.closing.structural.StructuralRefit`); None for another refit.
    starts_spread : float or None
        A structural refit: the relative spread of the fitted values among its starts.
    restarted : bool
        The refit is from a restart (:data:`~hystdisc.closing.rounds.Restart`: the
        family fitted again on the shifted angle) and the better for it.
    removed : bool
        Accepted, then dropped again when a later effect made it redundant.
    note : str or None
        Why it is not accepted (None when it is).
    points_at : str or None
        The physics that the sign the data want, outside the admissible bounds, points
        at (:attr:`~hystdisc.models.Effect.hint`); None when the sign is admissible.
    ok : bool
        The refit is usable: finite, its simulation did not blow up.
    improves : bool
        It lowers BIC by more than :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN` and
        removes at least :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the excess,
        or lowers the held-out error of every one of its (at least
        :data:`~hystdisc.closing.rounds.MIN_FOLDS_ALL`) held-out folds.
    significant : bool
        :attr:`wald_chi2` is above ``log N``.
    predicts : bool
        It does not predict the held-out data worse (True when the current model has no
        held-out error).
    violation : str or None
        Its first admissibility violation.
    wants : str or None
        The values the data want outside the admissible bounds (``"c_q = -0.1"``).
    heldout_skipped : bool
        Its held-out error was not computed: another test had already failed.
    heldout_refit : bool
        Its held-out error is that of folds refitted completely from the joint optimum
        (every other test had passed and the quick estimate said it does not predict).
    heldout_folds, heldout_folds_lower : int or None
        For a refit that lowers BIC, is significant and admissible but removes less than
        :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the excess: its held-out
        folds, and those whose error it lowers (it improves when it lowers every one of
        at least :data:`~hystdisc.closing.rounds.MIN_FOLDS_ALL`); None otherwise.
    """

    name: str
    round: int
    evidence: float
    evidence_eq: float | None = None
    start_rms: float | None = None
    rms_before: float = float("nan")
    rms_after: float | None = None
    bic_before: float = float("nan")
    bic_after: float | None = None
    wald_chi2: float | None = None
    heldout_rms_before: float | None = None
    heldout_rms_after: float | None = None
    converged: bool = False
    accepted: bool = False
    admissible: bool = True
    excess_share: float = 0.0
    starts: list[StartOutcome] | None = None
    starts_spread: float | None = None
    restarted: bool = False
    removed: bool = False
    note: str | None = None
    points_at: str | None = None
    ok: bool = False
    improves: bool = False
    significant: bool = False
    predicts: bool = True
    violation: str | None = None
    wants: str | None = None
    heldout_skipped: bool = False
    heldout_refit: bool = False
    heldout_folds: int | None = None
    heldout_folds_lower: int | None = None

    @property
    def acceptable(self) -> bool:
        """Every test passed: better in BIC by the margin and in the excess, significant,
        better on held-out data, physically admissible."""
        return bool(self.improves and self.significant and self.predicts and self.admissible)

    @property
    def lowers_bic(self) -> bool:
        """Its refit lowered BIC by more than
        :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN`."""
        return self.bic_after is not None and self.bic_after < self.bic_before - EFFECT_BIC_MARGIN

    @property
    def share_only(self) -> bool:
        """It passed every test but the share of the excess: it lowered BIC, is
        significant, admissible and predicts the held-out data better, yet removes less
        than :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the residual's excess.
        Once another effect shrinks the excess, the same gain may be a share that counts
        (the loop tries it again then)."""
        return bool(
            self.ok
            and self.lowers_bic
            and not self.improves
            and self.significant
            and self.predicts
            and self.admissible
        )

    def rejection(self) -> str:
        """Why the effect is not accepted: every test it failed, in the order applied (the
        held-out error is not computed for a refit that failed another test).

        Returns
        -------
        str
            The failed tests, separated by semicolons.
        """
        if not self.ok:
            return "its refit did not converge to finite values"
        failed = []
        lowered = self.lowers_bic
        if not lowered:
            failed.append("did not lower BIC")
        elif not self.improves:
            folds = ""
            if self.heldout_folds is not None:
                folds = (
                    f" and lowers the held-out error in {self.heldout_folds_lower} of its "
                    f"{self.heldout_folds} held-out folds"
                )
            failed.append(
                f"removes only {100 * self.excess_share:.0f} % of the residual's excess over "
                f"the noise{folds}"
            )
        if not self.significant:
            wz = np.sqrt(self.wald_chi2 or 0.0)
            failed.append(f"its parameter is not significant (z = {wz:.2g})")
        hb, ha = self.heldout_rms_before, self.heldout_rms_after
        if self.heldout_skipped:
            pass  # not predicted: the other tests already rejected it
        elif hb is not None and not (ha is not None and ha < hb):
            after = "diverged" if ha is None else f"{ha:.4g}"
            why = ": it improves the fit only on the data it was fitted to" if lowered else ""
            why += " (each fold refitted completely)" if self.heldout_refit else ""
            failed.append(f"does not lower the held-out error ({hb:.4g} -> {after}){why}")
        if not self.admissible:
            failed.append(f"not physical: {self.violation}")
        return "; ".join(failed)

    def reject(self) -> None:
        """Record why the effect is not accepted (:attr:`note`), and, when the data want
        a sign outside its admissible bounds, what that points at (:attr:`points_at`)."""
        self.note = self.rejection()
        if self.wants:
            hint = EFFECTS[self.name].hint or "physics the catalogue lacks"
            self.points_at = hint
            self.note = (
                f"the data want {self.wants}, which is not physical: this points at {hint}; "
                f"with the admissible sign it {self.note}"
            )


@dataclass
class EffectParameter:
    """A parameter of an accepted effect in the final fit.

    Attributes
    ----------
    value : float or None
        The estimate (None when the fit does not report it).
    ci95 : tuple of float or None
        ``(low, high)``, its 95 % interval (NaN or None when the fit has none).
    """

    value: float | None
    ci95: tuple[float | None, float | None]


def effect_parameters(name: str, fit: OEFit) -> dict[str, EffectParameter]:
    """The parameters of the effect ``name`` in ``fit``, by name."""
    nan = float("nan")
    return {
        p.name: EffectParameter(fit.params.get(p.name), tuple(fit.ci95.get(p.name, (nan, nan))))
        for p in EFFECTS[name].params
    }


@dataclass
class AcceptedEffect:
    """An effect the model keeps: its parameters in the final fit and what it changed.

    Attributes
    ----------
    name : str
        Catalogue name.
    terms : tuple of str
        Torque terms it adds.
    parameters : dict of str to EffectParameter
        Its parameters in the final fit.
    rms_before, rms_after : float
        Output-error RMS without and with it.
    bic_before, bic_after : float
        BIC without and with it.
    heldout_rms_before, heldout_rms_after : float or None
        Held-out RMS without and with it.
    evidence, evidence_eq : float or None
        Its output- and equation-error evidence when the loop accepted it (None for an
        effect judged outside the loop: :func:`~hystdisc.closing.measured.judge`).
    """

    name: str
    terms: tuple[str, ...]
    parameters: dict[str, EffectParameter]
    rms_before: float
    rms_after: float
    bic_before: float
    bic_after: float
    heldout_rms_before: float | None = None
    heldout_rms_after: float | None = None
    evidence: float | None = None
    evidence_eq: float | None = None

    @classmethod
    def between(
        cls,
        name: str,
        final: OEFit,
        before: OEFit,
        after: OEFit,
        evidence: float | None = None,
        evidence_eq: float | None = None,
    ) -> AcceptedEffect:
        """The effect ``name`` with its parameters from ``final``, judged by the fits
        ``before`` (without it) and ``after`` (with it).

        Returns
        -------
        AcceptedEffect
            The record.
        """
        return cls(
            name,
            tuple(EFFECTS[name].terms),
            effect_parameters(name, final),
            before.rms,
            after.rms,
            before.bic,
            after.bic,
            before.heldout_rms,
            after.heldout_rms,
            evidence,
            evidence_eq,
        )


@dataclass
class Diagnosis:
    """One round's diagnosis: the candidates' scores as they were ranked.

    Attributes
    ----------
    round : int
        Round number (1 first).
    candidates : list of EffectScore
        Every candidate's score, ranked by evidence (copies: what the round saw).
    """

    round: int
    candidates: list[EffectScore] = field(default_factory=list)


@dataclass
class LoopResult:
    """Outcome of :func:`~hystdisc.closing.loop.augment`.

    Attributes
    ----------
    base : OEFit
        The fit the loop started from.
    fit : OEFit
        The final fit (the base fit plus every accepted effect).
    effects : list of str
        Accepted effects, in the order they were added.
    tried : list of EffectVerdict
        Every refitted effect, with its verdict.
    accepted : list of AcceptedEffect
        The accepted effects (parameters from the final fit).
    diagnosis : list of Diagnosis
        One entry per round: the ranked scores of every candidate.
    skipped : list of EffectSkipped
        Catalogued effects not considered, with the reason.
    residual : ResidualVerdict or None
        The verdict on the final residual (set when the loop ends).
    unexplained : bool
        True when structure remains that no catalogued effect removes.
    unexplained_text : str or None
        That structure in plain words.
    pointed : dict of str to dict
        The effects the open library pointed at (refitted in the library's round), each
        with the start values it gave (:func:`~hystdisc.closing.loop.augment`).
    dropped : dict of str to str
        Measurement effects the base fit carried into the loop (a channel delay judged
        before it) that an accepted effect made redundant, each with why: the final fit
        no longer has them.
    """

    base: OEFit
    fit: OEFit
    effects: list[str] = field(default_factory=list)
    tried: list[EffectVerdict] = field(default_factory=list)
    accepted: list[AcceptedEffect] = field(default_factory=list)
    diagnosis: list[Diagnosis] = field(default_factory=list)
    skipped: list[EffectSkipped] = field(default_factory=list)
    residual: ResidualVerdict | None = None
    unexplained: bool = False
    unexplained_text: str | None = None
    pointed: dict[str, dict[str, float]] = field(default_factory=dict)
    dropped: dict[str, str] = field(default_factory=dict)
