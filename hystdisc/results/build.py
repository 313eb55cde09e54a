"""The one place that builds :class:`~hystdisc.results.Results` from a fitted discovery.

:func:`build_results` reads the estimator's public fitted attributes only (the list is in
its docstring) and writes every key of ``results.json``, the closing loop's included, in
the order of schema 1 (so that the bytes of a file stay those of hystdisc 0.1 apart from
``schema_version``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hystdisc import __version__
from hystdisc.registry import get_experiment, get_family
from hystdisc.results.records import term_model_to_dict
from hystdisc.results.results import Results


def _parameters(fit: Any, fixed: tuple[str, ...] = ()) -> dict:
    """``{name: {value, ci95, identifiable}}`` of an output-error fit; the parameters
    ``fixed`` (held at 0 because the data cannot show them) are not identifiable."""
    params = {}
    for k, v in fit.params.items():
        lo, hi = fit.ci95.get(k, (float("nan"), float("nan")))
        ident = fit.identifiable.get(k, True) and k not in fixed
        params[k] = {"value": v, "ci95": [lo, hi], "identifiable": ident}
    return params


def current_dependence(disc: Any) -> dict | None:
    """The ``current_dependence`` table when all runs share one current, else None.

    ``{"identifiable": false, "currents": [...], "fixed": [...], "note": ...}``: the
    current levels of the data, the selected family's current-dependent parameters (fixed
    at 0, marked not identifiable in every family table) and the reason in words. Absent
    from ``results.json`` when the data hold two current levels or more.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> current_dependence(SimpleNamespace(single_current_=True, currents_=[0.5, 0.5],
    ...     family_="dahl"))["fixed"]
    ['k_wb']
    """
    if not getattr(disc, "single_current_", False):
        return None
    levels = sorted({float(c) for c in disc.currents_})
    fixed = list(get_family(disc.family_).current_params)
    shown = ", ".join(f"{c:g}" for c in levels)
    return {
        "identifiable": False,
        "currents": levels,
        "fixed": fixed,
        "note": (
            f"all runs share one current ({shown} A); {', '.join(fixed) or 'no parameter'} "
            f"of {disc.family_} fixed at 0, the other parameters are its values at {shown} A "
            "(every family's current-dependent parameters likewise)"
        ),
    }


def family_entry(
    name: str,
    fit: Any,
    discovered_terms: dict,
    admissibility: Any | None = None,
    one_current: bool = False,
) -> dict:
    """The ``families`` entry of one family's fit (a plain table of the schema).

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
    dict
        The table of :class:`~hystdisc.results.FamilyResult`.
    """
    fam = get_family(name)
    fixed = tuple(fam.current_params) if one_current else ()
    if fit.is_system:  # a state-space family: no terms to compare with stage 1's
        return {
            **_common(fit, fam, admissibility, fixed),
            "missing_terms": [],
            "extra_terms": [],
            "notes": list(fit.notes),
            "term_model": None,
            "system": system_entry(fit),
            "converged": fit.success,
        }
    # terms the fit really uses (a current term fixed at 0 for one current is not "added")
    tm = fit.term_model
    fam_t = {t for t in fam.torque_terms if tm.torque.get(t, 0.0) != 0.0}
    fam_h = {t for t in fam.hysteresis_terms if tm.hysteresis.get(t, 0.0) != 0.0}
    dt = set(discovered_terms["torque"]) - {"theta", "1"}
    dh = set(discovered_terms["hysteresis"])
    return {
        **_common(fit, fam, admissibility, fixed),
        # hysteresis-side names are prefixed: theta_dot and |theta_dot|*z exist on both sides
        "missing_terms": sorted(dt - fam_t) + [f"dz/dt: {t}" for t in sorted(dh - fam_h)],
        "extra_terms": sorted(fam_t - dt) + [f"dz/dt: {t}" for t in sorted(fam_h - dh)],
        "notes": list(fit.notes),
        "term_model": term_model_to_dict(fit.term_model),
        "converged": fit.success,
    }


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


def system_entry(fit: Any) -> dict | None:
    """The ``system`` table of a state-space fit (None for a term model). A term model
    around a structural effect (``series_compliance``) is its term part (``model``) plus
    ``{"structural": name, "experiment", "values": the effect's parameters}``."""
    structure = getattr(fit.par, "structure", None)
    if structure is not None:
        _, values = fit.model
        return {
            "structural": structure.name,
            "experiment": fit.par.experiment,
            "values": {k: float(v) for k, v in values.items()},
        }
    if not fit.is_system:
        return None
    system, values = fit.model
    return {
        "family": system.family.name,
        "experiment": system.experiment.name,
        "effects": list(system.effects),
        "values": {k: float(v) for k, v in values.items()},
    }


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
) -> dict:
    """The ``final`` table: the selected family with its accepted effects (``fixed``: its
    parameters held at 0, not identifiable)."""
    return {
        "family": family,
        "effects": list(effects),
        "parameters": _parameters(fit, fixed),
        "rms": fit.rms,
        "bic": fit.bic,
        "heldout_rms": fit.heldout_rms,
        "n_params": fit.n_params,
        "converged": fit.success,
        "notes": list(fit.notes),
        **_admissible(admissibility),
    }


