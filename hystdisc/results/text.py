"""The console fit report of :class:`~hystdisc.results.Results` and its notebook HTML.

Every function takes a :class:`~hystdisc.results.Results` and reads its attributes.
"""

from __future__ import annotations

import html
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # the Results class imports this module
    from hystdisc.results.results import Results
    from hystdisc.results.sections import MotionNoiseRecord, OpenLibraryRecord


def _num(x: Any, fmt: str) -> str:
    return "-" if x is None else format(x, fmt)


def family_table(res: Results) -> str:
    """Fixed-width table of every family's fit (``*`` marks the selected one)."""
    rows = [
        f"{'family':<14}{'params':>7}{'RMS':>12}{'RMS/noise':>10}{'BIC':>14}{'held-out RMS':>14}"
    ]
    noise = res.noise_std or float("nan")
    for name, f in res.families.items():
        mark = " *" if name == res.family else ""
        ho = f.heldout_rms
        flag = "  not physical" if f.admissible is False else ""
        rows.append(
            f"{name + mark:<14}{f.n_params:>7d}{f.rms:>12.4g}{f.rms / noise:>10.3f}"
            f"{f.bic:>14.1f}{(f'{ho:.4g}' if ho is not None else '-'):>14}{flag}"
        )
    cond = res.conditions
    if cond:
        what = (
            f"each of the {cond.folds} test conditions"
            if cond.heldout_by == "condition"
            else "each run (the runs share one test condition)"
        )
        rows.append(f"held-out RMS: {what} predicted by the fit without it")
    for name, f in res.families.items():  # a '-' where the folds ran says why
        rows += [f"{name}: {n}" for n in f.notes if "held-out RMS not reported" in n]
    # the table's fits; with a re-selection, the families were fitted again with effects
    rs = res.reselection
    without = f" without {', '.join(rs.effects)}" if rs else ""
    for name, f in res.families.items():
        for v in f.violations:
            rows.append(f"{name} is not physical{without}: {v}")
    if res.selection_note:
        rows.append(f"selection: {res.selection_note}")
    if rs:  # the families compared again with the loop's effects
        cells = [
            f"{n} {_num(e.heldout_rms, '.4g')}{'' if e.admissible else ' (not physical)'}"
            for n, e in rs.families.items()
        ]
        rows.append(f"held-out RMS with {', '.join(rs.effects)}: " + ", ".join(cells))
        if not rs.switched:
            rows.append(f"selection again: {rs.note}")
    rd = res.reduction
    if rd and not rd.switched:  # a switch is the selection note itself
        rows.append(f"reduction: {rd.note}")
    return "\n".join(rows)


def parameter_table(res: Results, family: str | None = None) -> str:
    """A family's parameters (default: the selected one) with their 95 % intervals."""
    fam = family or res.family
    f = res.families[fam]
    rows = [
        f"{fam} parameters ({f.normalization})",
        f"  {'name':<10}{'value':>13}   {'95 % interval':<30}",
    ]
    for k, p in f.parameters.items():
        lo, hi = p.ci95 if p.ci95 else (None, None)
        ci = f"[{lo:.5g}, {hi:.5g}]" if lo is not None else "-"
        flag = "" if p.identifiable else "  not identifiable"
        rows.append(f"  {k:<10}{p.value:>13.6g}   {ci:<30}{flag}")
    for note in f.notes:
        rows.append(f"  note: {note}")
    return "\n".join(rows)


def _trial_lines(res: Results) -> list[str]:
    tried = res.effects_tried or []
    if not tried:
        return []
    out = [
        f"  {'effect':<20}{'evidence':>9}{'(eq.)':>8}  {'RMS before -> after':<24}"
        f"{'BIC change':>11}  {'held-out before -> after':<26}verdict"
    ]
    for e in tried:
        dbic = (
            e.bic_after - e.bic_before
            if e.bic_after is not None and e.bic_before is not None
            else None
        )
        verdict = "accepted" if e.accepted else ("removed" if e.removed else "rejected")
        if not e.accepted and e.note:
            verdict += f" ({e.note})"
        before, after = _num(e.rms_before, ".4g"), _num(e.rms_after, ".4g")
        hb, ha = _num(e.heldout_rms_before, ".4g"), _num(e.heldout_rms_after, ".4g")
        out.append(
            f"  {e.name:<20}{_num(e.evidence, '.3f'):>9}{_num(e.evidence_eq, '.3f'):>8}  "
            f"{before + ' -> ' + after:<24}{_num(dbic, '.1f'):>11}  {hb + ' -> ' + ha:<26}"
            f"{verdict}"
        )
    return out


