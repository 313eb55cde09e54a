"""The one place that builds :class:`~hystdisc.results.Results` from a discovery's state.

:func:`build_results` reads the :class:`~hystdisc.pipeline.state.State` the stages filled
and makes every key of ``results.json``, the closing loop's included, in the order of
schema 1 (so that the bytes of a file stay those of hystdisc 0.1 apart from
``schema_version``). It makes the typed records directly
(:meth:`~hystdisc.results.record.Record.make`, rounded as the file holds them), never a
plain table to parse back: the tables of single fits are :mod:`hystdisc.results.build`'s,
those of the closing loop's records :mod:`hystdisc.pipeline.loop_record`'s.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from hystdisc import __version__
from hystdisc.closing.open_library import ResidualTerms
from hystdisc.models import TermModel, format_equation
from hystdisc.pipeline.loop_record import effect_step, loop_tables, residual_summary
from hystdisc.pipeline.state import State
from hystdisc.registry import get_experiment, get_family
from hystdisc.results import SCHEMA_VERSION, Results
from hystdisc.results.build import family_entry, final_entry, system_entry
from hystdisc.results.record import Record, round_json
from hystdisc.results.records import (
    DiscoveredResult,
    ResidualSummary,
    RunRecord,
    Stage1Record,
    TermModelRecord,
)
from hystdisc.results.sections import (
    SECTIONS,
    ConditionsRecord,
    CurrentDependenceRecord,
    DelayScanRecord,
    EncoderRecord,
)


def equations(tm: TermModel, experiment: str) -> str:
    """pysindy-style text of a discovered structure ``tm``: the torque equation, the
    hysteresis equation (and ``J`` when the experiment identifies it).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> print(equations(Model("dahl").to_terms(), "driven"))
    T = 0.8 theta_dot + 0.5 z + 1.5 i*z + 158 theta
    dz/dt = 20 theta_dot - 20 |theta_dot|*z
    """
    lines = [format_equation("T", tm.torque)]
    if tm.hysteresis:
        lines.append(tm.equations().splitlines()[1])
    if get_experiment(experiment).inertia_identifiable:
        lines.insert(0, f"J = {tm.J:.4g}")
    return "\n".join(lines)


def current_dependence(state: State) -> dict | None:
    """The ``current_dependence`` table when all runs share one current, else None.

    ``{"identifiable": false, "currents": [...], "fixed": [...], "note": ...}``: the
    current levels of the data, the selected family's current-dependent parameters (fixed
    at 0, marked not identifiable in every family table) and the reason in words. Absent
    from ``results.json`` when the data hold two current levels or more.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> current_dependence(SimpleNamespace(single_current=True, currents=[0.5, 0.5],
    ...     family="dahl"))["fixed"]
    ['k_wb']
    """
    if not state.single_current:
        return None
    levels = sorted({float(c) for c in state.currents})
    fixed = list(get_family(state.family).current_params)
    shown = ", ".join(f"{c:g}" for c in levels)
    return {
        "identifiable": False,
        "currents": levels,
        "fixed": fixed,
        "note": (
            f"all runs share one current ({shown} A); {', '.join(fixed) or 'no parameter'} "
            f"of {state.family} fixed at 0, the other parameters are its values at {shown} A "
            "(every family's current-dependent parameters likewise)"
        ),
    }


def library_section(lib: ResidualTerms) -> Record:
    """The ``open_library`` section: what the library found, and its refit with the
    refitted model recorded as ``model`` and ``system_model`` record the final one."""
    table = lib.to_dict()
    moved = lib.refit.fit if lib.refit is not None else None
    if moved is not None:
        term = None if moved.is_system else TermModelRecord.of(moved.term_part).to_dict()
        entry = system_entry(moved)
        table["refit"]["model"] = term
        table["refit"]["system_model"] = None if entry is None else entry.to_dict()
    return section("open_library", table)


def section(key: str, table: dict) -> Record:
    """The typed section ``key`` of ``results.json`` from the JSON form its source object
    gives (``NoiseEstimate.to_dict``...: those objects own their form, and read it back),
    rounded as the file holds it; the nested tables become their records."""
    return SECTIONS[key].from_dict(round_json(table), key)


def _no_loop_residual(state: State) -> ResidualSummary:
    """The residual summary of the selected fit over the fitted samples (no closing loop)."""
    from hystdisc.closing.diagnostics import residual_summary as summary

    sel = state.family_fits[state.family]
    fs = float(np.median([r.fs for r in state.dataset.runs]))
    masked = [r[m] for r, m in zip(sel.residuals, state.fd.mask, strict=True)]
    noise = state.noise
    return ResidualSummary.make(
        **summary(masked, fs, state.noise_std, noise.samples if noise else None)
    )


def _discovered(state: State) -> DiscoveredResult:
    """The ``discovered`` entry: stage 1's structure and its output-error fit."""
    dfit = state.discovered_fit
    return DiscoveredResult.make(
        name=state.discovered_name,
        shape=state.discovered_shape,
        equations=equations(dfit.term_model, state.experiment),
        parameters=dfit.params,
        rms=dfit.rms,
        bic=dfit.bic,
        term_model=TermModelRecord.of(dfit.term_model),
        stage1={
            k: Stage1Record.make(terms=v.terms, bic=v.bic, inclusion=v.inclusion)
            for k, v in state.stage1.items()
        },
    )


