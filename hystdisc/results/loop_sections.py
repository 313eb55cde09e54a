"""The typed sections of ``results.json`` that the closing loop's re-runs and the staged
fit write: ``reselection``, ``reduction``, ``delay_scan``, ``open_library``,
``current_laws`` (records as in :mod:`hystdisc.results.sections`, which lists them all).

Examples
--------
>>> r = ReductionRecord.from_dict({"family": "lugre", "to": "dahl", "fit": {"bic": -5.0}})
>>> r.to, r.fit.bic, r["family"]
('dahl', -5.0, 'lugre')
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hystdisc.results.record import Record, list_of, record_of, table_of


@dataclass
class FitSummaryRecord(Record):
    """A fit in a table of the loop's re-runs (or of the staged fit).

    Attributes
    ----------
    rms, heldout_rms, bic : float or None
        Its RMS, held-out RMS and BIC.
    admissible : bool or None
        Whether it is physically admissible, where the table says.
    parameters : dict of str to dict or None
        Its parameters (``value``, ``ci95``), where the table has them.
    extra : dict
        Keys this version does not know.
    """

    rms: float | None = None
    heldout_rms: float | None = None
    bic: float | None = None
    admissible: bool | None = None
    parameters: dict[str, dict[str, Any]] | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class ReselectionRecord(Record):
    """``reselection``: every family refitted with the effects the loop accepted
    (:class:`hystdisc.closing.reselect.Reselection`).

    Attributes
    ----------
    effects : list of str
        The effects.
    families : dict of str to FitSummaryRecord
        Each family's refit.
    before, pick : str
        The family selected before, and the pick among the refits.
    switched : bool
        Whether the selection switched to ``pick``.
    final_heldout : dict of str to float
        The final models' held-out RMS.
    note : str
        In words.
    extra : dict
        Keys this version does not know.
    """

    _nested = {"families": table_of(FitSummaryRecord)}

    effects: list[str] = field(default_factory=list)
    families: dict[str, FitSummaryRecord] = field(default_factory=dict)
    before: str = ""
    pick: str = ""
    switched: bool = False
    final_heldout: dict[str, float | None] = field(default_factory=dict)
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class ReductionRecord(Record):
    """``reduction``: the selected family as a smaller family plus effects
    (:class:`hystdisc.closing.reduction.Reduction`).

    Attributes
    ----------
    family, to : str
        The selected family and the smaller one.
    at : dict of str to float
        The values at which it is the smaller one.
    effects : list of str
        The effects the smaller family was fitted with.
    fit : FitSummaryRecord
        That fit.
    switched : bool
        Whether the selection switched to it.
    final_heldout, final_bic : dict of str to float
        The final models' held-out RMS and BIC.
    note : str
        In words.
    extra : dict
        Keys this version does not know.
    """

    _nested = {"fit": record_of(FitSummaryRecord)}

    family: str = ""
    to: str = ""
    at: dict[str, float] = field(default_factory=dict)
    effects: list[str] = field(default_factory=list)
    fit: FitSummaryRecord | None = None
    switched: bool = False
    final_heldout: dict[str, float | None] = field(default_factory=dict)
    final_bic: dict[str, float | None] = field(default_factory=dict)
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class DelayScanRecord(Record):
    """``delay_scan``: the delay between a driven test's channels, scanned by stage 1
    (:class:`hystdisc.discovery.delay.DelayScan`).

    Attributes
    ----------
    tau : float
        The delay of the output behind the motion, s (0: none found).
    dbic : float
        The equation-error BIC's change at ``tau``.
    share : float
        The share of the equation-error residual the delay removes.
    found : bool
        Whether a delay was found.
    reach : float
        The largest delay scanned, s.
    best : float or None
        The scanned optimum, s, called found or not (``dbic`` and ``share`` are its).
    notes : list of str
        The verdict on the selected family, when every family carried the delay.
    extra : dict
        Keys this version does not know.
    """

    tau: float = 0.0
    dbic: float | None = None
    share: float | None = None
    found: bool = False
    reach: float | None = None
    best: float | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class LibraryTermRecord(Record):
    """One stable term of the open library (``open_library.terms``).

    Attributes
    ----------
    name : str
        The candidate's name.
    coefficient : float
        Its coefficient.
    inclusion : float
        The share of bootstrap refits that kept it.
    effect : str or None
        The catalogued effect it belongs to (empty: discovered).
    extra : dict
        Keys this version does not know.
    """

    name: str = ""
    coefficient: float | None = None
    inclusion: float | None = None
    effect: str | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class LibraryHeldOutRecord(Record):
    """``open_library.heldout``: the stable terms judged on held-out conditions
    (:class:`hystdisc.closing.open_library.HeldOutTerms`).

    Attributes
    ----------
    before, after : float
        The pooled held-out RMS without and with the terms, each condition left out and
        the model refitted (linearized at its optimum) with them.
    folds : int
        The held-out conditions.
    lower : int
        The conditions the terms predict better.
    extra : dict
        Keys this version does not know.
    """

    before: float | None = None
    after: float | None = None
    folds: int = 0
    lower: int = 0
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class LibraryRefitRecord(Record):
    """``open_library.refit``: the stable terms refitted into the model by output error
    and judged on held-out conditions (:class:`hystdisc.closing.library_refit.TermsRefit`).

    Attributes
    ----------
    terms : list of str
        The terms.
    coefficients, stderr : dict of str to float
        Each term's refitted coefficient and standard error.
    params : dict of str to float
        The model's free parameters refitted with the terms.
    rms_before, rms_after, bic_before, bic_after : float
        In-sample RMS and BIC without and with the terms.
    heldout_before, heldout_after : float or None
        Pooled held-out RMS (each condition left out, both models refitted on the others).
    fold_before, fold_after : list of float
        Each condition's held-out RMS.
    lower : int
        The conditions the terms predict better.
    excess_share : float
        Share of the residual's excess over the floor they remove.
    admissible, accepted : bool
        The model with them is admissible; the verdict.
    note : str
        Why, in words.
    equation : str
        ``F_extra = ...`` with the refitted coefficients.
    dropped : list of str
        Terms of the library's set left out (its spring, which softened).
    redundant : dict of str to float
        Catalogued effects of the model the terms made redundant (left out of the
        refitted model), each with its chi-square beside the terms.
    model, system_model : dict or None
        The refitted model, as ``model`` and ``system_model`` hold the final one
        (:meth:`hystdisc.results.Results.simulation_model` with ``refitted=True``).
    extra : dict
        Keys this version does not know.
    """

    terms: list[str] = field(default_factory=list)
    coefficients: dict[str, float] = field(default_factory=dict)
    stderr: dict[str, float] = field(default_factory=dict)
    params: dict[str, float] = field(default_factory=dict)
    rms_before: float | None = None
    rms_after: float | None = None
    bic_before: float | None = None
    bic_after: float | None = None
    heldout_before: float | None = None
    heldout_after: float | None = None
    fold_before: list[float] = field(default_factory=list)
    fold_after: list[float] = field(default_factory=list)
    lower: int = 0
    excess_share: float | None = None
    admissible: bool = False
    accepted: bool = False
    note: str = ""
    equation: str = ""
    dropped: list[str] = field(default_factory=list)
    redundant: dict[str, float] = field(default_factory=dict)
    model: dict[str, Any] | None = None
    system_model: dict[str, Any] | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class OpenLibraryRecord(Record):
    """``open_library``: what the open library found in a residual the catalogue left
    (:class:`hystdisc.closing.open_library.ResidualTerms`).

    Attributes
    ----------
    terms : list of LibraryTermRecord
        The stable terms, largest contribution first.
    explained : float
        The residual's share they explain together.
    effects : list of str
        Catalogued effects whose terms are all among them.
    candidates : int
        Candidate terms in the library.
    equation : str
        The discovered effect's equation.
    heldout : LibraryHeldOutRecord or None
        The terms judged on held-out conditions (None: not judged).
    refit : LibraryRefitRecord or None
        The terms refitted into the model and judged held out (None: not refitted).
    extra : dict
        Keys this version does not know.
    """

    _nested = {
        "terms": list_of(LibraryTermRecord),
        "heldout": record_of(LibraryHeldOutRecord),
        "refit": record_of(LibraryRefitRecord),
    }

    terms: list[LibraryTermRecord] = field(default_factory=list)
    explained: float | None = None
    effects: list[str] = field(default_factory=list)
    candidates: int = 0
    equation: str = ""
    heldout: LibraryHeldOutRecord | None = None
    refit: LibraryRefitRecord | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class LawLevelRecord(Record):
    """One current level's fit in ``current_laws.levels``.

    Attributes
    ----------
    current : float
        The level, A.
    runs : list
        Its runs.
    rms : float
        The level's fit's RMS.
    parameters : dict of str to dict
        Its parameters (``value``, ``ci95``).
    extra : dict
        Keys this version does not know.
    """

    current: float | None = None
    runs: list[Any] = field(default_factory=list)
    rms: float | None = None
    parameters: dict[str, dict[str, Any]] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class CurrentLawRecord(Record):
    """One law in ``current_laws.laws``: a parameter's per-level values and the law chosen.

    Attributes
    ----------
    parameter : str
        The family parameter that varies with the current.
    currents, values : list of float
        The levels and its value at each.
    ci95 : list of [float, float]
        Their 95 % intervals.
    law, proposed : str
        The law chosen, and the one the per-level values proposed.
    linear_p : float
        The p-value of the linear law's misfit.
    coefficients : dict of str to float
        The chosen law's coefficients by free-parameter name.
    heldout : dict of str to dict or None
        Each candidate law's held-out error (``z``, ``rms``; null without enough levels).
    extra : dict
        Keys this version does not know.
    """

    parameter: str = ""
    currents: list[float] = field(default_factory=list)
    values: list[float] = field(default_factory=list)
    ci95: list[list[float]] = field(default_factory=list)
    law: str = ""
    proposed: str = ""
    linear_p: float | None = None
    coefficients: dict[str, float] = field(default_factory=dict)
    heldout: dict[str, dict[str, float] | None] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class CurrentLawsRecord(Record):
    """``current_laws``: the staged fit (``discover --staged``)
    (:meth:`hystdisc.selection.staged.StagedFit.to_dict`).

    Attributes
    ----------
    family : str
        The family fitted per level.
    heldout_by : str
        ``"level"``: each held-out fold leaves one current level out.
    levels : list of LawLevelRecord
        Each level's fit.
    laws : dict of str to CurrentLawRecord
        Each law.
    changed : bool
        Whether a law other than the linear one was chosen.
    joint, linear : FitSummaryRecord
        The joint fits with the chosen laws and with linear ones.
    notes : list of str
        In words.
    extra : dict
        Keys this version does not know.
    """

    _nested = {
        "levels": list_of(LawLevelRecord),
        "laws": table_of(CurrentLawRecord),
        "joint": record_of(FitSummaryRecord),
        "linear": record_of(FitSummaryRecord),
    }

    family: str = ""
    heldout_by: str = "level"
    levels: list[LawLevelRecord] = field(default_factory=list)
    laws: dict[str, CurrentLawRecord] = field(default_factory=dict)
    changed: bool = False
    joint: FitSummaryRecord | None = None
    linear: FitSummaryRecord | None = None
    notes: list[str] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)
