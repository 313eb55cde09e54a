"""Report sections: family comparison, parameters with intervals, the seed's term
correspondence."""

from __future__ import annotations

from hystdisc.registry import family_names, get_family
from hystdisc.report.markup import ci_text, esc, md_cell, md_line, new_figure, num
from hystdisc.results import FamilyResult

#: The seed's section 5: the torque terms compared across the families (label, term); each
#: family declares the parameter that multiplies each term
#: (:attr:`~hystdisc.models.Family.correspondence`; a term it lacks is 0).
CORRESPONDENCE = (
    ("θ̇ (viscous)", "theta_dot"),
    ("z (hysteretic, 0 A)", "z"),
    ("i·z (hysteretic, per A)", "i*z"),
    ("i·θ̇ (viscous, per A)", "i*theta_dot"),
    ("ż (LuGre sigma_1; term |θ̇|·z)", "|theta_dot|*z"),
)
#: Units of the rig's own parameters (the families' units come from their definitions).
RIG_UNITS = {"k_s": "N*m/rad per unit J", "J": "kg*m^2"}


class ComparisonSections:
    """The sections ``families``, ``parameters`` and ``correspondence`` (a mixin of
    :class:`~hystdisc.report.document.Document`)."""

    def families(self) -> None:
        """The families section: the comparison table and figure."""
        from hystdisc.plotting import plot_family_comparison

        d = self.res
        self.h2("families")
        fams = d.families
        noise = d.noise_std or float("nan")
        bmin = min(f.bic for f in fams.values() if f.bic is not None)
        rows, sel = [], []
        for i, (name, f) in enumerate(fams.items()):
            if name == d.family:
                sel.append(i)
            rows.append(
                [
                    name + (" *" if name == d.family else ""),
                    "–" if f.n_params is None else f.n_params,
                    num(f.rms),
                    num(f.rms / noise if f.rms is not None else None, ".3f"),
                    num(f.bic, ".1f"),
                    num(f.bic - bmin if f.bic is not None else None, ".1f"),
                    num(f.heldout_rms),
                    {True: "yes", False: "no"}.get(f.admissible, "–"),
                    ", ".join(f.missing_terms) or "–",
                    ", ".join(f.extra_terms) or "–",
                    "yes" if f.converged else "no",
                ]
            )
        self.p(
            "Every family fitted by output error over all runs jointly; * marks the "
            f"{'declared' if d.declared else 'selected'} family (among the physical "
            "families whose held-out RMS is within 10 % of the best, the lowest BIC; within "
            "2 of it, the fewest parameters). RMS in data units; held-out RMS: "
            + _heldout_text(d)
            + " 'physical': the model dissipates energy and its spring stiffens over twice "
            "the training envelope. 'lacks' lists discovered terms the family does not have, "
            "'adds' the family's terms that were not discovered."
            + (f" Selection: {d.selection_note}." if d.selection_note else "")
        )
        self.table(
            [
                "family",
                "params",
                "RMS",
                "RMS/noise",
                "BIC",
                "ΔBIC",
                "held-out RMS",
                "physical",
                "lacks",
                "adds",
                "converged",
            ],
            rows,
            left={0, 8, 9},
            sel=sel,
        )
        fig, axes = new_figure(1, 2, 11, 3.8)
        plot_family_comparison(fams, ax=list(axes[0]), noise_std=d.noise_std, selected=d.family)
        self.figure(fig, "Left: output-error RMS (and held-out RMS); right: BIC above the best.")

    def parameters(self) -> None:
        """The parameters section: each family's values with 95 % intervals."""
        d = self.res
        self.h2("parameters")
        self.p(
            "95 % intervals from the Jacobian at the optimum. A parameter is flagged as not "
            "identifiable when its interval is wider than its value or it lies along a "
            "near-singular direction of the Jacobian."
        )
        blocks = [(name, f, f.normalization) for name, f in d.families.items()]
        fin = d.final
        if fin and fin.effects:
            blocks.append((f"{fin.family} + {' + '.join(fin.effects)} (final)", fin, ""))
        for name, f, normalization in blocks:
            units = _units(name)
            title = name + (f" — {normalization}" if normalization else "")
            self.html.append(f"<h3>{esc(title)}</h3>")
            self.md += [f"### {md_cell(title)}", ""]
            rows = [
                [
                    k,
                    num(p.value, ".6g"),
                    ci_text(p.ci95, ".5g"),
                    units.get(k, ""),
                    "yes" if p.identifiable else "NO",
                ]
                for k, p in f.parameters.items()
            ]
            self.table(
                ["parameter", "value", "95 % interval", "unit", "identifiable"], rows, left={0, 3}
            )
            if f.notes:
                self.html.append("<ul>" + "".join(f"<li>{esc(n)}</li>" for n in f.notes) + "</ul>")
                self.md += [f"- {md_line(n)}" for n in f.notes] + [""]

    def correspondence(self) -> None:
        """The correspondence section: the families' parameters side by side."""
        d = self.res
        self.h2("correspondence")
        fams = d.families
        cols = [f for f in fams if f in family_names() and get_family(f).correspondence]
        self.p(
            "The seed's comparison of the torque equations (its section 5), filled with the "
            "fitted values and their 95 % intervals. The last column is the discovered "
            "structure in term form (coefficients of the torque terms on the discovered z "
            "scale). The z-multiplying parameters depend on each family's normalization of "
            "z (Dahl and Bouc-Wen: z saturates at 1; LuGre: z_sat = 1/(sigma_0 a_0)); the "
            "last two rows compare them on one scale, as torque at saturation."
        )
        tm = d.discovered.term_model if d.discovered else None
        disc_tq = tm.torque if tm is not None else {}
        header = ["torque term", *[_family_title(c) for c in cols], "discovered (term form)"]
        rows = []
        for label, term in CORRESPONDENCE:
            row = [label]
            for c in cols:
                row.append(_param_cell(fams[c], get_family(c).correspondence.get(term)))
            row.append(num(disc_tq.get(term), ".5g") if term in disc_tq else "0")
            rows.append(row)
        # scale-free: hysteretic torque at saturation
        for label, which in (
            ("torque at z saturation, 0 A", "a"),
            ("torque at z saturation, per A", "b"),
        ):
            row = [label]
            for c in cols:
                values = {k: p.value for k, p in fams[c].parameters.items() if p is not None}
                row.append(num(get_family(c).saturation_torque(values, which), ".5g"))
            row.append("–")
            rows.append(row)
        self.table(header, rows, left=len(header))


def _units(name: str) -> dict[str, str]:
    """Units of a family's parameters (none for a name that is no family) and the rig's."""
    units = {}
    if name in family_names():
        units = {p.name: p.unit for p in get_family(name).params}
    return {**units, **RIG_UNITS}


def _family_title(name: str) -> str:
    return get_family(name).title if name in family_names() else name


def _param_cell(entry: FamilyResult, pname: str | None) -> str:
    if pname is None:
        return "0"
    p = entry.parameters.get(pname)
    if p is None:
        return "–"
    flag = "" if p.identifiable else " (not identifiable)"
    return f"{pname} = {num(p.value, '.5g')} {ci_text(p.ci95, '.3g')}{flag}"


def _heldout_text(d) -> str:
    """How the held-out RMS was made, in one sentence."""
    cond = d.conditions or {}
    if cond.get("heldout_by") == "condition":
        return (
            f"each of the {cond.get('folds')} test conditions (runs sharing an input) "
            "predicted by the fit without it."
        )
    return "each run predicted by the fit without it (the runs share one test condition)."