def _no_loop_residual(disc: Any, dataset: Any) -> dict:
    """The residual summary of the selected fit over the fitted samples (no closing loop)."""
    from hystdisc.closing.diagnostics import residual_summary

    sel = disc.family_fits_[disc.family_]
    fs = float(np.median([r.fs for r in dataset.runs]))
    masked = [r[m] for r, m in zip(sel.residuals, disc.fit_data_.mask, strict=True)]
    noise = getattr(disc, "noise_", None)
    return residual_summary(masked, fs, disc.noise_std_, noise.samples if noise else None)


def build_results(disc: Any, dataset: Any) -> Results:
    """The complete ``results.json`` record of a fitted :class:`~hystdisc.Discovery`.

    Reads only the estimator's public attributes: ``experiment_``, ``noise_std_``,
    ``terms_``, ``discovered_name_``, ``discovered_shape_``, ``stage1_`` (shape -> object
    with ``terms``, ``bic``, ``inclusion``), ``discovered_fit_``, ``family_fits_``,
    ``family_``, ``declared_``, ``equal_fits_``, ``fit_data_`` (its ``mask``, ``names``,
    ``folds()``, ``heldout_by``, ``motion_noise``), ``conditions_``, ``envelope_``,
    ``admissibility_``,
    ``final_admissibility_``, ``selection_note_``, ``single_current_``, ``currents_``,
    ``noise_`` (optional: the :class:`~hystdisc.data.NoiseEstimate`), ``outliers_`` (its
    ``to_dict()``), ``reselection_`` and ``reduction_`` (optional, their ``to_dict()``), ``loop_``
    (the closing loop's ``LoopResult``, or None when it did not run: ``accepted``,
    ``tried``, ``skipped``, ``diagnosis``, ``unexplained``, ``unexplained_text``,
    ``residual``, ``fit``, ``effects``), the parameters ``input_hold`` and ``seed``, and
    ``equations()``.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    dataset : Dataset
        The dataset it was fitted on (source, runs, sampling rate).

    Returns
    -------
    Results
    """
    adm = disc.admissibility_
    currents = current_dependence(disc)
    one = currents is not None
    fams = {
        n: family_entry(n, f, disc.terms_, adm.get(n), one_current=one)
        for n, f in disc.family_fits_.items()
    }
    sel = disc.family_fits_[disc.family_]
    dfit = disc.discovered_fit_
    loop = disc.loop_
    final = loop.fit if loop is not None else sel
    forced = get_experiment(disc.experiment_).has_input
    data: dict[str, Any] = {
        "version": __version__,
        "input": dataset.source,
        "experiment": disc.experiment_,
        **({"input_hold": disc.input_hold} if forced else {}),
        "noise_std": disc.noise_std_,
        "terms": disc.terms_,
        "discovered": {
            "name": disc.discovered_name_,
            "shape": disc.discovered_shape_,
            "equations": disc.equations(),
            "parameters": dfit.params,
            "rms": dfit.rms,
            "bic": dfit.bic,
            "term_model": term_model_to_dict(dfit.term_model),
            "stage1": {
                k: {"terms": v.terms, "bic": v.bic, "inclusion": v.inclusion}
                for k, v in disc.stage1_.items()
            },
        },
        "family": disc.family_,
        "declared": disc.declared_,
        "equal_fits": disc.equal_fits_,
        "families": fams,
        "model": None if final.is_system else term_model_to_dict(final.term_part),
        # the measurement effects judged before the loop (a channel delay), then the loop's
        "effects": [v["entry"] for v in getattr(disc, "measured_", []) if v["entry"]]
        + (loop.accepted if loop is not None else []),
        "unexplained": loop.unexplained if loop is not None else False,
        # the residual over the samples the fit uses (driven start-up excluded)
        "residual": loop.residual if loop is not None else _no_loop_residual(disc, dataset),
        "runs": [
            {"name": r.name, "current": r.current, "samples": int(r.t.size)} for r in dataset.runs
        ],
        "seed": disc.seed,
        "conditions": {
            "labels": dict(zip(disc.fit_data_.names, disc.conditions_, strict=True)),
            "heldout_by": disc.fit_data_.heldout_by,
            "folds": len(disc.fit_data_.folds()),
        },
        "envelope": disc.envelope_.to_dict(),
        "selection_note": disc.selection_note_,
        "system_model": system_entry(final),
    }
    if currents is not None:  # one current: its dependence is not identifiable
        data["current_dependence"] = currents
    noise = getattr(disc, "noise_", None)
    if noise is not None:  # the measurement, modelled: how the noise was estimated
        data["noise"] = noise.to_dict()
        data["encoder"] = noise.encoder.to_dict() if noise.encoder is not None else None
    motion = getattr(disc.fit_data_, "motion_noise", None)
    if motion is not None:  # driven: the measured motion's noise, carried to the intervals
        data["motion_noise"] = motion.to_dict()
    outliers = getattr(disc, "outliers_", None)
    if outliers is not None:  # the isolated glitches left out of the fits
        data["outliers"] = outliers.to_dict()
    # the tasks that failed and were dropped (the run went on without them)
    data["failed"] = dict(getattr(disc, "failed_", {}))
    scan = getattr(disc, "delay_scan_", None)
    if scan is not None:  # the delay between the channels, scanned by stage 1
        data["delay_scan"] = {**scan.to_dict(), "notes": [v["note"] for v in disc.measured_]}
    reselection = getattr(disc, "reselection_", None)
    if reselection is not None:  # the families compared again with the rig's effects
        data["reselection"] = reselection.to_dict()
    reduction = getattr(disc, "reduction_", None)
    if reduction is not None:  # the selected family reduced to a smaller one plus effects
        data["reduction"] = reduction.to_dict()
    staged = getattr(disc, "staged_", None)
    if staged is not None:  # the seed's flowchart: per-level fits and current laws
        data["current_laws"] = staged.to_dict(disc.fit_data_.names)
    if loop is not None:
        data.update(
            {
                "effects_tried": loop.tried,
                "effects_skipped": loop.skipped,
                "diagnosis": loop.diagnosis,
                "unexplained_text": loop.unexplained_text,
                "final": final_entry(
                    loop.fit,
                    disc.family_,
                    getattr(disc, "effects_", loop.effects),
                    disc.final_admissibility_,
                    tuple(currents["fixed"]) if currents else (),
                ),
            }
        )
    return Results.from_dict(data)
