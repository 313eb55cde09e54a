"""Results: the typed, versioned record of a discovery (``results.json``).

:class:`Results` is the top-level record (``Discovery.results_``), built in one place,
:func:`hystdisc.pipeline.record.build_results`; its entries are the dataclasses of :mod:`hystdisc.results.records`.
"""

from hystdisc.results.build import family_entry, final_entry
from hystdisc.results.record import SIG_DIGITS, Record, SchemaError, round_json
from hystdisc.results.records import (
    RECORDS,
    DiagnosisRound,
    DiscoveredResult,
    EffectCandidate,
    EffectStep,
    EffectTrial,
    FamilyResult,
    FinalResult,
    ParameterResult,
    ResidualSummary,
    RunRecord,
    SkippedEffect,
    Stage1Record,
    TermModelRecord,
    term_model_from_dict,
    term_model_to_dict,
)
from hystdisc.results.results import Results
from hystdisc.results.schema import SCHEMA_VERSION, migrate

__all__ = [
    "RECORDS",
    "SCHEMA_VERSION",
    "SIG_DIGITS",
    "DiagnosisRound",
    "DiscoveredResult",
    "EffectCandidate",
    "EffectStep",
    "EffectTrial",
    "FamilyResult",
    "FinalResult",
    "ParameterResult",
    "Record",
    "ResidualSummary",
    "Results",
    "RunRecord",
    "SchemaError",
    "SkippedEffect",
    "Stage1Record",
    "TermModelRecord",
    "family_entry",
    "final_entry",
    "migrate",
    "round_json",
    "term_model_from_dict",
    "term_model_to_dict",
]
