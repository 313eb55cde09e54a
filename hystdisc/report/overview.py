"""Report sections: summary, data, measured against simulated output, hysteresis loops."""

from __future__ import annotations

import numpy as np

from hystdisc import __version__
from hystdisc.data import Dataset
from hystdisc.report.markup import (
    FAMILY_COLORS,
    currents_text,
    figure_legend,
    new_figure,
    num,
    thin,
)
from hystdisc.report.signals import final_fit, fit_label, fit_signals, fits_of, model_loops
from hystdisc.report.stages import residual_sentence


class OverviewSections:
    """The sections ``summary``, ``data``, ``time-series`` and ``loops`` (a mixin of
    :class:`~hystdisc.report.document.Document`)."""

    def summary(self) -> None:
        """The summary section: the selected family, its fit and the verdict."""
        d, disc = self.res, self.disc
        self.h2("summary")
        sel = "declared" if d.declared else "selected"
        rows = [
            ["input", d.input],
            ["experiment", d.experiment or ""],
            ["runs", f"{self.fd.n_runs} (currents {currents_text(self.fd.currents)} A)"],
            ["noise (estimated)", num(d.noise_std, ".3g")],
            *[[k.lower(), v] for k, _, v in (x.partition(": ") for x in d.measurement_lines())],
            ["discovered structure", d.discovered.name if d.discovered else ""],
            [f"{sel} family", d.family or ""],
        ]
        fin = d.final
        if fin:
            rows.append(
                ["final model", " + ".join([fin.family, *fin.effects]) + f", RMS {num(fin.rms)}"]
            )
        if d.residual:
            rows.append(["residual", residual_sentence(d.residual)])
        if d.unexplained:
            rows.append(["unexplained", d.unexplained_text or "structure remains"])
        cd = d.current_dependence
        if cd and not cd.get("identifiable", True):
            rows.append(["current dependence", f"not identifiable: {cd.get('note', '')}"])
        if d.outliers is not None:
            n = int(d.outliers.get("count", 0))
            rows.append(
                [
                    "outliers",
                    f"{n} isolated glitch{'' if n == 1 else 'es'} left out of the fit"
                    + (f" (runs {', '.join(d.outliers.get('runs', []))}; see data)" if n else ""),
                ]
            )
        rows.append(["hystdisc", d.version or __version__])
        self.table(["item", "value"], rows, left=2)
        if d.equal_fits:
            self.p(
                f"{', '.join(d.equal_fits)} fit as well as {d.family} (BIC within 6): "
                "the data cannot tell them apart; the simpler one is chosen."
            )
        self.html.append("<h3>Discovered equations</h3>")
        self.md += ["### Discovered equations", ""]
        self.pre(disc.equations())

    def data(self) -> None:
        """The data section: the runs, their currents and the noise."""
        fd, ds = self.fd, self.ds
        self.h2("data")
        meas = ds.measured()
        rows = []
        by_name = {r.name: r for r in ds.runs}
        for k, name in enumerate(fd.names):
            r = by_name.get(name)
            y = fd.y[k]
            rows.append(
                [
                    name,
                    f"{fd.currents[k]:g}",
                    r.n if r is not None else "–",
                    int(np.asarray(fd.mask[k]).sum()),
                    num(fd.t[k][-1] - fd.t[k][0], ".3g"),
                    num(1.0 / np.median(np.diff(fd.t[k])), ".4g"),
                    num(np.ptp(y), ".3g"),
                ]
            )
        self.p(
            f"{len(ds.runs)} {ds.experiment} runs from {ds.source}; measured signal: {meas}; "
            f"estimated measurement noise {num(self.disc.noise_std_, '.3g')} (data units)."
            + (
                " Release runs are trimmed where the motion has died below the noise."
                if self.released
                else ""
            )
        )
        self.table(
            ["run", "current [A]", "samples", "fitted", "duration [s]", "fs [Hz]", f"{meas} range"],
            rows,
        )
        out = (self.res.outliers or {}).get("items", [])
        if out:
            self.p(
                f"{len(out)} isolated glitch{'' if len(out) == 1 else 'es'} (samples that disagree "
                "with their neighbours while the neighbours agree with each other) were left out "
                "of every fit and replaced by their local prediction for stage 1:"
            )
            self.table(
                ["run", "signal", "t [s]", "sample", "size", "residual of the model"],
                [
                    [
                        g["run"],
                        g["signal"],
                        num(g["t"], ".6g"),
                        g["sample"],
                        num(g["size"], ".3g"),
                        "–" if g.get("residual") is None else num(g["residual"], ".3g"),
                    ]
                    for g in out
                ],
            )
        from hystdisc.plotting import plot_runs

        fig, axes = new_figure(1, 1, 10, 3.6)
        shown = Dataset([ds.runs[k] for k in range(len(ds.runs))], ds.experiment, ds.source)
        plot_runs(shown, ax=axes[0, 0])
        axes[0, 0].set_title("measured runs", fontsize="medium")
        self.figure(fig)

    def time_series(self) -> None:
        """The time-series section: measured and simulated output of the shown runs."""
        from hystdisc.plotting import plot_fit

        self.h2("time-series")
        if self.exp.motion_imposed:
            start = " (on the recorded motion)"
        elif self.exp.has_input:
            start = " (from their fitted initial state, driven by the recorded input)"
        else:
            start = " (release runs from their fitted initial angle)"
        self.p(
            f"Output-error fits: every run simulated with each fitted model{start}, dashed, "
            "over the measurement (grey); right, each model's residual (simulated - "
            "measured)." + self.shown_note(),
            md=False,
        )
        self.md += ["Figures: see the HTML report.", ""]
        signals = fit_signals(self.disc, self.shown)
        if not signals:
            return
        ylabel = "torque" if self.units == "torque" else "angle [rad]"
        # worst fit first, so that the best is drawn on top
        fits = fits_of(self.disc)
        keys = sorted(signals[0]["predictions"], key=lambda k: -float(fits[k].rms))
        n = len(signals)
        fig, axes = new_figure(n, 2, 11, 1.0 + 2.2 * n, width_ratios=[2.2, 1])
        for row, s in enumerate(signals):
            k = thin(len(s["t"]))
            for j, key in enumerate(keys):
                plot_fit(
                    s["t"][k],
                    s["measured"][k],
                    s["predictions"][key][k],
                    ax=axes[row, 0],
                    residual_ax=axes[row, 1],
                    label=fit_label(self.disc, key),
                    ylabel=ylabel,
                    title=f"run {s['name']}, {s['current']:g} A",
                    draw_measured=j == 0,
                    legend=False,
                    color=FAMILY_COLORS.get(key),
                )
        figure_legend(fig, axes[0, 0])
        self.figure(fig)

    def loops(self) -> None:
        """The loops section: torque against motion, measured and simulated."""
        from hystdisc.plotting import loops_figure

        self.h2("loops")
        if self.exp.motion_imposed:
            text = (
                "Measured torque against the smoothed imposed velocity and displacement "
                "(grey), with the torque each fitted model simulates on the same motion."
            )
        else:
            eq = "-theta'' - k_s theta" if self.released else "u - J theta'' - k_s theta"
            text = (
                f"The damper torque is not measured in a {self.fd.experiment} test: grey is "
                f"the torque the rig equation implies, {eq} from the smoothed angle (k_s"
                f"{'' if self.released else ' and J'} of the "
                f"{'final' if final_fit(self.disc) else 'selected'} fit); dashed, each fitted "
                "model's damper torque against its own simulated velocity and angle."
            )
        self.p(text + self.shown_note(), md=False)
        self.md += ["Figures: see the HTML report.", ""]
        loops = model_loops(self.disc, self.shown)
        n = len(self.shown)
        fig, axes = new_figure(n, 2, 11, 0.6 + 3.0 * n)
        for row, r in enumerate(self.shown):
            items = []
            for lp in loops:
                if lp["run"] != r:
                    continue
                k = thin(len(lp["t"]))
                lp = {
                    **lp,
                    **{q: np.asarray(lp[q])[k] for q in ("t", "theta", "theta_dot", "torque")},
                }
                if lp["kind"] == "data":
                    lp["label"] = "data"
                items.append(lp)
            loops_figure(items, axes=list(axes[row]), legend=False)
            axes[row, 0].set_title(
                f"run {self.fd.names[r]}, {self.fd.currents[r]:g} A", fontsize="medium"
            )
        figure_legend(fig, axes[0, 0])
        self.figure(fig)
