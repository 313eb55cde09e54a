"""The closing loop's typed records as the typed tables of ``results.json``.

The loop records its work in :mod:`hystdisc.closing.records` (each refit's
:class:`~hystdisc.closing.EffectVerdict`, the :class:`~hystdisc.closing.AcceptedEffect`
entries, each round's :class:`~hystdisc.closing.Diagnosis`, the
:class:`~hystdisc.closing.EffectSkipped` and the :class:`~hystdisc.closing.ResidualVerdict`);
:func:`~hystdisc.pipeline.record.build_results` turns them into the records of
:mod:`hystdisc.results.records` here, field by field, in the keys and order of
``results.json`` (an optional key is written only when it is set, as the loop always wrote
it).

Examples
--------
>>> from hystdisc.closing import EffectSkipped
>>> skipped_effect(EffectSkipped("offset", "no rig spring")).to_dict()
{'name': 'offset', 'reason': 'no rig spring'}
"""

from __future__ import annotations

from typing import Any

from hystdisc.closing import (
    AcceptedEffect,
    Diagnosis,
    EffectScore,
    EffectSkipped,
    EffectVerdict,
    LoopResult,
    ResidualVerdict,
)
from hystdisc.closing.structural import StartOutcome
from hystdisc.results.records import (
    DiagnosisRound,
    EffectCandidate,
    EffectStep,
    EffectTrial,
    ParameterResult,
    ResidualSummary,
    SkippedEffect,
)


def start_row(o: StartOutcome) -> dict[str, float]:
    """A structural refit's start as a row of ``starts``: ``<p>_start``, ``<p>``, ``rms``,
    ``bic``.

    Examples
    --------
    >>> start_row(StartOutcome("k_w", 400.0, 512.5, 1e-3, -9e4))
    {'k_w_start': 400.0, 'k_w': 512.5, 'rms': 0.001, 'bic': -90000.0}
    """
    return {f"{o.parameter}_start": o.start, o.parameter: o.value, "rms": o.rms, "bic": o.bic}


def effect_trial(v: EffectVerdict) -> EffectTrial:
    """The ``effects_tried`` entry of a refit's verdict."""
    optional: dict[str, Any] = {}
    if v.starts is not None:  # a structural refit: how its starts ended
        optional["starts"] = [start_row(o) for o in v.starts]
        optional["starts_spread"] = v.starts_spread
    if v.restarted:
        optional["restarted"] = True
    if v.removed:
        optional["removed"] = True
    if v.note is not None:
        optional["note"] = v.note
    if v.points_at is not None:
        optional["points_at"] = v.points_at
    if v.heldout_folds is not None:
        optional["heldout_folds"] = v.heldout_folds
        optional["heldout_folds_lower"] = v.heldout_folds_lower
    return EffectTrial.make(
        name=v.name,
        round=v.round,
        evidence=v.evidence,
        evidence_eq=v.evidence_eq,
        start_rms=v.start_rms,
        rms_before=v.rms_before,
        rms_after=v.rms_after,
        bic_before=v.bic_before,
        bic_after=v.bic_after,
        wald_chi2=v.wald_chi2,
        heldout_rms_before=v.heldout_rms_before,
        heldout_rms_after=v.heldout_rms_after,
        converged=v.converged,
        accepted=v.accepted,
        admissible=v.admissible,
        excess_share=v.excess_share,
        **optional,
    )


def effect_step(a: AcceptedEffect) -> EffectStep:
    """The ``effects`` entry of an accepted effect."""
    return EffectStep.make(
        name=a.name,
        terms=list(a.terms),
        parameters={
            k: ParameterResult.make(value=p.value, ci95=list(p.ci95))
            for k, p in a.parameters.items()
        },
        rms_before=a.rms_before,
        rms_after=a.rms_after,
        bic_before=a.bic_before,
        bic_after=a.bic_after,
        heldout_rms_before=a.heldout_rms_before,
        heldout_rms_after=a.heldout_rms_after,
        evidence=a.evidence,
        evidence_eq=a.evidence_eq,
    )


def effect_candidate(s: EffectScore) -> EffectCandidate:
    """The ``diagnosis`` entry of one candidate's score."""
    optional: dict[str, Any] = {}
    if s.starts is not None:  # a structural effect: its diagnosis screened starts
        optional["starts_screened"] = len(s.starts)
    if s.signature:
        optional["signature"] = s.signature
    if s.not_refitted:
        optional["not_refitted"] = s.not_refitted
    return EffectCandidate.make(
        name=s.name,
        terms=list(s.terms),
        evidence=s.evidence,
        evidence_per_run=list(s.per_run),
        evidence_eq=s.evidence_eq,
        predicted_dbic_eq=s.predicted_dbic_eq,
        start_rms=s.start_rms,
        start_dbic=s.start_dbic,
        lm=s.lm,
        predicted_rms=s.predicted_rms,
        predicted_dbic=s.predicted_dbic,
        estimate=dict(s.estimate),
        **optional,
    )


def diagnosis_round(d: Diagnosis) -> DiagnosisRound:
    """The ``diagnosis`` entry of one round."""
    return DiagnosisRound.make(
        round=d.round, candidates=[effect_candidate(s) for s in d.candidates]
    )


def skipped_effect(s: EffectSkipped) -> SkippedEffect:
    """The ``effects_skipped`` entry of an effect that was no candidate."""
    return SkippedEffect.make(name=s.name, reason=s.reason)


def residual_summary(r: ResidualVerdict) -> ResidualSummary:
    """The ``residual`` table of the loop's verdict on the final residual."""
    noise = {} if r.noise_used is None else {"noise_used": r.noise_used}
    return ResidualSummary.make(
        rms=r.rms,
        whiteness_p=r.whiteness_p,
        dominant_hz=r.dominant_hz,
        rms_over_noise=r.rms_over_noise,
        peak_q=r.peak_q,
        whiteness_test=r.whiteness_test,
        ljung_box_p=r.ljung_box_p,
        **noise,
    )


def loop_tables(loop: LoopResult) -> dict[str, Any]:
    """The loop's own keys of ``results.json`` after ``failed`` and the comparison's:
    ``effects_tried``, ``effects_skipped``, ``diagnosis``, ``unexplained_text`` (``final``
    is the builder's)."""
    return {
        "effects_tried": [effect_trial(v) for v in loop.tried],
        "effects_skipped": [skipped_effect(s) for s in loop.skipped],
        "diagnosis": [diagnosis_round(d) for d in loop.diagnosis],
        "unexplained_text": loop.unexplained_text,
    }
