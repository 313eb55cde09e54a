"""The report's current-laws section: the seed's flowchart, level by level."""

from __future__ import annotations

from hystdisc.report.markup import ci_text, new_figure, num


class CurrentSections:
    """The ``current-laws`` section (a mixin of the report's :class:`Document`)."""

    def current_laws(self) -> None:
        """The current-laws section: the staged fit's per-level values and chosen laws
        (left out when the staged fit did not run)."""
        cl = self.res.current_laws
        if not cl:
            return
        self.h2("current-laws")
        levels = cl.levels
        self.p(
            f"{cl.family} fitted at each current level on its own, 0 A first and each "
            "next level started from the last one's optimum, with its current-dependent "
            "parameters fixed at 0: the passive parameters are the values at that level "
            "(95 % intervals). Each law parameter's law is chosen by leaving one level out: "
            "the law fitted to the other levels predicts the left-out value; the error is "
            "in units of that level's standard error, and the simplest law within 10 % of "
            "the best wins."
        )
        names = list(levels[0].parameters)
        rows = []
        for lv in levels:
            cells = []
            for k in names:
                p = lv.parameters[k]
                cells.append(f"{num(p['value'])} {ci_text(p['ci95'])}")
            rows.append([f"{lv.current:g}", str(len(lv.runs)), num(lv.rms), *cells])
        self.table(["current (A)", "runs", "RMS", *names], rows, left=0)
        laws = cl.laws
        cand = list(next(iter(laws.values())).heldout) if laws else []
        rows = []
        for d in laws.values():
            held = ["-" if d.heldout[c] is None else num(d.heldout[c]["z"]) for c in cand]
            coefs = ", ".join(f"{k} = {num(v)}" for k, v in d.coefficients.items())
            rows.append([d.parameter, *held, d.law, coefs])
        self.table(["parameter", *[f"held-out {c}" for c in cand], "chosen", "coefficients"], rows)
        if laws:
            from hystdisc.plotting import plot_current_laws

            fig, axes = new_figure(1, len(laws), 4.2 * len(laws), 3.4)
            plot_current_laws(cl, axes=list(axes[0]))
            self.figure(
                fig,
                "Each law parameter against the current: per-level values with 95 % "
                "intervals, the chosen law fitted to them and (dashed) the linear law.",
            )
        j, lin = cl.joint, cl.linear

        self.table(
            ["joint fit", "RMS", "held-out RMS", "BIC"],
            [
                ["chosen laws", num(j.rms), num(j.heldout_rms), num(j.bic)],
                ["linear laws", num(lin.rms), num(lin.heldout_rms), num(lin.bic)],
            ],
        )
        for note in cl.notes:
            self.p(note)