def effects_table(res: Results) -> list[str]:
    """Lines of the closing-the-loop table: every refitted effect, then the verdict.

    Returns
    -------
    list of str
        Empty when the loop did not run.
    """
    if not res.closed_loop:
        return []
    out = ["", "Closing the loop (residual -> catalogued effects):", *_trial_lines(res)]
    rest = res.not_refitted()
    weak = [c for c in rest if not c.not_refitted]
    if weak:
        out.append(
            "  not refitted (too little evidence): "
            + ", ".join(f"{c.name} {_num(c.evidence, '.2g')}" for c in weak)
        )
    for c in rest:
        if c.not_refitted:
            out.append(f"  not refitted: {c.name} ({c.not_refitted})")
    for sk in res.effects_skipped or []:
        out.append(f"  not applicable: {sk.name} ({sk.reason})")
    if res.effects:
        out.append("  Accepted effects (final fit, 95 % intervals):")
        for e in res.effects:
            ps = ", ".join(
                f"{k} = {p.value:.5g} [{_num(p.ci95[0], '.5g')}, {_num(p.ci95[1], '.5g')}]"
                for k, p in e.parameters.items()
            )
            held = ""
            if e.heldout_rms_before is not None and e.heldout_rms_after is not None:
                held = f", held-out {e.heldout_rms_before:.4g} -> {e.heldout_rms_after:.4g}"
            out.append(
                f"    {e.name} ({', '.join(e.terms)}): {ps}; RMS "
                f"{e.rms_before:.4g} -> {e.rms_after:.4g}{held}"
            )
    else:
        out.append("  No catalogued effect improves the model.")
    fin = res.final
    if fin:
        noise = res.noise_std
        ratio = f" ({fin.rms / noise:.2f}x the noise)" if noise else ""
        held = f", held-out {fin.heldout_rms:.4g}" if fin.heldout_rms is not None else ""
        out.append(
            f"  Final model: {' + '.join([fin.family, *fin.effects])}, "
            f"RMS {fin.rms:.4g}{ratio}{held}, BIC {fin.bic:.1f}"
        )
        refit = res.open_library.refit if res.open_library is not None else None
        if refit is not None and refit.accepted and refit.redundant:
            kept = [e for e in fin.effects if e not in refit.redundant]
            out.append(
                f"  With the open library's accepted terms (below): "
                f"{' + '.join([fin.family, *kept, 'F_extra'])}; "
                f"{', '.join(refit.redundant)} only stood in for them"
            )
        if fin.effects:  # the family's own parameters move when an effect enters
            effect_params = {k for e in res.effects for k in e.parameters}
            out.append("  Final model's parameters (95 % intervals):")
            for k, p in fin.parameters.items():
                if k in effect_params or p.value is None:
                    continue
                lo, hi = p.ci95 if p.ci95 else (None, None)
                ci = f"[{lo:.5g}, {hi:.5g}]" if lo is not None and hi is not None else "-"
                flag = "" if p.identifiable else "  not identifiable"
                out.append(f"    {k:<10}{p.value:>13.6g}   {ci:<30}{flag}".rstrip())
        for v in fin.violations:
            out.append(f"  WARNING: the final model is not physical: {v}")
    return out


def _residual_lines(res: Results) -> list[str]:
    r = res.residual
    if not r:
        return []
    wp, ratio = r.whiteness_p, r.rms_over_noise
    spectrum = r.whiteness_test == "noise spectrum"
    verdict = "white" if wp is not None and wp >= 0.01 else "not white"
    if spectrum:
        verdict = "as the noise" if wp is not None and wp >= 0.01 else "above the noise"
    rms = r.rms if r.rms is not None else float("nan")
    test = "whiteness against the noise's own spectrum" if spectrum else "Ljung-Box whiteness"
    out = [
        "",
        f"Residual: RMS {rms:.4g}"
        + (f" ({ratio:.2f}x the noise)" if ratio is not None else "")
        + f", {test} p = {wp if wp is None else format(wp, '.3g')} "
        + f"({verdict})"
        + (f", dominant {r.dominant_hz:.3g} Hz" if r.dominant_hz is not None else ""),
    ]
    if res.unexplained:
        out.append(f"  Unexplained: {res.unexplained_text or 'structure remains'}")
    out += ["  " + line for line in open_library_lines(res.open_library)]
    return out


