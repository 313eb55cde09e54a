"""The entries of ``results.json`` made from fits: a family's table, a state-space model's,
the final model's.

The whole record is built from a discovery's state by
:func:`hystdisc.pipeline.record.build_results`; these are the tables it is made of, made
as records (:meth:`~hystdisc.results.record.Record.make`), not as plain tables to parse.
"""

from __future__ import annotations

from typing import Any

from hystdisc.registry import get_family
from hystdisc.results.records import (
    FamilyResult,
    FinalResult,
    ParameterResult,
    TermModelRecord,
)
from hystdisc.results.sections import SystemModelRecord


def _parameters(fit: Any, fixed: tuple[str, ...] = ()) -> dict[str, ParameterResult]:
    """``{name: (value, ci95, identifiable)}`` of an output-error fit; the parameters
    ``fixed`` (held at 0 because the data cannot show them) are not identifiable."""
    params = {}
    for k, v in fit.params.items():
        lo, hi = fit.ci95.get(k, (float("nan"), float("nan")))
        ident = fit.identifiable.get(k, True) and k not in fixed
        params[k] = ParameterResult.make(value=v, ci95=[lo, hi], identifiable=ident)
    return params


def family_entry(
    name: str,
    fit: Any,
    discovered_terms: dict,
    admissibility: Any | None = None,
    one_current: bool = False,
) -> FamilyResult:
    """The ``families`` entry of one family's fit.

    Parameters
    ----------
    name : str
        Family name.
    fit : OEFit
        Its output-error fit.
    discovered_terms : dict
        ``{"torque": [...], "hysteresis": [...]}`` that stage 1 discovered.
    admissibility : Admissibility, optional
        Its physical admissibility (``ok``, ``violations``).
    one_current : bool
        All runs share one current: the family's current-dependent parameters were fixed
        at 0 and are marked not identifiable.

    Returns
    -------
    FamilyResult
        The entry.
    """
    fam = get_family(name)
    fixed = tuple(fam.current_params) if one_current else ()
    if fit.is_system:  # a state-space family: no terms to compare with stage 1's
        return FamilyResult.make(
            **_common(fit, fam, admissibility, fixed),
            missing_terms=[],
            extra_terms=[],
            notes=list(fit.notes),
            term_model=None,
            system=system_entry(fit),
            converged=fit.success,
        )
    # terms the fit really uses (a current term fixed at 0 for one current is not "added")
    tm = fit.term_model
    fam_t = {t for t in fam.torque_terms if tm.torque.get(t, 0.0) != 0.0}
    fam_h = {t for t in fam.hysteresis_terms if tm.hysteresis.get(t, 0.0) != 0.0}
    dt = set(discovered_terms["torque"]) - {"theta", "1"}
    dh = set(discovered_terms["hysteresis"])
    return FamilyResult.make(
        **_common(fit, fam, admissibility, fixed),
        # hysteresis-side names are prefixed: theta_dot and |theta_dot|*z exist on both sides
        missing_terms=sorted(dt - fam_t) + [f"dz/dt: {t}" for t in sorted(dh - fam_h)],
        extra_terms=sorted(fam_t - dt) + [f"dz/dt: {t}" for t in sorted(fam_h - dh)],
        notes=list(fit.notes),
        term_model=TermModelRecord.of(fit.term_model),
        converged=fit.success,
    )


def _common(fit: Any, fam: Any, admissibility: Any | None, fixed: tuple[str, ...]) -> dict:
    return {
        "parameters": _parameters(fit, fixed),
        "normalization": getattr(fit.par, "normalization", "") or fam.normalization,
        "rms": fit.rms,
        "bic": fit.bic,
        "heldout_rms": fit.heldout_rms,
        "n_params": fit.n_params,
        **_admissible(admissibility),
    }


def system_entry(fit: Any) -> SystemModelRecord | None:
    """The ``system`` table of a state-space fit (None for a term model). A term model
    around a structural effect (``series_compliance``) is its term part (``model``) plus
    ``{"structural": name, "experiment", "values": the effect's parameters}``."""
    structure = getattr(fit.par, "structure", None)
    if structure is not None:
        _, values = fit.model
        return SystemModelRecord.make(
            structural=structure.name,
            experiment=fit.par.experiment,
            values={k: float(v) for k, v in values.items()},
        )
    if not fit.is_system:
        return None
    system, values = fit.model
    return SystemModelRecord.make(
        family=system.family.name,
        experiment=system.experiment.name,
        effects=list(system.effects),
        values={k: float(v) for k, v in values.items()},
    )


def _admissible(adm: Any | None) -> dict:
    if adm is None:
        return {}
    return {"admissible": bool(adm.ok), "violations": list(adm.violations)}


def final_entry(
    fit: Any,
    family: str,
    effects: list[str],
    admissibility: Any = None,
    fixed: tuple[str, ...] = (),
) -> FinalResult:
    """The ``final`` entry: the selected family with its accepted effects (``fixed``: its
    parameters held at 0, not identifiable)."""
    return FinalResult.make(
        family=family,
        effects=list(effects),
        parameters=_parameters(fit, fixed),
        rms=fit.rms,
        bic=fit.bic,
        heldout_rms=fit.heldout_rms,
        n_params=fit.n_params,
        converged=fit.success,
        notes=list(fit.notes),
        **_admissible(admissibility),
    )
