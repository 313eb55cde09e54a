"""Report sections: stage 1's term selection and the closing loop (effects tried, the
residual spectrum)."""

from __future__ import annotations

import numpy as np

from hystdisc.registry import effect_names, get_effect
from hystdisc.report.markup import ci_text, color_of, new_figure, num
from hystdisc.results import ResidualSummary
from hystdisc.results.text import redundant_sentence


class StageSections:
    """The sections ``selection`` and ``closing`` (a mixin of
    :class:`~hystdisc.report.document.Document`)."""

    def selection(self) -> None:
        """The selection section: stage 1's threshold path and inclusion probabilities."""
        from hystdisc.plotting import plot_inclusion, plot_selection_path

        st = self.rd.stage1
        self.h2("selection")
        self.p(
            "Stage 1 (equation error): for each hysteresis shape the shape constants are "
            "found by variable projection and the torque-side terms by sequentially "
            "thresholded least squares (STLSQ) along a threshold path scored by BIC; the "
            "shape with the lowest BIC is the discovered structure."
        )
        rows, sel = [], []
        for i, row in enumerate(st["rows"]):
            chosen = row["shape"] == st["selected"]
            if chosen:
                sel.append(i)
            rows.append(
                [
                    row["shape"] + (" *" if chosen else ""),
                    ", ".join(row["terms"]),
                    ", ".join(f"{v:.4g}" for v in row["s"]) or "–",
                    num(row["bic"], ".1f"),
                ]
            )
        self.table(
            ["hysteresis shape", "selected torque terms", "shape constants", "BIC"],
            rows,
            left=2,
            sel=sel,
        )
        if st["path"]:
            fig, axes = new_figure(2, 1, 10, 6.2, sharex=True, height_ratios=[3, 1.4])
            plot_selection_path(
                st["path"],
                ax=list(axes[:, 0]),
                title=f"STLSQ path, hysteresis shape '{st['shape']}'",
            )
            self.figure(
                fig,
                "Each coefficient divided by its largest magnitude along the path; a term "
                "leaves the model where its curve drops to 0. Dashed red: the threshold with "
                "the lowest BIC (the selected model).",
            )
        if st["inclusion"]:
            fig, axes = new_figure(1, 1, 7, 0.9 + 0.35 * len(st["inclusion"]))
            plot_inclusion(st["inclusion"], ax=axes[0, 0], title="ensemble inclusion")
            self.figure(fig)
            self.table(
                ["term", "inclusion probability"],
                [[k, num(v, ".2f")] for k, v in st["inclusion"].items()],
            )

    def closing(self) -> None:
        """The closing section: the effects tried and the residual's spectrum."""
        from hystdisc.plotting import plot_residual_spectrum

        d = self.res
        self.h2("closing")
        ran = d.closed_loop
        if not ran:
            self.p("The closing loop was not run (close_loop=False or --no-effects).")
        tried = d.effects_tried or []
        if tried:
            rows = []
            for e in tried:
                dbic = (
                    e.bic_after - e.bic_before
                    if e.bic_after is not None and e.bic_before is not None
                    else None
                )
                verdict = "accepted" if e.accepted else "rejected"
                if not e.accepted and e.note:
                    verdict += f" ({e.note})"
                rows.append(
                    [
                        e.name,
                        _effect_terms(e.name),
                        num(e.evidence, ".3g"),
                        num(e.rms_before),
                        num(e.rms_after),
                        num(dbic, ".1f"),
                        num(e.heldout_rms_before),
                        num(e.heldout_rms_after),
                        verdict,
                    ]
                )
            self.p(
                "An effect is accepted only if it lowers BIC, its parameter is significant, it "
                "removes a tenth of the residual's excess over the noise, it lowers the "
                "held-out RMS (data the refit did not see) and the model stays physical."
            )
            self.table(
                [
                    "effect tried",
                    "terms",
                    "evidence",
                    "RMS before",
                    "RMS after",
                    "ΔBIC",
                    "held-out before",
                    "held-out after",
                    "verdict",
                ],
                rows,
                left=2,
            )
        elif ran:
            self.p("No catalogued effect had enough evidence to be refitted.")
        rest = d.not_refitted()
        weak = [c for c in rest if not c.not_refitted]
        if weak:
            self.p(
                "Not refitted (too little evidence): "
                + ", ".join(f"{c.name} {num(c.evidence, '.2g')}" for c in weak)
                + "."
            )
        for c in rest:
            if c.not_refitted:
                self.p(f"Not refitted: {c.name} ({c.not_refitted}).")
        for sk in d.effects_skipped or []:
            self.p(f"Not applicable: {sk.name} ({sk.reason}).")
        if d.effects:
            self.html.append("<h3>Accepted effects</h3>")
            self.md += ["### Accepted effects", ""]
            rows = [
                [
                    e.name,
                    ", ".join(e.terms),
                    k,
                    num(p.value, ".5g"),
                    ci_text(p.ci95, ".4g"),
                    num(e.rms_before),
                    num(e.rms_after),
                    num(e.heldout_rms_before),
                    num(e.heldout_rms_after),
                ]
                for e in d.effects
                for k, p in e.parameters.items()
            ]
            self.table(
                [
                    "effect",
                    "terms",
                    "parameter",
                    "value",
                    "95 % interval",
                    "RMS before",
                    "RMS after",
                    "held-out before",
                    "held-out after",
                ],
                rows,
                left=3,
            )
        else:
            self.p("No effect was accepted.")
        res = d.residual
        if res:
            self.p("Final residual: " + residual_sentence(res) + ".")
        if d.unexplained:
            self.p("Unexplained: " + (d.unexplained_text or "structure remains"), cls="bad")
        lib = d.open_library
        if lib and lib.get("terms"):
            self.p(
                f"The residual regressed on the open library ({lib['candidates']} candidate "
                f"forces, stability selection): the stable terms explain "
                f"{100 * lib['explained']:.0f} % of it. Evidence, not a verdict: a term is "
                "part of the model only once a refit predicts held-out tests better."
            )
            self.table(
                ["term", "coefficient", "inclusion", "catalogued effect"],
                [
                    [
                        t["name"],
                        num(t["coefficient"], ".4g"),
                        num(t["inclusion"], ".2f"),
                        t["effect"] or "– (discovered)",
                    ]
                    for t in lib["terms"]
                ],  # fmt: skip
                left=1,
            )
            if lib.get("equation"):
                self.p("Discovered: " + lib["equation"])
            h = lib.get("heldout")
            if h and h.get("before") is not None and h.get("after") is not None:
                self.p(
                    "With the stable terms, each test condition left out and the model "
                    "refitted with them (one Gauss-Newton step from its optimum), the held-"
                    f"out RMS goes {num(h['before'], '.4g')} -> {num(h['after'], '.4g')}, "
                    f"lower in {h['lower']} of {h['folds']} conditions. The term set was "
                    "chosen on all the data; the model's own prediction does not include it."
                )
            r = lib.get("refit")
            if r:
                self._library_refit(r)
        self._spectrum_figure(plot_residual_spectrum)
        self._residual_map()

    def _library_refit(self, r: dict) -> None:
        """The open library's terms refitted into the model (``open_library.refit``)."""
        held = "the held-out error is not available"
        if r.get("heldout_before") is not None and r.get("heldout_after") is not None:
            held = (
                f"the held-out RMS goes {num(r['heldout_before'], '.4g')} -> "
                f"{num(r['heldout_after'], '.4g')}, lower in {r['lower']} of "
                f"{len(r['fold_after'])} conditions"
            )
        verdict = "Accepted" if r.get("accepted") else "Not accepted"
        self.p(
            f"Refitted into the model by output error ({r['equation']}): RMS "
            f"{num(r['rms_before'], '.4g')} -> {num(r['rms_after'], '.4g')}; each condition "
            f"left out and both models refitted on the others, {held}. {verdict}: "
            f"{r.get('note', '')}."
        )
        if r.get("redundant"):
            self.p(redundant_sentence(r["redundant"]).capitalize() + ".")

    def _residual_map(self) -> None:
        """Where the model misses: the residual against displacement and velocity."""
        from hystdisc.plotting.residuals import plot_residual_map

        runs, after = self.rd.runs, self.rd.spectrum.get("after")
        if "theta" not in runs or after is None:
            return  # a report written before the map
        disp, vel = [], []
        for t, x, m in zip(runs["t"], runs["theta"], runs["mask"], strict=True):
            x = np.asarray(x, dtype=float)
            disp.append(x[m])
            vel.append(np.gradient(x, np.asarray(t, dtype=float))[m])
        fig, axes = new_figure(1, 2, 10, 3.6)
        plot_residual_map(
            after["residuals"], disp, vel, runs["currents"], self.rd.noise_std, axes=axes[0]
        )
        self.figure(
            fig,
            "Where the model misses: the residual of "
            + after["label"]
            + " against displacement and velocity, its mean in bins per current; grey: "
            "the measurement's floor (one standard deviation).",
        )

    def _spectrum_figure(self, plot_residual_spectrum) -> None:
        sp, res = self.rd.spectrum, self.res.residual
        fig, axes = new_figure(1, 1, 9, 3.8)
        ax = axes[0, 0]
        before = sp.get("before")
        if before is not None:
            plot_residual_spectrum(
                before["residuals"],
                sp["fs"],
                ax=ax,
                label=before["label"],
                color=color_of(before["key"]),
                alpha=0.6,
            )
        after = sp["after"]
        plot_residual_spectrum(
            after["residuals"],
            sp["fs"],
            ax=ax,
            noise_std=self.rd.noise_std,
            dominant_hz=res.dominant_hz if res else None,
            label=after["label"],
            color=color_of(after["key"]),
        )
        ax.set_title(
            f"residual spectrum (Welch, averaged over runs); whiteness p = "
            f"{num(res.whiteness_p if res else None, '.3g')}",
            fontsize="medium",
        )
        self.figure(
            fig,
            "Dashed grey: the level of white noise with the estimated measurement noise; "
            "dotted red: the dominant frequency of a structured residual.",
        )


def _effect_terms(name: str) -> str:
    """The torque terms of a catalogued effect ("–" for a name that is none)."""
    return ", ".join(get_effect(name).terms) if name in effect_names() else "–"


def residual_sentence(res: ResidualSummary) -> str:
    """The final residual in one line: RMS, whiteness, dominant frequency."""
    wp = res.whiteness_p
    white = wp is not None and wp >= 0.01
    out = f"RMS {num(res.rms)}"
    if res.rms_over_noise is not None:
        out += f" ({num(res.rms_over_noise, '.2f')}x the noise)"
    if res.whiteness_test == "noise spectrum":
        verdict = "as the noise" if white else "above the noise"
        out += f", whiteness against the noise's own spectrum p = {num(wp, '.3g')} ({verdict})"
    else:
        out += f", Ljung-Box whiteness p = {num(wp, '.3g')} ({'white' if white else 'not white'})"
    if res.dominant_hz is not None:
        out += f", dominant frequency {num(res.dominant_hz, '.3g')} Hz"
    return out