def open_library_lines(lib: OpenLibraryRecord | None) -> list[str]:
    """The open library's finding, a line each: its stable terms, their inclusion and
    the catalogued effect each belongs to, and the discovered effect's equation.

    Examples
    --------
    >>> from hystdisc.results.sections import OpenLibraryRecord
    >>> lib = OpenLibraryRecord.from_dict({"candidates": 31, "explained": 0.88,
    ...     "equation": "T_extra = 0.05*[theta_dot>0]", "terms": [{"name": "[theta_dot>0]",
    ...     "coefficient": 0.05, "inclusion": 1.0, "effect": ""}]})
    >>> for line in open_library_lines(lib):
    ...     print(line)
    Open library (31 candidates, stability selection): 1 stable term explains 88 % of it
      [theta_dot>0]: 0.05 (inclusion 1.00, discovered)
      T_extra = 0.05*[theta_dot>0] (evidence, not a verdict: refit and held out before use)
    """
    if not lib:
        return []
    terms = lib.terms
    head = f"Open library ({lib.candidates} candidates, stability selection): "
    if not terms:
        return [head + "no stable term"]
    n = len(terms)
    out = [
        head + f"{n} stable term{'s' if n > 1 else ''} explain{'' if n > 1 else 's'} "
        f"{100 * float(lib.explained or 0.0):.0f} % of it"
    ]
    for t in terms:
        who = f"-> {t.effect}" if t.effect else "discovered"
        out.append(f"  {t.name}: {t.coefficient:.4g} (inclusion {t.inclusion:.2f}, {who})")
    if lib.equation:
        out.append(f"  {lib.equation} (evidence, not a verdict: refit and held out before use)")
    h = lib.heldout
    if h is not None and h.before is not None and h.after is not None:
        out.append(
            f"  held out (each condition left out, the model refitted with the terms, "
            f"linearized): {h.before:.4g} -> {h.after:.4g}, lower in {h.lower} of {h.folds} "
            "conditions"
        )
    return out + library_refit_lines(lib.refit)


def library_refit_lines(refit) -> list[str]:
    """The open library's terms refitted into the model (``open_library.refit``): the
    equation with its coefficients and the held-out verdict.

    Examples
    --------
    >>> from hystdisc.results.sections import LibraryRefitRecord
    >>> r = LibraryRefitRecord.from_dict({"terms": ["i"], "coefficients": {"i": -20.3},
    ...     "stderr": {"i": 0.4}, "rms_before": 41.2, "rms_after": 15.1,
    ...     "heldout_before": 46.6, "heldout_after": 15.3, "fold_after": [1] * 6,
    ...     "lower": 6, "accepted": True, "note": "they remove 88% of the excess",
    ...     "equation": "F_extra = -20.3*i"})
    >>> for line in library_refit_lines(r):
    ...     print(line)
      refitted into the model by output error: F_extra = -20.3*i
        i = -20.3 +/- 0.4 (s.e.)
        RMS 41.2 -> 15.1, held out 46.6 -> 15.3 (each condition left out, both models refitted; lower in 6 of 6): ACCEPTED, they remove 88% of the excess
    """
    if refit is None:
        return []
    out = [f"  refitted into the model by output error: {refit.equation}"]
    out += [f"    {n} = {refit.coefficients[n]:.4g} +/- {refit.stderr.get(n, float('nan')):.2g} (s.e.)"
            for n in refit.terms]  # fmt: skip
    held = "held out: not available"
    if refit.heldout_before is not None and refit.heldout_after is not None:
        held = (
            f"held out {refit.heldout_before:.4g} -> {refit.heldout_after:.4g} (each condition "
            f"left out, both models refitted; lower in {refit.lower} of {len(refit.fold_after)})"
        )
    verdict = "ACCEPTED" if refit.accepted else "not accepted"
    out.append(
        f"    RMS {refit.rms_before:.4g} -> {refit.rms_after:.4g}, {held}: {verdict}, {refit.note}"
    )
    if refit.redundant:
        out.append(f"    {redundant_sentence(refit.redundant)}")
    return out


def redundant_sentence(redundant: dict[str, float]) -> str:
    """The catalogued effects the open library's terms made redundant, in words.

    Examples
    --------
    >>> redundant_sentence({"offset": 0.04, "level_bias": 1.2})
    'the refitted model leaves out offset, level_bias: beside the terms their parameters are no longer significant (z^2 0.04, 1.2) and BIC falls without them; they stood in for what the terms describe'
    """
    names = ", ".join(redundant)
    z2 = ", ".join(f"{v:.2g}" for v in redundant.values())
    return (
        f"the refitted model leaves out {names}: beside the terms their parameters are no "
        f"longer significant (z^2 {z2}) and BIC falls without them; they stood in for what "
        "the terms describe"
    )


