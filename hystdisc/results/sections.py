"""The typed sections of ``results.json``: what the data were and how they were measured
(this module), and what the loop's re-runs found (:mod:`hystdisc.results.loop_sections`).

Each is a :class:`~hystdisc.results.record.Record`: its attributes are the JSON keys, it
reads and writes the table it was read from (an older file's keys and order kept, keys
this version does not know in ``extra``), and ``section["key"]`` still reads like the
plain tables of schema 1. They are made in code by
:func:`hystdisc.pipeline.record.build_results` from the objects that computed them
(:meth:`~hystdisc.results.record.Record.make`); this module only describes their shape.

Examples
--------
>>> n = NoiseRecord.from_dict({"std": 0.001, "method": "cycles",
...     "runs": [{"name": "a", "method": "cycles", "floor": 0.001}]})
>>> n.method, n.runs[0].floor, n["std"]
('cycles', 0.001, 0.001)
>>> ConditionsRecord.make(labels={"a": "0"}, heldout_by="run", folds=1).to_dict()
{'labels': {'a': '0'}, 'heldout_by': 'run', 'folds': 1}
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from hystdisc.results.loop_sections import (
    CurrentLawRecord,
    CurrentLawsRecord,
    DelayScanRecord,
    FitSummaryRecord,
    LawLevelRecord,
    LibraryHeldOutRecord,
    LibraryRefitRecord,
    LibraryTermRecord,
    OpenLibraryRecord,
    ReductionRecord,
    ReselectionRecord,
)
from hystdisc.results.record import Record, list_of


@dataclass
class ConditionsRecord(Record):
    """``conditions``: how the held-out folds were cut.

    Attributes
    ----------
    labels : dict of str to str
        Run name -> its test condition.
    heldout_by : str
        ``"condition"`` or ``"run"``: what each held-out fold leaves out.
    folds : int
        The number of held-out folds.
    extra : dict
        Keys this version does not know.
    """

    labels: dict[str, str] = field(default_factory=dict)
    heldout_by: str = "run"
    folds: int = 0
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class RunEnvelopeRecord(Record):
    """One run's reach in ``envelope.runs`` (:class:`hystdisc.data.envelope.RunEnvelope`).

    Attributes
    ----------
    name : str
        The run.
    current : float
        Its current, A.
    theta_max, theta_dot_max : float
        Its largest displacement and velocity, data units.
    duration : float
        Its length, s.
    extra : dict
        Keys this version does not know.
    """

    name: str = ""
    current: float | None = None
    theta_max: float | None = None
    theta_dot_max: float | None = None
    duration: float | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class EnvelopeRecord(Record):
    """``envelope``: what the training runs covered; ``predict`` warns beyond it
    (:class:`hystdisc.data.envelope.Envelope`).

    Attributes
    ----------
    theta_max, theta_dot_max : float
        The largest displacement and velocity reached, data units.
    current_min, current_max : float
        The current range, A.
    runs : list of RunEnvelopeRecord
        Each run's reach.
    extra : dict
        Keys this version does not know.
    """

    _nested = {"runs": list_of(RunEnvelopeRecord)}

    theta_max: float | None = None
    theta_dot_max: float | None = None
    current_min: float | None = None
    current_max: float | None = None
    runs: list[RunEnvelopeRecord] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class SystemModelRecord(Record):
    """``system_model`` (and a family's ``system``): a state-space model, or a term model
    around a structural effect.

    Attributes
    ----------
    family : str or None
        The state-space family (None around a structural effect).
    structural : str or None
        The structural effect's name (``series_compliance``), around the term part
        ``model`` of the results.
    experiment : str
        The experiment it simulates.
    effects : list of str
        The effects inside the state-space model.
    values : dict of str to float
        Its parameter values (the structural effect's, around a term model).
    extra : dict
        Keys this version does not know.
    """

    family: str | None = None
    structural: str | None = None
    experiment: str = ""
    effects: list[str] = field(default_factory=list)
    values: dict[str, float] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class CurrentDependenceRecord(Record):
    """``current_dependence``: all runs share one current.

    Attributes
    ----------
    identifiable : bool
        False: the current dependence cannot be told.
    currents : list of float
        The one level.
    fixed : list of str
        The selected family's current-dependent parameters, held at 0.
    note : str
        The reason in words.
    extra : dict
        Keys this version does not know.
    """

    identifiable: bool = False
    currents: list[float] = field(default_factory=list)
    fixed: list[str] = field(default_factory=list)
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class NoiseRunRecord(Record):
    """One run's noise estimates in ``noise.runs`` (:class:`hystdisc.data.NoiseEstimate`).

    Attributes
    ----------
    name : str
        The run.
    differences : float or None
        High-order differences' estimate.
    period, period_samples : float or None
        The excitation's period (s, samples) when the run repeats.
    cycles : float or None
        The cycle-to-cycle repeatability of the output (cycles aligned on the motion).
    floor : float or None
        The run's floor as used.
    used, method : str or None
        Which estimate the run's floor is.
    extra : dict
        Keys this version does not know.
    """

    name: str = ""
    differences: float | None = None
    period: float | None = None
    period_samples: float | None = None
    cycles: float | None = None
    floor: float | None = None
    used: str | None = None
    method: str | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class NoiseRecord(Record):
    """``noise``: how ``noise_std`` was estimated (:meth:`hystdisc.data.NoiseEstimate.to_dict`).

    Attributes
    ----------
    std : float
        The noise level.
    method : str
        ``cycles`` (the output's cycle-to-cycle repeatability), ``period``
        (period-to-period differences), ``differences`` (high-order differences, white
        noise assumed: a fallback) or ``quantization`` (``q / sqrt(12)``).
    signal : str
        The measured signal it belongs to.
    differences : float or None
        The high-order differences' estimate, for comparison.
    period : float or None
        The excitation's period, s.
    pooled : float or None
        The pooled cycle-to-cycle estimate over the periodic runs.
    quantization_floor : float or None
        The floor of a quantized output.
    runs : list of NoiseRunRecord
        Each run's estimates.
    extra : dict
        Keys this version does not know.
    """

    _nested = {"runs": list_of(NoiseRunRecord)}

    std: float | None = None
    method: str = ""
    signal: str = ""
    differences: float | None = None
    period: float | None = None
    pooled: float | None = None
    quantization_floor: float | None = None
    runs: list[NoiseRunRecord] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class MotionNoiseRecord(Record):
    """``motion_noise``: the noise on a driven test's measured motion, which enters the
    fit and its intervals (:meth:`hystdisc.data.motion.MotionNoise.to_dict`).

    Attributes
    ----------
    std : float
        Pooled over the runs (the root of their sample-weighted mean variance).
    method : str
        Most runs' method: ``cycle-to-cycle``, ``differences`` or ``quantization``.
    runs : dict of str to float
        Run name -> its level.
    methods : dict of str to str
        Run name -> its method.
    estimates : dict of str to dict
        Run name -> how the fit's motion was estimated (``estimate``: ``harmonic``,
        ``smoother`` or ``filter``; a harmonic fit's ``harmonics``, ``frequency``,
        ``residual``; a ``note`` when the series was not used).
    extra : dict
        Keys this version does not know.
    """

    std: float | None = None
    method: str = ""
    runs: dict[str, float] = field(default_factory=dict)
    methods: dict[str, str] = field(default_factory=dict)
    estimates: dict[str, dict[str, Any]] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class PrefilterRecord(Record):
    """``prefilter``: a causal moving average read in the records, which the fits saw the
    model through (:class:`hystdisc.data.FilterFound`; absent when the data declare their
    filter or none was read).

    Attributes
    ----------
    windows : dict of str to int
        Each run's window, samples.
    channels : list of str
        The channels it acts on.
    contrast : dict of str to float
        Each run's notches below its sidelobes, decades (runs where it was read).
    inferred : list of str
        Runs whose window was inferred from the others' (too few notches of their own).
    missing : list of str
        Runs with no window (fitted as unfiltered).
    note : str
        What was found, in one sentence.
    extra : dict
        Keys this version does not know.
    """

    windows: dict[str, int] = field(default_factory=dict)
    channels: list[str] = field(default_factory=list)
    contrast: dict[str, float] = field(default_factory=dict)
    inferred: list[str] = field(default_factory=list)
    missing: list[str] = field(default_factory=list)
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class EncoderRecord(Record):
    """``encoder``: the lattice of a quantized recorded angle (:class:`hystdisc.data.Quantization`).

    Attributes
    ----------
    step : float
        The lattice step.
    counts_per_revolution : int or None
        ``2 pi / step`` when whole.
    floor : float
        ``step / sqrt(12)``.
    offset : float
        The lattice's offset.
    levels : int
        The distinct levels seen.
    on_lattice : float
        The share of samples on the lattice.
    extra : dict
        Keys this version does not know.
    """

    step: float | None = None
    counts_per_revolution: int | None = None
    floor: float | None = None
    offset: float | None = None
    levels: int | None = None
    on_lattice: float | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class OutlierRecord(Record):
    """One glitch in ``outliers.items`` (or ``explained``).

    Attributes
    ----------
    run, signal : str
        The run and the signal it is in.
    sample : int
        Its sample.
    t : float
        Its time, s.
    size : float
        Its size against the local prediction.
    residual : float or None
        The model's residual there.
    fitted : bool
        Whether the screen ran on the fitted model.
    extra : dict
        Keys this version does not know.
    """

    run: str = ""
    signal: str = ""
    sample: int = 0
    t: float | None = None
    size: float | None = None
    residual: float | None = None
    fitted: bool = False
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class OutliersRecord(Record):
    """``outliers``: the isolated glitches of the measured signals
    (:class:`hystdisc.measurement.outliers.Outliers`).

    Attributes
    ----------
    count : int
        Glitches found.
    runs : list of str
        The runs that hold glitches.
    threshold_sigma : float
        The screen, in noise standard deviations.
    left_out : bool
        Whether they were left out of every fit (else reported only).
    items : list of OutlierRecord
        Each glitch.
    explained : list of OutlierRecord
        Candidates the model reproduces, kept in the fit.
    extra : dict
        Keys this version does not know.
    """

    _nested = {"items": list_of(OutlierRecord), "explained": list_of(OutlierRecord)}

    count: int = 0
    runs: list[str] = field(default_factory=list)
    threshold_sigma: float | None = None
    left_out: bool = False
    items: list[OutlierRecord] = field(default_factory=list)
    explained: list[OutlierRecord] = field(default_factory=list)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


@dataclass
class RunRecord(Record):
    """One run of the dataset.

    Attributes
    ----------
    name : str
        Run name.
    current : float
        Coil current in A.
    samples : int
        Samples in the run as read.
    fitted : int or None
        Samples that enter the fit's residual and every RMS the results state: a driven
        run's start until its motion has swept its range once (the unknown initial
        hysteretic state), a smoother's ends and glitches are left out. Where runs differ
        in noise (a filter of a window per run), the noise of these samples is the RMS's
        floor, not that of every sample.
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    name: str = ""
    current: float | None = None
    samples: int | None = None
    fitted: int | None = None
    extra: dict[str, Any] = field(default_factory=dict, repr=False)


#: The section records by their ``results.json`` key.
SECTIONS: dict[str, type[Record]] = {
    "conditions": ConditionsRecord,
    "envelope": EnvelopeRecord,
    "system_model": SystemModelRecord,
    "current_dependence": CurrentDependenceRecord,
    "current_laws": CurrentLawsRecord,
    "noise": NoiseRecord,
    "motion_noise": MotionNoiseRecord,
    "encoder": EncoderRecord,
    "prefilter": PrefilterRecord,
    "outliers": OutliersRecord,
    "reselection": ReselectionRecord,
    "reduction": ReductionRecord,
    "delay_scan": DelayScanRecord,
    "open_library": OpenLibraryRecord,
}

#: Every section record, the nested ones included.
SECTION_RECORDS: tuple[type[Record], ...] = (
    *SECTIONS.values(),
    RunEnvelopeRecord,
    NoiseRunRecord,
    OutlierRecord,
    FitSummaryRecord,
    LibraryTermRecord,
    LibraryHeldOutRecord,
    LibraryRefitRecord,
    LawLevelRecord,
    CurrentLawRecord,
)


__all__ = [
    "SECTIONS",
    "SECTION_RECORDS",
    "ConditionsRecord",
    "CurrentDependenceRecord",
    "CurrentLawRecord",
    "CurrentLawsRecord",
    "DelayScanRecord",
    "EncoderRecord",
    "EnvelopeRecord",
    "FitSummaryRecord",
    "LawLevelRecord",
    "LibraryHeldOutRecord",
    "LibraryRefitRecord",
    "LibraryTermRecord",
    "MotionNoiseRecord",
    "NoiseRecord",
    "NoiseRunRecord",
    "OpenLibraryRecord",
    "OutlierRecord",
    "OutliersRecord",
    "PrefilterRecord",
    "ReductionRecord",
    "ReselectionRecord",
    "RunEnvelopeRecord",
    "RunRecord",
    "SystemModelRecord",
]
