"""The typed entries of ``results.json``: parameters, family fits, effects, residual, runs.

Each class is a dataclass :class:`~hystdisc.results.record.Record`: its attributes are the
keys of its ``results.json`` table (the contract of ``DESIGN.md`` section 5, kept in
``doc/develop.rst``), read by attribute (``fam.rms``) or, as the plain dicts of schema 1
were, by key (``fam["rms"]``).

Examples
--------
>>> p = ParameterResult.from_dict({"value": 0.8, "ci95": [0.79, 0.81], "identifiable": True})
>>> p.value, p.ci95, p.to_dict() == {"value": 0.8, "ci95": [0.79, 0.81], "identifiable": True}
(0.8, [0.79, 0.81], True)
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from hystdisc.models import SHEAR_M0, SHEAR_TERM, TermModel
from hystdisc.results.record import Record, list_of, record_of, table_of
from hystdisc.results.sections import RunRecord, SystemModelRecord


def term_model_to_dict(tm: TermModel) -> dict:
    """The ``results.json`` table of a term model.

    Examples
    --------
    >>> term_model_to_dict(TermModel({"z": 1.0}, {"theta_dot": 2.0}))
    {'torque': {'z': 1.0}, 'hysteresis': {'theta_dot': 2.0}, 'n': 1.0, 'J': 1.0}

    A model with the shear-thinning term also carries its exponent ``m``.
    """
    out = {"torque": dict(tm.torque), "hysteresis": dict(tm.hysteresis), "n": tm.n, "J": tm.J}
    if SHEAR_TERM in tm.torque:
        out["m"] = tm.m
    if tm.delay:
        out["delay"] = tm.delay  # the channel delay [s] (absent: 0, as older records)
    if tm.saturation:
        out["saturation"] = dict(tm.saturation)  # saturating current laws (absent: linear)
    if tm.play:
        out["play"] = tm.play  # the backlash half-width (absent: 0, as older records)
    return out


def term_model_from_dict(d: Any) -> TermModel:
    """The term model of a ``results.json`` table (a dict or a :class:`TermModelRecord`)."""
    return TermModel(
        {k: float(v) for k, v in d.get("torque", {}).items()},
        {k: float(v) for k, v in d.get("hysteresis", {}).items()},
        float(d.get("n", 1.0)),
        float(d.get("J", 1.0)),
        float(d.get("m", SHEAR_M0)),
        float(d.get("delay", 0.0) or 0.0),
        {k: float(v) for k, v in (d.get("saturation") or {}).items()},
        float(d.get("play", 0.0) or 0.0),
    )


@dataclass
class TermModelRecord(Record):
    """A fitted model in term form (what ``hystdisc predict`` simulates).

    Attributes
    ----------
    torque : dict of str to float
        Coefficient of each torque term (``theta`` is the rig spring).
    hysteresis : dict of str to float
        Coefficient of each term of ``dz/dt``.
    n : float
        Exponent of the hysteresis shape.
    J : float
        Inertia (1 unless the experiment is forced).
    delay : float
        Delay of the measured output behind the model's, in s (``channel_delay``; 0 and
        absent in records without it).
    extra : dict
        Keys this version does not know (kept on a round trip); ``m``, the exponent of
        the shear-thinning term, when the model has that term; ``saturation`` (schema 5),
        the saturation current ``i0`` of each group of current terms whose law saturates
        (:attr:`~hystdisc.models.TermModel.saturation`), when the model has one;
        ``play``, the half-width of a backlash between the measured motion and the damper
        (:attr:`~hystdisc.models.TermModel.play`), when the model has one.
    """

    torque: dict[str, float] = field(default_factory=dict)
    hysteresis: dict[str, float] = field(default_factory=dict)
    n: float = 1.0
    J: float = 1.0
    delay: float = 0.0
    extra: dict[str, Any] = field(default_factory=dict, repr=False)

    @classmethod
    def of(cls, tm: TermModel) -> TermModelRecord:
        """The record of a :class:`~hystdisc.models.TermModel`, rounded as ``results.json``
        holds it."""
        return cls.make(**term_model_to_dict(tm))

    def to_term_model(self) -> TermModel:
        """The :class:`~hystdisc.models.TermModel` (ValueError/TypeError when malformed)."""
        tm = term_model_from_dict(self)
        values = [*tm.torque.values(), *tm.hysteresis.values(), tm.n, tm.J, tm.m, tm.delay, tm.play]
        values += list(tm.saturation.values())
        if not all(math.isfinite(v) for v in values):
            raise ValueError("a coefficient is not finite")
        return tm


@dataclass
class ParameterResult(Record):
    """One fitted parameter.

    Attributes
    ----------
    value : float
        The estimate.
    ci95 : list of float or None
        ``[low, high]``, the 95 % interval from the Jacobian at the optimum (an end is None
        when it is not finite).
    identifiable : bool
        False when the interval is wider than the value or the parameter lies along a
        near-singular direction (absent for an accepted effect's parameters).
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    value: float | None = None
    ci95: list[float | None] | None = None
    identifiable: bool = True
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class FamilyResult(Record):
    """The output-error fit of one family.

    Attributes
    ----------
    parameters : dict of str to ParameterResult
        Fitted parameters with intervals, in the family's order.
    normalization : str
        How the hysteretic state is scaled (for example ``"z_sat = 1"``).
    rms : float
        Output (simulation) error against the measured signal over all runs, data units.
    bic : float
        Bayesian information criterion of the fit.
    heldout_rms : float or None
        Held-out RMS: each test condition (or run) predicted by the fit without it, pooled
        (None when not computed).
    n_params : int
        Parameters counted by the BIC (initial states included).
    admissible : bool or None
        The fitted model dissipates energy and its spring stiffens over twice the training
        envelope (schema 3; None in older files).
    violations : list of str
        Where it does not (empty when admissible).
    missing_terms : list of str
        Discovered terms the family lacks (prefix ``dz/dt:`` for the hysteresis side).
    extra_terms : list of str
        The family's terms that were not discovered.
    notes : list of str
        Remarks of the fit (bounds reached, parameters fixed).
    term_model : TermModelRecord
        The fit in term form (None for a system family).
    system : SystemModelRecord or None
        A system family's fitted model (schema 4).
    converged : bool
        The optimizer's success flag.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {
        "parameters": table_of(ParameterResult),
        "term_model": record_of(TermModelRecord),
        "system": record_of(SystemModelRecord),
    }

    parameters: dict[str, ParameterResult] = field(default_factory=dict)
    normalization: str = ""
    rms: float | None = None
    bic: float | None = None
    heldout_rms: float | None = None
    n_params: int | None = None
    admissible: bool | None = None
    violations: list[str] = field(default_factory=list)
    missing_terms: list[str] = field(default_factory=list)
    extra_terms: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    term_model: TermModelRecord | None = None
    system: SystemModelRecord | None = None
    converged: bool = True
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class Stage1Record(Record):
    """Stage 1 with one hysteresis shape.

    Attributes
    ----------
    terms : list of str
        Torque terms selected by the sparse regression.
    bic : float
        Equation-error BIC of the selected model.
    inclusion : dict of str to float or None
        Ensemble inclusion probability of each term (None without an ensemble).
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    terms: list[str] = field(default_factory=list)
    bic: float | None = None
    inclusion: dict[str, float] | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class DiscoveredResult(Record):
    """The structure stage 1 discovered and its output-error fit.

    Attributes
    ----------
    name : str
        Plain-words name (a family's, when the terms are one's).
    shape : str
        Hysteresis shape with the lowest stage-1 BIC.
    equations : str
        The equations, pysindy style.
    parameters : dict of str to float
        Output-error fit of the structure.
    rms, bic : float
        Its output error and BIC.
    term_model : TermModelRecord
        The fit in term form.
    stage1 : dict of str to Stage1Record
        Every hysteresis shape tried.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {
        "term_model": record_of(TermModelRecord),
        "stage1": table_of(Stage1Record),
    }

    name: str = ""
    shape: str = ""
    equations: str = ""
    parameters: dict[str, float] = field(default_factory=dict)
    rms: float | None = None
    bic: float | None = None
    term_model: TermModelRecord | None = None
    stage1: dict[str, Stage1Record] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class EffectStep(Record):
    """An effect the closing loop accepted.

    Attributes
    ----------
    name : str
        Catalogue name of the effect.
    terms : list of str
        Torque terms it adds.
    parameters : dict of str to ParameterResult
        Its parameters in the final fit (value and 95 % interval).
    rms_before, rms_after : float
        Output-error RMS without and with it.
    bic_before, bic_after : float
        BIC without and with it.
    heldout_rms_before, heldout_rms_after : float or None
        Held-out RMS (leave one test condition out) without and with it (schema 3).
    evidence : float
        Share of the residual its signature explained (score test).
    evidence_eq : float or None
        The same share in equation error.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {"parameters": table_of(ParameterResult)}

    name: str = ""
    terms: list[str] = field(default_factory=list)
    parameters: dict[str, ParameterResult] = field(default_factory=dict)
    rms_before: float | None = None
    rms_after: float | None = None
    bic_before: float | None = None
    bic_after: float | None = None
    heldout_rms_before: float | None = None
    heldout_rms_after: float | None = None
    evidence: float | None = None
    evidence_eq: float | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class EffectTrial(Record):
    """An effect the closing loop refitted (accepted or not).

    Attributes
    ----------
    name : str
        Catalogue name.
    round : int
        Round of the loop (1 first).
    evidence, evidence_eq : float or None
        Output- and equation-error evidence at the time.
    start_rms : float or None
        Output-error RMS of its stage-1 start (None when not screened).
    rms_before, rms_after : float or None
        RMS of the current model and of the refit (None when the refit failed).
    bic_before, bic_after : float or None
        The same for BIC.
    heldout_rms_before, heldout_rms_after : float or None
        The same for the held-out RMS (schema 3); ``heldout_rms_after`` is None also when
        the refit failed another test (BIC, significance, admissibility):
        its held-out error is computed only when it could decide the verdict.
    admissible : bool or None
        The refit is physically admissible (an effect the data want with a non-physical
        sign is refitted within its bounds: this judges that refit).
    points_at : str or None
        For an effect the data want with a non-physical sign: the physics that sign
        points at.
    wald_chi2 : float or None
        Squared z-score of the effect's parameters in the refit.
    converged : bool
        The refit's success flag.
    accepted : bool
        The effect was kept.
    excess_share : float or None
        Share of the residual's excess over the noise that the refit removed.
    starts : list of dict or None
        A structural refit: how the fit from each of its starts ended (``<p>_start``,
        ``<p>``, ``rms``, ``bic``, for the parameter ``<p>`` that tells the starts apart).
    starts_spread : float or None
        A structural refit: the relative spread of ``<p>`` among its starts within the
        BIC margin of the best.
    note : str or None
        Why it was not accepted (absent when accepted).
    removed : bool
        Accepted, then dropped again by a later effect (absent unless so).
    heldout_folds, heldout_folds_lower : int or None
        For a refit that lowered BIC, significant and admissible, but removed less than
        a tenth of the excess: its held-out folds and those whose error it lowered (it is
        accepted only when it lowered every one of at least four); absent otherwise.
    restarted : bool
        The refit had a start from the family fitted again on the shifted angle (the
        offset's, from its stage-1 value or from a refit that fitted better but did not
        predict: :mod:`hystdisc.closing.motion_restart`), and is the better for it (absent unless
        so).
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    name: str = ""
    round: int | None = None
    evidence: float | None = None
    evidence_eq: float | None = None
    start_rms: float | None = None
    rms_before: float | None = None
    rms_after: float | None = None
    bic_before: float | None = None
    bic_after: float | None = None
    wald_chi2: float | None = None
    heldout_rms_before: float | None = None
    heldout_rms_after: float | None = None
    admissible: bool | None = None
    points_at: str | None = None
    converged: bool = True
    accepted: bool = False
    excess_share: float | None = None
    starts: list[dict[str, float]] | None = None
    starts_spread: float | None = None
    note: str | None = None
    removed: bool = False
    restarted: bool = False
    heldout_folds: int | None = None
    heldout_folds_lower: int | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class SkippedEffect(Record):
    """A catalogued effect the closing loop did not consider.

    Attributes
    ----------
    name : str
        Catalogue name.
    reason : str
        Why (the family has its terms, one current level, no rig spring, ...).
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    name: str = ""
    reason: str = ""
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class EffectCandidate(Record):
    """The diagnosis of one candidate effect (the score test) in one round.

    Attributes
    ----------
    name : str
        Catalogue name.
    terms : list of str
        Torque terms the effect adds.
    evidence : float
        Share of the output-error RSS its projected signature explains.
    evidence_per_run : list of float
        Each run's part of it.
    evidence_eq, predicted_dbic_eq : float or None
        Equation-error share and the BIC change it means.
    start_rms, start_dbic : float or None
        Output-error RMS and BIC change of its stage-1 start (when screened).
    lm : float
        Score statistic.
    predicted_rms, predicted_dbic, estimate : float, float, dict of str to float
        Predicted RMS and BIC change after adding it, and its parameters' one-step estimate.
    starts_screened, signature : int or None, str or None
        A structural effect: the starts its diagnosis screened, and its signature in the
        residual in words, when there is one.
    not_refitted : str or None
        Why a candidate whose evidence called for a refit was not refitted.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    name: str = ""
    terms: list[str] = field(default_factory=list)
    evidence: float | None = None
    evidence_per_run: list[float] = field(default_factory=list)
    evidence_eq: float | None = None
    predicted_dbic_eq: float | None = None
    start_rms: float | None = None
    start_dbic: float | None = None
    lm: float | None = None
    predicted_rms: float | None = None
    predicted_dbic: float | None = None
    estimate: dict[str, float] = field(default_factory=dict)
    starts_screened: int | None = None
    signature: str | None = None
    not_refitted: str | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class DiagnosisRound(Record):
    """One round of the closing loop's diagnosis.

    Attributes
    ----------
    round : int
        Round number (1 first).
    candidates : list of EffectCandidate
        Every candidate, ranked by evidence.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {"candidates": list_of(EffectCandidate)}

    round: int | None = None
    candidates: list[EffectCandidate] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class ResidualSummary(Record):
    """The final output-error residual.

    Attributes
    ----------
    rms : float
        Its RMS over the fitted samples, data units.
    whiteness_p : float
        p-value of the whiteness test named by ``whiteness_test`` (white when at least
        0.01).
    dominant_hz : float or None
        Dominant frequency of a structured (not white) residual.
    rms_over_noise : float or None
        RMS over the estimated noise.
    peak_q : float or None
        Quality factor of the dominant peak (closing loop only).
    noise_used : float or None
        The noise level the verdict used (closing loop only).
    whiteness_test : str or None
        ``ljung-box`` (against white noise, pooled over runs) or ``noise spectrum``
        (against the spectrum of the noise's own period-to-period differences).
    ljung_box_p : float or None
        The Ljung-Box p-value, whichever test decided.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    rms: float | None = None
    whiteness_p: float | None = None
    dominant_hz: float | None = None
    rms_over_noise: float | None = None
    peak_q: float | None = None
    noise_used: float | None = None
    whiteness_test: str | None = None
    ljung_box_p: float | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class FinalResult(Record):
    """The selected family with every accepted effect, refitted together.

    Attributes
    ----------
    family : str
        The selected (or declared) family.
    effects : list of str
        Accepted effects, in the order they were added.
    parameters : dict of str to ParameterResult
        Fitted parameters of the final model.
    rms, bic : float
        Its output error and BIC.
    heldout_rms : float or None
        Its held-out RMS (leave one test condition out, or one run).
    n_params : int
        Parameters counted by the BIC.
    converged : bool
        The optimizer's success flag.
    notes : list of str
        Remarks of the fit.
    admissible : bool or None
        It dissipates energy and its spring stiffens over twice the training envelope
        (schema 3).
    violations : list of str
        Where it does not.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {"parameters": table_of(ParameterResult)}

    family: str = ""
    effects: list[str] = field(default_factory=list)
    parameters: dict[str, ParameterResult] = field(default_factory=dict)
    rms: float | None = None
    bic: float | None = None
    heldout_rms: float | None = None
    n_params: int | None = None
    converged: bool = True
    notes: list[str] = field(default_factory=list)
    admissible: bool | None = None
    violations: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


#: Every record class, for the tests of their documentation and round trip.
RECORDS: tuple[type[Record], ...] = (
    TermModelRecord,
    ParameterResult,
    FamilyResult,
    Stage1Record,
    DiscoveredResult,
    EffectStep,
    EffectTrial,
    SkippedEffect,
    EffectCandidate,
    DiagnosisRound,
    ResidualSummary,
    FinalResult,
    RunRecord,
)