_HOW = {
    "period": "period-to-period differences of the periodic excitation",
    "cycles": "the output's cycle-to-cycle repeatability (cycles aligned on the motion)",
    "differences": "high-order differences (white noise assumed; a fallback: no run repeats)",
    "quantization": "the quantization floor q/sqrt(12)",
}


def measurement_lines(res: Results) -> list[str]:
    """How the noise was estimated, and the encoder of a quantized angle (if any)."""
    out = []
    nz, enc = res.noise, res.encoder
    if nz is not None and nz.std is not None:
        how = _HOW.get(nz.method, str(nz.method))
        diff = nz.differences
        other = (
            f"; high-order differences give {diff:.3g}"
            if nz.method != "differences" and diff is not None
            else ""
        )
        out.append(f"Measurement noise: {nz.std:.3g} from {how}{other}")
    motion = res.motion_noise
    if motion is not None and motion.std is not None:  # driven: the motion is measured too
        out.append(_motion_line(motion))
    pre = res.prefilter
    if pre is not None and pre.windows:
        out.append(f"Filter read in the records: {pre.note}; the fits see the model through it")
    if enc:
        counts = enc.counts_per_revolution
        what = f"{counts} counts per revolution, " if counts else ""
        used = " (the noise floor)" if nz is not None and nz.method == "quantization" else ""
        out.append(
            f"Encoder: {what}step {enc.step:.6g}, quantization floor q/sqrt(12) = "
            f"{enc.floor:.3g}{used}"
        )
    return out


def _motion_line(motion: MotionNoiseRecord) -> str:
    """``Motion noise: ...``: its level, how it was estimated, how the motion was estimated
    (and the first reason a run's harmonic series was not used)."""
    kinds: dict[str, int] = {}
    notes = []
    for name, est in motion.estimates.items():
        kinds[est.get("estimate")] = kinds.get(est.get("estimate"), 0) + 1
        if est.get("estimate") in ("local", "smoother") and est.get("note"):
            notes.append(f"run {name}: {est['note']}")
    line = f"Motion noise: {motion.std:.3g} from {motion.method}"
    if kinds:
        how = ", ".join(f"{n} {k}" for k, n in kinds.items())
        carried = (
            "not propagated: the declared filter hides the motion's noise"
            if set(kinds) == {"filter"}
            else "propagated to the intervals"
        )
        line += f"; motion estimated by {how} (its errors {carried})"
    if notes:
        more = f" (and {len(notes) - 1} more)" if len(notes) > 1 else ""
        line += f"; {notes[0]}{more}"
    return line


def report(res: Results) -> str:
    """A readable fit report: discovered equations, family table, parameters, effects."""
    disc = res.discovered
    noise = res.noise_std if res.noise_std is not None else float("nan")
    out = [
        f"hystdisc {res.version} — {res.input} ({res.experiment}, "
        f"{len(res.runs)} runs, noise {noise:.3g})",
        *measurement_lines(res),
        "",
        f"Discovered structure: {disc.name if disc else ''}",
        disc.equations if disc else "",
        "",
        "Families (output error; * selected):",
        family_table(res),
        *failed_lines(res),
    ]
    if res.equal_fits:
        out.append(
            f"Note: {', '.join(res.equal_fits)} fit as well as {res.family} "
            f"(BIC within 6); the data cannot tell them apart."
        )
    cd = res.current_dependence
    if cd and not cd.identifiable:
        out.append(f"Current dependence: not identifiable: {cd.note}")
    sel = "declared" if res.declared else "selected"
    out += ["", f"{sel.capitalize()} family: {res.family}", parameter_table(res)]
    f = res.families[res.family]
    if f.missing_terms or f.extra_terms:
        out.append(
            f"  vs discovered: lacks {f.missing_terms or 'nothing'}, "
            f"adds {f.extra_terms or 'nothing'}"
        )
    out += effects_table(res)
    out += _residual_lines(res)
    out += outlier_lines(res)
    return "\n".join(out)