def build_results(state: State) -> Results:
    """The complete ``results.json`` record of a discovery's state."""
    dataset, opts, fd = state.dataset, state.options, state.fd
    adm = state.admissibility
    currents = current_dependence(state)
    one = currents is not None
    fitted = {n: int(np.asarray(m).sum()) for n, m in zip(fd.names, fd.mask, strict=True)}
    fams = {
        n: family_entry(n, f, state.terms, adm.get(n), one_current=one)
        for n, f in state.family_fits.items()
    }
    loop = state.loop
    final = loop.fit if loop is not None else state.family_fits[state.family]
    forced = get_experiment(state.experiment).has_input
    # the keys in the order of the file (schema 1's, then the ones added since)
    data: dict[str, Any] = {
        "schema_version": SCHEMA_VERSION,
        "version": __version__,
        "input": dataset.source,
        "experiment": state.experiment,
        **({"input_hold": opts.input_hold} if forced else {}),
        "noise_std": state.noise_std,
        "terms": state.terms,
        "discovered": _discovered(state),
        "family": state.family,
        "declared": state.declared,
        "equal_fits": state.equal_fits,
        "families": fams,
        "model": None if final.is_system else TermModelRecord.of(final.term_part),
        # the measurement effects judged before the loop (a channel delay), then the loop's
        "effects": [effect_step(v.entry) for v in state.measured if v.entry is not None]
        + ([effect_step(a) for a in loop.accepted] if loop is not None else []),
        "unexplained": loop.unexplained if loop is not None else False,
        # the residual over the samples the fit uses (driven start-up excluded)
        "residual": (
            residual_summary(loop.residual)
            if loop is not None and loop.residual is not None
            else _no_loop_residual(state)
        ),
        "runs": [
            RunRecord.make(
                name=r.name, current=r.current, samples=int(r.t.size), fitted=fitted.get(r.name)
            )
            for r in dataset.runs
        ],
        "seed": opts.seed,
        "conditions": ConditionsRecord.make(
            labels=dict(zip(fd.names, state.conditions, strict=True)),
            heldout_by=fd.heldout_by,
            folds=len(fd.folds()),
        ),
        "envelope": section("envelope", state.envelope.to_dict()),
        "selection_note": state.selection_note,
        "system_model": system_entry(final),
    }
    if currents is not None:  # one current: its dependence is not identifiable
        data["current_dependence"] = CurrentDependenceRecord.make(**currents)
    if state.noise is not None:  # the measurement, modelled: how the noise was estimated
        data["noise"] = section("noise", state.noise.to_dict())
        enc = state.noise.encoder
        data["encoder"] = EncoderRecord.make(**enc.to_dict()) if enc is not None else None
    if state.prefilter is not None:  # a moving average read in the records, fitted through
        data["prefilter"] = section("prefilter", state.prefilter.to_dict())
    if fd.motion_noise is not None:  # driven: the measured motion's noise, in the intervals
        data["motion_noise"] = section("motion_noise", fd.motion_noise.to_dict())
    if state.outliers is not None:  # the isolated glitches left out of the fits
        data["outliers"] = section("outliers", state.outliers.to_dict())
    # the tasks that failed and were dropped (the run went on without them)
    data["failed"] = dict(state.failed)
    if state.delay_scan is not None:  # the delay between the channels, scanned by stage 1
        notes = [v.note for v in state.measured]
        data["delay_scan"] = DelayScanRecord.make(**state.delay_scan.to_dict(), notes=notes)
    if state.open_library is not None:  # the open library on a residual the catalogue left
        data["open_library"] = library_section(state.open_library)
    if state.reselection is not None:  # the families compared again with the rig's effects
        data["reselection"] = section("reselection", state.reselection.to_dict())
    if state.reduction is not None:  # the selected family reduced to a smaller one + effects
        data["reduction"] = section("reduction", state.reduction.to_dict())
    if state.staged is not None:  # the seed's flowchart: per-level fits and current laws
        data["current_laws"] = section("current_laws", state.staged.to_dict(fd.names))
    if loop is not None:
        data.update(loop_tables(loop))
        data["final"] = final_entry(
            loop.fit,
            state.family,
            state.effects,
            state.final_admissibility,
            tuple(currents["fixed"]) if currents else (),
        )
    return Results.make(**data)
