"""The result of a discovery: the ``results.json`` contract, a fit report, notebook display.

Follows lmfit's result objects: :meth:`Results.summary` returns the contract as a dict,
:meth:`Results.to_json`/:meth:`Results.from_json` and :meth:`Results.save`/
:meth:`Results.load` round-trip JSON, :meth:`Results.report` is a readable fit report with
intervals, and ``_repr_html_`` renders tables in a notebook.

The file carries ``schema_version`` (:data:`~hystdisc.results.schema.SCHEMA_VERSION`). Schema 1 is the file of
hystdisc 0.1 (the same keys, no ``schema_version``); schema 2 added ``schema_version``;
schema 3 added the held-out judging and admissibility (``conditions``, ``envelope``,
``selection_note``, each family's and the final model's ``admissible`` and
``violations``, each effect's ``heldout_rms_before``/``heldout_rms_after``); schema 4
added the state-space families (each family's ``system``, the final ``system_model``);
schema 5 added the current laws the final model carries (a term model's ``saturation``,
a law's ``<law>_i0`` or ``<law>_i2`` among the parameters and the system's values).
Older files are read as they are (the new keys absent) and written back as schema 5. A file of a newer schema is refused. To change the schema: add the attribute
to its record (with a default, documented), bump :data:`~hystdisc.results.schema.SCHEMA_VERSION`, and migrate older
tables in :func:`migrate`.

Examples
--------
>>> r = Results.from_dict({"version": "0", "input": "x.csv", "experiment": "release",
...     "noise_std": 0.001, "terms": {"torque": ["z"], "hysteresis": []}, "family": "dahl",
...     "families": {}, "model": {"torque": {"z": 1.0}}, "effects": [], "unexplained": False,
...     "residual": {}})
>>> r.family, r.schema_version, r.model.torque
('dahl', 5, {'z': 1.0})
>>> Results.from_json(r.to_json()).summary() == r.summary()
True
>>> list(r.summary())[:3]
['schema_version', 'version', 'input']
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import hystdisc.results.text as text
from hystdisc.errors import HystdiscError
from hystdisc.models import TermModel
from hystdisc.registry import experiment_names
from hystdisc.results.record import Record, SchemaError, list_of, record_of, round_json, table_of
from hystdisc.results.records import (
    DiagnosisRound,
    DiscoveredResult,
    EffectCandidate,
    EffectStep,
    EffectTrial,
    FamilyResult,
    FinalResult,
    ResidualSummary,
    RunRecord,
    SkippedEffect,
    TermModelRecord,
)
from hystdisc.results.schema import SCHEMA_VERSION, migrate
from hystdisc.results.sections import (
    SECTIONS,
    ConditionsRecord,
    CurrentDependenceRecord,
    CurrentLawsRecord,
    DelayScanRecord,
    EncoderRecord,
    EnvelopeRecord,
    MotionNoiseRecord,
    NoiseRecord,
    OpenLibraryRecord,
    OutliersRecord,
    PrefilterRecord,
    ReductionRecord,
    ReselectionRecord,
    SystemModelRecord,
)

_FIX_RERUN = "fix: rerun hystdisc discover --json"


def _no_model(family: str | None, exc: Exception) -> HystdiscError:
    """The one-line error of a results file without a usable model for ``family``."""
    return HystdiscError(
        f"results: no usable model for {family or 'the selected family'} ({exc}); fix: "
        "rerun hystdisc discover"
    )


@dataclass
class Results(Record):
    """The record of a discovery (``results.json``; ``Discovery.results_``).

    Attributes
    ----------
    schema_version : int
        The ``results.json`` schema (:data:`~hystdisc.results.schema.SCHEMA_VERSION`; older files are migrated).
    version : str
        The hystdisc version that wrote it.
    input : str
        The data source (file names).
    experiment : str
        ``"release"``, ``"driven"`` or ``"forced"``.
    input_hold : str or None
        How the forced input is held between samples (forced experiments only).
    noise_std : float
        Estimated measurement noise of the measured signal, data units.
    terms : dict of str to list of str
        Discovered ``torque`` and ``hysteresis`` terms.
    discovered : DiscoveredResult
        The discovered structure, its fit and stage 1 per hysteresis shape.
    family : str
        The selected (or declared) family.
    declared : bool
        True when the family was declared (``--model``) rather than selected.
    equal_fits : list of str
        Families within the BIC margin of the selected one.
    families : dict of str to FamilyResult
        The output-error fit of every family.
    model : TermModelRecord
        The final model in term form (selected family plus accepted effects; None when
        the family is a state-space system).
    effects : list of EffectStep
        Effects the closing loop accepted.
    unexplained : bool
        True when structure remains in the residual that no catalogued effect removes.
    residual : ResidualSummary
        The final residual (RMS, whiteness, dominant frequency).
    runs : list of RunRecord
        The runs of the dataset.
    seed : int or None
        The seed of the stage-1 ensemble.
    effects_tried : list of EffectTrial or None
        Every effect refitted (None when the closing loop did not run).
    effects_skipped : list of SkippedEffect or None
        Catalogued effects not considered, with the reason (None: no loop).
    diagnosis : list of DiagnosisRound or None
        Each round's ranked candidates (None: no loop).
    unexplained_text : str or None
        The remaining structure in plain words.
    final : FinalResult or None
        The selected family with its accepted effects (None: no loop).
    conditions : ConditionsRecord or None
        The test conditions and held-out folds (schema 3).
    envelope : EnvelopeRecord or None
        What the training runs covered (schema 3). ``predict`` warns beyond it.
    selection_note : str or None
        Why the selected family is not the one BIC alone would have chosen (schema 3).
    system_model : SystemModelRecord or None
        The final model of a system family, or a term model's structural effect (schema 4).
    current_dependence : CurrentDependenceRecord or None
        Present when all runs share one current; absent with two levels or more.
    noise : NoiseRecord or None
        How ``noise_std`` was estimated.
    motion_noise : MotionNoiseRecord or None
        Driven experiments: the noise on the measured motion, in the fit and intervals.
    encoder : EncoderRecord or None
        The lattice of the recorded angle, when it is quantized.
    prefilter : PrefilterRecord or None
        A moving average read in the records, fitted through (absent: none read).
    current_laws : CurrentLawsRecord or None
        The staged fit (``discover --staged``); None without it.
    outliers : OutliersRecord or None
        The isolated glitches left out of every fit; None in files written before it.
    reselection : ReselectionRecord or None
        Every family refitted with the effects the loop accepted, when it did.
    reduction : ReductionRecord or None
        The selected family reduced to a smaller family plus effects, when its intervals
        held those values.
    delay_scan : DelayScanRecord or None
        Driven data: the delay between the channels scanned by stage 1.
    open_library : OpenLibraryRecord or None
        The open library's terms in a residual the catalogue left; None when not run.
    failed : dict of str to str
        The tasks of the discovery that failed and were dropped, each with its one-line
        reason (a family, ``<family> start '<label>'``, ``<family> held-out folds``,
        ``effect <name>``, ``staged fit``...): the run went on without them. Empty when
        nothing failed (absent in files written before it).
    extra : dict
        Keys this version does not know (kept on a round trip).
    """

    _nested = {
        "discovered": record_of(DiscoveredResult),
        "families": table_of(FamilyResult),
        "model": record_of(TermModelRecord),
        "effects": list_of(EffectStep),
        "residual": record_of(ResidualSummary),
        "runs": list_of(RunRecord),
        "effects_tried": list_of(EffectTrial),
        "effects_skipped": list_of(SkippedEffect),
        "diagnosis": list_of(DiagnosisRound),
        "final": record_of(FinalResult),
        **{key: record_of(cls) for key, cls in SECTIONS.items()},
    }

    schema_version: int = SCHEMA_VERSION
    version: str = ""
    input: str = ""
    experiment: str | None = None
    input_hold: str | None = None
    noise_std: float | None = None
    terms: dict[str, list[str]] = field(default_factory=dict)
    discovered: DiscoveredResult | None = None
    family: str | None = None
    declared: bool = False
    equal_fits: list[str] = field(default_factory=list)
    families: dict[str, FamilyResult] = field(default_factory=dict)
    model: TermModelRecord | None = None
    effects: list[EffectStep] = field(default_factory=list)
    unexplained: bool = False
    residual: ResidualSummary | None = None
    runs: list[RunRecord] = field(default_factory=list)
    seed: int | None = None
    effects_tried: list[EffectTrial] | None = None
    effects_skipped: list[SkippedEffect] | None = None
    diagnosis: list[DiagnosisRound] | None = None
    unexplained_text: str | None = None
    final: FinalResult | None = None
    conditions: ConditionsRecord | None = None
    envelope: EnvelopeRecord | None = None
    selection_note: str | None = None
    system_model: SystemModelRecord | None = None
    current_dependence: CurrentDependenceRecord | None = None
    current_laws: CurrentLawsRecord | None = None
    noise: NoiseRecord | None = None
    motion_noise: MotionNoiseRecord | None = None
    encoder: EncoderRecord | None = None
    prefilter: PrefilterRecord | None = None
    outliers: OutliersRecord | None = None
    reselection: ReselectionRecord | None = None
    reduction: ReductionRecord | None = None
    delay_scan: DelayScanRecord | None = None
    open_library: OpenLibraryRecord | None = None
    failed: dict[str, str] = field(default_factory=dict)
    extra: dict[str, Any] = field(default_factory=dict, repr=False)

    # ----------------------------------------------------------------- JSON
    @classmethod
    def from_dict(cls, data: Any, where: str | None = None) -> Results:
        """Results from a ``results.json`` table of any known schema (floats rounded).

        Parameters
        ----------
        data : dict
            The parsed ``results.json`` table.
        where : str, optional
            Its name in error messages (default ``"results.json"``).

        Returns
        -------
        Results
            The typed record, migrated to :data:`~hystdisc.results.schema.SCHEMA_VERSION`.

        Raises
        ------
        SchemaError
            When the table does not fit the schema.
        RecursionError
            When it is nested too deeply to round.
        """
        if not isinstance(data, dict):
            raise SchemaError("results.json", f"not a table ({type(data).__name__})")
        return super().from_dict(migrate(round_json(data)), where or "results.json")

    def summary(self) -> dict:
        """The ``results.json`` contract as a plain dict.

        Returns
        -------
        dict
            The same as :meth:`to_dict`.
        """
        return self.to_dict()

    def to_json(self) -> str:
        """The ``results.json`` text (``indent=1``, a final newline).

        Returns
        -------
        str
            The JSON text.
        """
        return json.dumps(self.to_dict(), indent=1, sort_keys=False) + "\n"

    @classmethod
    def from_json(cls, text: str) -> Results:
        """Results from ``results.json`` text (see :meth:`load` for the checks).

        Parameters
        ----------
        text : str
            The JSON text.

        Returns
        -------
        Results
            As :meth:`from_dict` gives it.
        """
        return cls.from_dict(json.loads(text))

    def save(self, path: str | Path, force: bool = False) -> Path:
        """Write ``results.json`` atomically (refuses to overwrite without ``force``).

        Parameters
        ----------
        path : str or pathlib.Path
            The file to write.
        force : bool, default False
            Replace an existing file.

        Returns
        -------
        pathlib.Path
            The path written.
        """
        from hystdisc.data import atomic_write_text

        return atomic_write_text(path, self.to_json(), force=force)

    @classmethod
    def load(cls, path: str | Path) -> Results:
        """Read a ``results.json`` of any known schema; a malformed file is a one-line
        HystdiscError.

        Parameters
        ----------
        path : str or pathlib.Path
            The file to read.

        Returns
        -------
        Results
            The typed record, migrated to :data:`~hystdisc.results.schema.SCHEMA_VERSION`.
        """
        p = Path(path)
        try:
            data = json.loads(p.read_text(encoding="utf-8"))
        except FileNotFoundError:
            raise HystdiscError(
                f"{p}: no such file; fix: give the results.json written by discover"
            ) from None
        except (OSError, UnicodeDecodeError, ValueError, RecursionError) as exc:
            # ValueError covers JSONDecodeError and over-long integer literals
            msg = str(exc).splitlines()[0]
            raise HystdiscError(f"{p}: not a readable results.json ({msg}); {_FIX_RERUN}") from None
        if (
            not isinstance(data, dict)
            or any(k not in data for k in ("families", "model", "experiment"))
            or not isinstance(data["families"], dict)
            or not isinstance(data["model"] or data.get("system_model"), dict)
        ):
            raise HystdiscError(
                f"{p}: not a hystdisc results.json (no 'families'/'model'/'experiment' keys); "
                "fix: give the file written by hystdisc discover --json"
            )
        if data["experiment"] not in (None, *experiment_names()):
            raise HystdiscError(
                f"{p}: not a hystdisc results.json (experiment {str(data['experiment'])[:40]!r} "
                f"is not one of {', '.join(experiment_names())}); {_FIX_RERUN}"
            )
        try:
            return cls.from_dict(data)
        except RecursionError:  # round_json() recurses once per nesting level
            raise HystdiscError(
                f"{p}: not a readable results.json (nested too deeply); {_FIX_RERUN}"
            ) from None
        except SchemaError as exc:
            raise HystdiscError(
                f"{p}: not a hystdisc results.json ({' '.join(str(exc).split())}); {_FIX_RERUN}"
            ) from None

    # ----------------------------------------------------------------- models
    def term_model(self, family: str | None = None, refitted: bool = False) -> TermModel:
        """The fitted model in term form (final model with effects, or one family's fit).

        Parameters
        ----------
        family : str, optional
            A compared family; without it, the final model (selected family and effects).
        refitted : bool
            The final model as the open library's accepted terms refitted it
            (``open_library.refit``; the terms themselves are not part of it).

        Returns
        -------
        TermModel
            The model as ``hystdisc predict`` simulates it.

        Raises
        ------
        HystdiscError
            When there is no such fit or its model is malformed.
        """
        try:
            rec = self._records(family, refitted)[0]
            if rec is None:
                raise KeyError("term_model")
            return (
                TermModelRecord.from_dict(rec).to_term_model() if refitted else rec.to_term_model()
            )
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise _no_model(family, exc) from None

    def _records(self, family: str | None, refitted: bool) -> tuple:
        """The term-form and system records of the final model, a family's fit, or the
        final model as the open library's accepted refit moved it."""
        if refitted:
            r = self.open_library.refit if self.open_library is not None else None
            if r is None or not r.accepted:
                raise KeyError("no accepted refit of the open library's terms")
            return r.model, r.system_model
        if family is None:
            return self.model, self.system_model
        return self.families[family].term_model, self.families[family].system

    def simulation_model(self, family: str | None = None, refitted: bool = False):
        """The fitted model as the simulator takes it: the term form, or a system
        family's state-space model with its parameter values (final model with effects,
        or one family's fit).

        Parameters
        ----------
        family : str, optional
            A compared family; without it, the final model (selected family and effects).
        refitted : bool
            The final model as the open library's accepted terms refitted it (see
            :meth:`term_model`).

        Returns
        -------
        TermModel or tuple of (StateSpaceModel, dict of str to float)
            The term form, or the system with its parameter values.

        Raises
        ------
        HystdiscError
            When there is no such fit or its model is malformed.
        """
        try:
            rec = self._records(family, refitted)[1]
        except KeyError as exc:
            if refitted:
                raise _no_model(family, exc) from None
            rec = None  # term_model says what is missing
        if not rec:
            return self.term_model(family, refitted)
        from hystdisc.registry import get_effect, get_family

        if "structural" in rec:  # the term part (``model``) around a structural effect
            terms = self.term_model(family, refitted)
            try:
                system = get_effect(rec["structural"]).system_model(terms, rec["experiment"])
                values = {k: float(v) for k, v in rec["values"].items()}
                system.check(values)
            except (KeyError, TypeError, ValueError, AttributeError, HystdiscError) as exc:
                raise _no_model(family, exc) from None
            return system, values
        try:
            fam = get_family(rec["family"])
            values = {k: float(v) for k, v in rec["values"].items()}
            # a current law that is not linear: its coefficient is among the values
            laws = fam.laws_of(values)
            system = fam.system(rec["experiment"], tuple(rec.get("effects", ())), laws)
            system.check(values)
        except (KeyError, TypeError, ValueError, AttributeError, HystdiscError) as exc:
            raise _no_model(family, exc) from None
        return system, values

    def to_control(self, family: str | None = None, name: str = "damper") -> Any:
        """The fitted damper as a ``control.NonlinearIOSystem`` (python-control).

        Inputs ``theta, theta_dot, current`` (the motion across the damper and the coil
        current), output ``torque``, the model's own states; the rig, the measurement
        chain and the rig's structure are not part of it
        (:func:`hystdisc.apply.control.to_control`). The final model with the open
        library's accepted terms is the refitted model plus those terms (a play's with a
        state of its own), as ``hystdisc predict`` uses it.

        Parameters
        ----------
        family : str, optional
            A family's own fit instead of the final model.
        name : str
            The system's name in python-control (e.g. for ``interconnect``).

        Returns
        -------
        control.NonlinearIOSystem
            The damper: inputs ``theta, theta_dot, current``, output ``torque``.

        Raises
        ------
        HystdiscError
            When there is no such fit, it is not exportable, or python-control is absent.
        """
        from hystdisc.apply.control import to_control

        refit = self.open_library.refit if self.open_library is not None else None
        if family is None and refit is not None and refit.accepted:
            model = self.simulation_model(refitted=True)
            return to_control(model, self.experiment, name, extra=refit.coefficients)
        return to_control(self.simulation_model(family), self.experiment or "driven", name)

    @property
    def selected(self) -> FamilyResult:
        """The fit of the selected (or declared) family."""
        return self.families[self.family]

    @property
    def closed_loop(self) -> bool:
        """True when the closing loop ran (its keys are present)."""
        return self.diagnosis is not None or bool(self.effects_tried)

    def not_refitted(self) -> list[EffectCandidate]:
        """The first round's candidates that no round refitted.

        Returns
        -------
        list of EffectCandidate
            Those whose evidence called for a refit carry the reason in ``not_refitted``.
        """
        names = {e.name for e in self.effects_tried or []}
        diag = self.diagnosis or []
        return [c for c in (diag[0].candidates if diag else []) if c.name not in names]

    # ----------------------------------------------------------------- text
    def family_table(self) -> str:
        """Fixed-width table of every family's fit (``*``: selected).

        Returns
        -------
        str
            One line per family: parameters, RMS, RMS/noise, BIC, held-out RMS.
        """
        return text.family_table(self)

    def parameter_table(self, family: str | None = None) -> str:
        """Parameters of a family (default: the selected one) with 95 % intervals.

        Parameters
        ----------
        family : str, optional
            The family (default: the selected one).

        Returns
        -------
        str
            The fixed-width table, one parameter a line.
        """
        return text.parameter_table(self, family)

    def effects_table(self) -> list[str]:
        """Lines of the closing-the-loop table (empty when the loop did not run).

        Returns
        -------
        list of str
            The table's lines.
        """
        return text.effects_table(self)

    def measurement_lines(self) -> list[str]:
        """How the noise was estimated and the encoder of a quantized angle, one line each.

        Returns
        -------
        list of str
            The lines.
        """
        return text.measurement_lines(self)

    def report(self) -> str:
        """A readable fit report: discovered equations, family table, parameters, effects.

        Returns
        -------
        str
            The report (what ``hystdisc discover`` prints).
        """
        return text.report(self)

    def __str__(self) -> str:
        return self.report()

    def __repr__(self) -> str:
        return f"<Results family={self.family!r} input={self.input!r}>"

    def _repr_html_(self) -> str:
        return text.html_summary(self)