def failed_lines(res: Results) -> list[str]:
    """The tasks that failed and were dropped, one line each (none: nothing).

    Examples
    --------
    >>> from hystdisc.results import Results
    >>> r = Results(failed={"spencer": "the simulation diverged at every start"})
    >>> for line in failed_lines(r):
    ...     print(line)
    Failed and dropped (the run went on without them):
      spencer: the simulation diverged at every start
    """
    if not res.failed:
        return []
    return ["Failed and dropped (the run went on without them):"] + [
        f"  {name}: {reason}" for name, reason in res.failed.items()
    ]


def outlier_lines(res: Results) -> list[str]:
    """The isolated glitches left out of the fit (empty for a file without the key).

    Examples
    --------
    >>> from hystdisc.results import Results
    >>> from hystdisc.results.sections import OutliersRecord
    >>> r = Results(outliers=OutliersRecord.from_dict({"count": 1, "runs": ["2"],
    ...     "left_out": True, "items": [{"run": "2", "signal": "theta", "sample": 7,
    ...     "t": 0.007, "size": 0.05}]}))
    >>> for line in outlier_lines(r)[1:]:
    ...     print(line)
    Outliers: 1 isolated glitch left out of the fit (run 2)
      run 2, theta, t = 0.007 s (sample 7): +0.05
    """
    o = res.outliers
    if not o:
        return []
    n = int(o.count)
    if n == 0:
        return ["", f"Outliers: none (screen at {o.threshold_sigma or 7:g} noise std)"]
    what = "left out of the fit" if o.left_out else "reported only"
    runs = ", ".join(str(r) for r in o.runs)
    out = ["", f"Outliers: {n} isolated glitch{'' if n == 1 else 'es'} {what} (run {runs})"]
    items = o.items
    for g in items[:20]:
        out.append(f"  run {g.run}, {g.signal}, t = {g.t:.6g} s (sample {g.sample}): {g.size:+.4g}")
    if len(items) > 20:
        out.append(f"  ... and {len(items) - 20} more (results.json, key outliers)")
    return out


def html_summary(res: Results) -> str:
    """The notebook display: discovered structure, family and parameter tables, effects."""
    e = html.escape
    rows = "".join(
        f"<tr><td>{e(n)}{' &#9733;' if n == res.family else ''}</td><td>{f.n_params}</td>"
        f"<td>{f.rms:.4g}</td><td>{f.bic:.1f}</td>"
        f"<td>{'' if f.heldout_rms is None else format(f.heldout_rms, '.4g')}</td></tr>"
        for n, f in res.families.items()
    )
    f = res.families[res.family]
    prow = "".join(
        f"<tr><td>{e(k)}</td><td>{p.value:.6g}</td><td>"
        + (f"[{_num(p.ci95[0], '.5g')}, {_num(p.ci95[1], '.5g')}]" if p.ci95 else "")
        + f"</td><td>{'' if p.identifiable else 'not identifiable'}</td></tr>"
        for k, p in f.parameters.items()
    )
    disc = res.discovered
    eq = e(disc.equations if disc else "").replace("\n", "<br>")
    eff = "".join(
        f"<li>{e(x.name)}: RMS {x.rms_before:.4g} &rarr; {x.rms_after:.4g}</li>"
        for x in res.effects
    )
    eff_html = f"<b>Accepted effects</b><ul>{eff}</ul>" if eff else "<i>No effect accepted.</i>"
    if res.unexplained:
        eff_html += f"<br><b>Unexplained:</b> {e(str(res.unexplained_text or ''))}"
    lib = open_library_lines(res.open_library)
    if lib:
        eff_html += "<br>" + "<br>".join(e(x) for x in lib)
    cd = res.current_dependence
    if cd and not cd.identifiable:
        eff_html += f"<br><b>Current dependence not identifiable:</b> {e(cd.note)}"
    if res.failed:
        items = "".join(f"<li>{e(k)}: {e(v)}</li>" for k, v in res.failed.items())
        eff_html += f"<br><b>Failed and dropped</b><ul>{items}</ul>"
    return (
        f"<div><b>hystdisc</b> — {e(str(res.input))} ({e(str(res.experiment))})<br>"
        f"<b>Discovered:</b> {e(disc.name if disc else '')}<br><code>{eq}</code>"
        "<table><tr><th>family</th><th>params</th><th>RMS</th><th>BIC</th><th>held-out RMS</th>"
        f"</tr>{rows}</table><b>{e(res.family)}</b> ({e(f.normalization)})"
        f"<table><tr><th>parameter</th><th>value</th><th>95 % interval</th><th></th></tr>{prow}"
        f"</table>{eff_html}</div>"
    )
