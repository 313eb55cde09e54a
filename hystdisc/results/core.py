"""The result of a discovery: the ``results.json`` contract, a fit report, notebook display.

Follows lmfit's result objects: :meth:`Results.summary` returns the contract as a dict,
:meth:`Results.save`/:meth:`Results.load` round-trip JSON, :meth:`Results.report` is a
readable fit report with intervals, and ``_repr_html_`` renders tables in a notebook.

Examples
--------
>>> r = Results({"version": "0", "input": "x.csv", "experiment": "release", "noise_std": 0.001,
...              "terms": {"torque": ["z"], "hysteresis": []}, "family": "dahl", "families": {},
...              "effects": [], "unexplained": False, "residual": {}})
>>> r.family
'dahl'
>>> Results.from_json(r.to_json()).summary() == r.summary()
True
"""

from __future__ import annotations

import html
import json
import math
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc import __version__
from hystdisc.errors import HystdiscError
from hystdisc.models import FAMILIES, TermModel

SIG_DIGITS = 10


def _round(x: Any) -> Any:
    """Round floats to SIG_DIGITS significant digits (stable bytes); NaN/inf become None."""
    if isinstance(x, dict):
        return {k: _round(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_round(v) for v in x]
    if isinstance(x, (np.floating, float)):
        x = float(x)
        if not math.isfinite(x):
            return None
        return float(f"{x:.{SIG_DIGITS}g}")
    if isinstance(x, np.integer):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def term_model_to_dict(tm: TermModel) -> dict:
    return {"torque": dict(tm.torque), "hysteresis": dict(tm.hysteresis), "n": tm.n, "J": tm.J}


def term_model_from_dict(d: dict) -> TermModel:
    return TermModel(
        {k: float(v) for k, v in d.get("torque", {}).items()},
        {k: float(v) for k, v in d.get("hysteresis", {}).items()},
        float(d.get("n", 1.0)),
        float(d.get("J", 1.0)),
    )


class Results:
    """Discovery result: attribute access to the ``results.json`` keys."""

    def __init__(self, data: dict) -> None:
        self._data = _round(data)

    def __getattr__(self, name: str) -> Any:
        data = self.__dict__.get("_data", {})
        if name in data:
            return data[name]
        raise AttributeError(name)

    def summary(self) -> dict:
        """The ``results.json`` contract as a plain dict."""
        return json.loads(json.dumps(self._data))

    def to_json(self) -> str:
        return json.dumps(self._data, indent=1, sort_keys=False) + "\n"

    @classmethod
    def from_json(cls, text: str) -> Results:
        return cls(json.loads(text))

    def save(self, path: str | Path, force: bool = False) -> Path:
        """Write ``results.json`` atomically (refuses to overwrite without ``force``)."""
        from hystdisc.data import atomic_write_text

        return atomic_write_text(path, self.to_json(), force=force)

    @classmethod
    def load(cls, path: str | Path) -> Results:
        """Read a ``results.json``; a malformed file is a one-line HystdiscError."""
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
            raise HystdiscError(
                f"{p}: not a readable results.json ({msg}); fix: rerun hystdisc discover --json"
            ) from None
        if (
            not isinstance(data, dict)
            or any(k not in data for k in ("families", "model", "experiment"))
            or not isinstance(data["families"], dict)
            or not isinstance(data["model"], dict)
        ):
            raise HystdiscError(
                f"{p}: not a hystdisc results.json (no 'families'/'model'/'experiment' keys); fix: give the file "
                "written by hystdisc discover --json"
            )
        try:
            return cls(data)
        except RecursionError:  # _round() recurses once per nesting level
            raise HystdiscError(
                f"{p}: not a readable results.json (nested too deeply); fix: rerun hystdisc "
                "discover --json"
            ) from None

    def term_model(self, family: str | None = None) -> TermModel:
        """The fitted model in term form (final model with effects, or one family's fit)."""
        try:
            if family is None:
                tm = term_model_from_dict(self._data["model"])
            else:
                tm = term_model_from_dict(self._data["families"][family]["term_model"])
            values = [*tm.torque.values(), *tm.hysteresis.values(), tm.n, tm.J]
            if not all(math.isfinite(v) for v in values):
                raise ValueError("a coefficient is not finite")
            return tm
        except (KeyError, TypeError, ValueError, AttributeError, OverflowError) as exc:
            raise HystdiscError(
                f"results: no usable model for {family or 'the selected family'} ({exc}); fix: "
                "rerun hystdisc discover"
            ) from None

    # ----------------------------------------------------------------- text
    def family_table(self) -> str:
        rows = [
            f"{'family':<14}{'params':>7}{'RMS':>12}{'RMS/noise':>10}{'BIC':>14}{'held-out RMS':>14}"
        ]
        noise = self._data.get("noise_std") or float("nan")
        for name, f in self._data["families"].items():
            mark = " *" if name == self._data.get("family") else ""
            ho = f.get("heldout_rms")
            rows.append(
                f"{name + mark:<14}{f['n_params']:>7d}{f['rms']:>12.4g}{f['rms'] / noise:>10.3f}"
                f"{f['bic']:>14.1f}{(f'{ho:.4g}' if ho is not None else '-'):>14}"
            )
        return "\n".join(rows)

    def parameter_table(self, family: str | None = None) -> str:
        fam = family or self._data["family"]
        f = self._data["families"][fam]
        rows = [
            f"{fam} parameters ({f.get('normalization', '')})",
            f"  {'name':<10}{'value':>13}   {'95 % interval':<30}",
        ]
        for k, p in f["parameters"].items():
            lo, hi = p["ci95"] if p.get("ci95") else (None, None)
            ci = f"[{lo:.5g}, {hi:.5g}]" if lo is not None else "-"
            flag = "" if p.get("identifiable", True) else "  not identifiable"
            rows.append(f"  {k:<10}{p['value']:>13.6g}   {ci:<30}{flag}")
        for note in f.get("notes", []):
            rows.append(f"  note: {note}")
        return "\n".join(rows)

    def effects_table(self) -> list[str]:
        """Lines of the closing-the-loop table: every refitted effect, then the verdict.

        Returns
        -------
        list of str
            Empty when the loop did not run.
        """
        d = self._data
        if "diagnosis" not in d and not d.get("effects_tried"):
            return []

        def num(x, fmt):
            return "-" if x is None else format(x, fmt)

        out = ["", "Closing the loop (residual -> catalogued effects):"]
        tried = d.get("effects_tried") or []
        if tried:
            out.append(
                f"  {'effect':<20}{'evidence':>9}{'(eq.)':>8}  {'RMS before -> after':<24}"
                f"{'BIC change':>11}  verdict"
            )
            for e in tried:
                before, after = e.get("rms_before"), e.get("rms_after")
                dbic = (
                    e["bic_after"] - e["bic_before"]
                    if e.get("bic_after") is not None and e.get("bic_before") is not None
                    else None
                )
                verdict = (
                    "accepted"
                    if e.get("accepted")
                    else ("removed" if e.get("removed") else "rejected")
                )
                if not e.get("accepted") and e.get("note"):
                    verdict += f" ({e['note']})"
                out.append(
                    f"  {e['name']:<20}{num(e.get('evidence'), '.3f'):>9}"
                    f"{num(e.get('evidence_eq'), '.3f'):>8}  "
                    f"{num(before, '.4g') + ' -> ' + num(after, '.4g'):<24}"
                    f"{num(dbic, '.1f'):>11}  {verdict}"
                )
        names = {e["name"] for e in tried}
        diag = d.get("diagnosis") or []
        rest = [c for c in (diag[0]["candidates"] if diag else []) if c["name"] not in names]
        if rest:
            out.append(
                "  not refitted (too little evidence): "
                + ", ".join(f"{c['name']} {num(c.get('evidence'), '.2g')}" for c in rest)
            )
        for sk in d.get("effects_skipped") or []:
            out.append(f"  not applicable: {sk['name']} ({sk['reason']})")
        if d.get("effects"):
            out.append("  Accepted effects (final fit, 95 % intervals):")
            for e in d["effects"]:
                ps = ", ".join(
                    f"{k} = {p['value']:.5g} [{num(p['ci95'][0], '.5g')}, {num(p['ci95'][1], '.5g')}]"
                    for k, p in e["parameters"].items()
                )
                out.append(
                    f"    {e['name']} ({', '.join(e['terms'])}): {ps}; RMS "
                    f"{e['rms_before']:.4g} -> {e['rms_after']:.4g}"
                )
        else:
            out.append("  No catalogued effect improves the model.")
        fin = d.get("final")
        if fin:
            noise = d.get("noise_std")
            ratio = f" ({fin['rms'] / noise:.2f}x the noise)" if noise else ""
            out.append(
                f"  Final model: {' + '.join([fin['family'], *fin.get('effects', [])])}, "
                f"RMS {fin['rms']:.4g}{ratio}, BIC {fin['bic']:.1f}"
            )
        return out

    def report(self) -> str:
        """A readable fit report: discovered equations, family table, parameters, effects."""
        d = self._data
        out = [
            f"hystdisc {d.get('version', '')} — {d.get('input', '')} ({d.get('experiment')}, "
            f"{len(d.get('runs', []))} runs, noise {d.get('noise_std', float('nan')):.3g})",
            "",
            f"Discovered structure: {d.get('discovered', {}).get('name', '')}",
            d.get("discovered", {}).get("equations", ""),
            "",
            "Families (output error; * selected):",
            self.family_table(),
        ]
        if d.get("equal_fits"):
            out.append(
                f"Note: {', '.join(d['equal_fits'])} fit as well as {d['family']} "
                f"(BIC within 6); the data cannot tell them apart."
            )
        sel = "declared" if d.get("declared") else "selected"
        out += ["", f"{sel.capitalize()} family: {d['family']}", self.parameter_table()]
        f = d["families"][d["family"]]
        if f.get("missing_terms") or f.get("extra_terms"):
            out.append(
                f"  vs discovered: lacks {f.get('missing_terms') or 'nothing'}, "
                f"adds {f.get('extra_terms') or 'nothing'}"
            )
        out += self.effects_table()
        res = d.get("residual", {})
        if res:
            wp = res.get("whiteness_p")
            ratio = res.get("rms_over_noise")
            verdict = "white" if wp is not None and wp >= 0.01 else "not white"
            out += [
                "",
                f"Residual: RMS {res.get('rms', float('nan')):.4g}"
                + (f" ({ratio:.2f}x the noise)" if ratio is not None else "")
                + f", Ljung-Box whiteness p = {wp if wp is None else format(wp, '.3g')} "
                + f"({verdict})"
                + (
                    f", dominant {res['dominant_hz']:.3g} Hz"
                    if res.get("dominant_hz") is not None
                    else ""
                ),
            ]
            if d.get("unexplained"):
                out.append(f"  Unexplained: {d.get('unexplained_text') or 'structure remains'}")
        return "\n".join(out)

    def __str__(self) -> str:
        return self.report()

    def __repr__(self) -> str:
        return f"<Results family={self._data.get('family')!r} input={self._data.get('input')!r}>"

    def _repr_html_(self) -> str:
        d = self._data
        e = html.escape
        rows = "".join(
            f"<tr><td>{e(n)}{' &#9733;' if n == d['family'] else ''}</td><td>{f['n_params']}</td>"
            f"<td>{f['rms']:.4g}</td><td>{f['bic']:.1f}</td>"
            f"<td>{'' if f.get('heldout_rms') is None else format(f['heldout_rms'], '.4g')}</td></tr>"
            for n, f in d["families"].items()
        )
        f = d["families"][d["family"]]
        prow = "".join(
            f"<tr><td>{e(k)}</td><td>{p['value']:.6g}</td><td>"
            + (f"[{p['ci95'][0]:.5g}, {p['ci95'][1]:.5g}]" if p.get("ci95") else "")
            + f"</td><td>{'' if p.get('identifiable', True) else 'not identifiable'}</td></tr>"
            for k, p in f["parameters"].items()
        )
        eq = e(d.get("discovered", {}).get("equations", "")).replace("\n", "<br>")
        eff = "".join(
            f"<li>{e(x['name'])}: RMS {x['rms_before']:.4g} &rarr; {x['rms_after']:.4g}</li>"
            for x in d.get("effects", [])
        )
        eff_html = f"<b>Accepted effects</b><ul>{eff}</ul>" if eff else "<i>No effect accepted.</i>"
        if d.get("unexplained"):
            eff_html += f"<br><b>Unexplained:</b> {e(str(d.get('unexplained_text', '')))}"
        return (
            f"<div><b>hystdisc</b> — {e(str(d.get('input')))} ({e(str(d.get('experiment')))})<br>"
            f"<b>Discovered:</b> {e(d.get('discovered', {}).get('name', ''))}<br><code>{eq}</code>"
            "<table><tr><th>family</th><th>params</th><th>RMS</th><th>BIC</th><th>held-out RMS</th>"
            f"</tr>{rows}</table><b>{e(d['family'])}</b> ({e(f.get('normalization', ''))})"
            f"<table><tr><th>parameter</th><th>value</th><th>95 % interval</th><th></th></tr>{prow}"
            f"</table>{eff_html}</div>"
        )


def _family_entry(name: str, fit, discovered_terms: dict) -> dict:
    fam = FAMILIES[name]
    params = {}
    for k, v in fit.params.items():
        lo, hi = fit.ci95.get(k, (float("nan"), float("nan")))
        params[k] = {"value": v, "ci95": [lo, hi], "identifiable": fit.identifiable.get(k, True)}
    # terms the fit really uses (a current term fixed at 0 for one current is not "added")
    tm = fit.term_model
    fam_t = {t for t in fam.torque_terms if tm.torque.get(t, 0.0) != 0.0}
    fam_h = {t for t in fam.hysteresis_terms if tm.hysteresis.get(t, 0.0) != 0.0}
    dt = set(discovered_terms["torque"]) - {"theta", "1"}
    dh = set(discovered_terms["hysteresis"])
    return {
        "parameters": params,
        "normalization": getattr(fit.par, "normalization", "") or fam.normalization,
        "rms": fit.rms,
        "bic": fit.bic,
        "heldout_rms": fit.heldout_rms,
        "n_params": fit.n_params,
        # hysteresis-side names are prefixed: theta_dot and |theta_dot|*z exist on both sides
        "missing_terms": sorted(dt - fam_t) + [f"dz/dt: {t}" for t in sorted(dh - fam_h)],
        "extra_terms": sorted(fam_t - dt) + [f"dz/dt: {t}" for t in sorted(fam_h - dh)],
        "notes": list(fit.notes),
        "term_model": term_model_to_dict(fit.term_model),
        "converged": fit.success,
    }


def build_results(disc, dataset) -> Results:
    """Assemble the ``results.json`` contract from a fitted :class:`~hystdisc.Discovery`."""
    from hystdisc.closing.diagnostics import residual_summary

    fams = {n: _family_entry(n, f, disc.terms_) for n, f in disc.family_fits_.items()}
    sel = disc.family_fits_[disc.family_]
    fs = float(np.median([r.fs for r in dataset.runs]))
    dfit = disc.discovered_fit_
    data = {
        "version": __version__,
        "input": dataset.source,
        "experiment": disc.experiment_,
        **({"input_hold": disc.input_hold} if disc.experiment_ == "forced" else {}),
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
        "model": term_model_to_dict(sel.term_model),
        "effects": [],
        "unexplained": False,
        # the residual over the samples the fit uses (driven start-up excluded)
        "residual": residual_summary(
            [r[m] for r, m in zip(sel.residuals, disc._fd.mask, strict=True)], fs, disc.noise_std_
        ),
        "runs": [
            {"name": r.name, "current": r.current, "samples": int(r.t.size)} for r in dataset.runs
        ],
        "seed": disc.seed,
    }
    return Results(data)
