"""Report sections: summary, data, measured against simulated output, hysteresis loops."""

from __future__ import annotations

import numpy as np

from hystdisc import __version__
from hystdisc.report.markup import (
    color_of,
    currents_text,
    esc,
    figure_legend,
    new_figure,
    num,
    thin,
)
from hystdisc.report.stages import residual_sentence


def failed_tasks(res) -> dict[str, str]:
    """The tasks of a fit that failed (``failed`` in ``results.json``): name -> reason.

    Read defensively: a record without the key, or with something else than a table
    under it, has none.

    Examples
    --------
    >>> from hystdisc.results import Results
    >>> failed_tasks(Results())
    {}
    >>> failed_tasks(Results.from_dict({"failed": {"lugre, start 2": "diverged"}}))
    {'lugre, start 2': 'diverged'}
    """
    failed = getattr(res, "failed", None) or (getattr(res, "extra", None) or {}).get("failed")
    if not isinstance(failed, dict):
        return {}
    return {str(k): str(v) for k, v in failed.items()}


class OverviewSections:
    """The sections ``summary``, ``failed``, ``data``, ``time-series`` and ``loops`` (a mixin of
    :class:`~hystdisc.report.document.Document`)."""

    def summary(self) -> None:
        """The summary section: the selected family, its fit and the verdict."""
        d = self.res
        self.h2("summary")
        sel = "declared" if d.declared else "selected"
        measurement = [
            [k.lower(), v] for k, _, v in (x.partition(": ") for x in d.measurement_lines())
        ]
        # the noise once: the line that says how it was estimated, else the number
        if not any("noise" in k for k, _ in measurement):
            measurement.insert(0, ["noise (estimated)", num(d.noise_std, ".3g")])
        rows = [
            ["input", d.input],
            ["experiment", d.experiment or ""],
            ["runs", f"{self.fd.n_runs} (currents {currents_text(self.fd.currents)} A)"],
            *measurement,
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
        failed = failed_tasks(d)
        if failed:
            n = len(failed)
            rows.append(["failed", f"{n} task{'' if n == 1 else 's'} failed (see Failed tasks)"])
        rows.append(["hystdisc", d.version or __version__])
        self.table(["item", "value"], rows, left=2)
        if d.equal_fits:
            self.p(
                f"{', '.join(d.equal_fits)} fit as well as {d.family} (BIC within 6): "
                "the data cannot tell them apart; the simpler one is chosen."
            )
        self.html.append("<h3>Discovered equations</h3>")
        self.md += ["### Discovered equations", ""]
        self.pre(self.rd.equations)

    def failed(self) -> None:
        """The failed tasks (families, starts, folds, effects), when any failed."""
        failed = failed_tasks(self.res)
        if not failed:
            return
        self.h2("failed")
        self.p(
            "These tasks failed; the run went on without them (a failed family is not in "
            "the comparison, a failed start or fold is left out of its fit or held-out "
            "error, a failed effect was not added):",
            cls="bad",
        )
        self.table(["task", "reason"], [[k, v] for k, v in failed.items()], left=2)

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
            f"estimated measurement noise {num(self.rd.noise_std, '.3g')} (data units)."
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
        out = self.res.outliers.items if self.res.outliers else []
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
                        g.run,
                        g.signal,
                        num(g.t, ".6g"),
                        g.sample,
                        num(g.size, ".3g"),
                        "–" if g.residual is None else num(g.residual, ".3g"),
                    ]
                    for g in out
                ],
            )
        from hystdisc.plotting import plot_runs

        fig, axes = new_figure(1, 1, 10, 3.6)
        plot_runs(ds, ax=axes[0, 0])
        axes[0, 0].set_title("measured runs", fontsize="medium")
        self.figure(fig)

    def time_series(self) -> None:
        """The time-series section: measured and simulated output of the shown runs, one
        figure per fit (the selected family first), each with its residual."""
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
            "over the measurement (grey), one figure per model, the selected one first; "
            "right, the model's residual (simulated - measured)." + self.shown_note(),
            md=False,
        )
        self.md += ["Figures: see the HTML report.", ""]
        signals = [self.rd.signals[k] for k in self.shown]
        if not signals:
            return
        ylabel = "torque" if self.units == "torque" else "angle [rad]"
        n = len(signals)
        height = 0.95 + 1.75 * n
        for key in self.fit_order():
            fit = self.rd.fits[key]
            # placed by hand: the constrained layout is half the time of these figures
            fig, axes = new_figure(
                n, 2, 11, height, layout=None, width_ratios=[2.2, 1], sharex="col"
            )
            fig.subplots_adjust(
                left=0.08,
                right=0.985,
                bottom=0.45 / height,
                top=1 - 0.55 / height,
                wspace=0.22,
                hspace=0.5,
            )
            for row, s in enumerate(signals):
                plot_fit(
                    s["t"],
                    s["measured"],
                    s["predictions"][key],
                    ax=axes[row, 0],
                    residual_ax=axes[row, 1],
                    label=fit["label"],
                    ylabel=ylabel,
                    title=f"run {s['name']}, {s['current']:g} A",
                    legend=False,
                    color=color_of(key),
                )
                axes[row, 1].set_title("residual", fontsize="medium")
                axes[row, 1].set_ylabel("")
                if row < n - 1:  # the columns share their time axis: label it once
                    for ax in axes[row]:
                        ax.set_xlabel("")
                        ax.tick_params(labelbottom=False)
                else:
                    axes[row, 0].set_xlabel("time [s]")
            title = self.fit_title(key)
            handles, labels = axes[0, 0].get_legend_handles_labels()
            fig.legend(
                handles,
                labels,
                loc="upper right",
                bbox_to_anchor=(0.985, 1 - 0.05 / height),
                ncols=len(labels),
                fontsize="small",
                frameon=False,
            )
            cls = ' class="selected"' if self.is_selected(key) else ""
            self.html.append(f"<h3{cls}>{esc(title)}</h3>")
            self.figure(fig)

    def fit_order(self) -> list[str]:
        """The fits drawn, the selected (or final) model first, then by RMS."""
        fits = self.rd.fits
        first = [k for k in ("final", self.res.family) if k in fits]
        rest = sorted((k for k in fits if k not in first), key=lambda k: float(fits[k]["rms"]))
        return first + rest

    def is_selected(self, key: str) -> bool:
        """``key`` is the selected (declared) family, or the final model built on it."""
        return key == self.res.family or key == "final"

    def fit_title(self, key: str) -> str:
        """A fit's name in headings, the selected one marked, with its RMS."""
        fit = self.rd.fits[key]
        sel = "declared" if self.res.declared else "selected"
        mark = ""
        if key == self.res.family:
            mark = f" ({sel} family)"
        elif key == "final":
            mark = f" (final model: the {sel} family with its accepted effects)"
        return f"{fit['label']}{mark}, RMS {num(fit['rms'])}"

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
                f"{'final' if self.rd.final else 'selected'} fit); dashed, each fitted "
                "model's damper torque against its own simulated velocity and angle."
            )
        self.p(text + self.shown_note(), md=False)
        self.md += ["Figures: see the HTML report.", ""]
        n = len(self.shown)
        fig, axes = new_figure(n, 2, 11, 0.9 + 3.0 * n)
        for row, r in enumerate(self.shown):
            items = []
            for lp in self.rd.loops:
                if lp["run"] != r:
                    continue
                k = thin(len(lp["t"]))
                lp = {
                    **lp,
                    **{q: np.asarray(lp[q])[k] for q in ("t", "theta", "theta_dot", "torque")},
                }
                if lp["kind"] == "data":
                    lp["label"] = "data"
                elif self.is_selected(lp["kind"]):
                    lp["label"] += " (selected)" if lp["kind"] != "final" else " (final)"
                    lp["style"] = {**lp["style"], "lw": 1.8}
                items.append(lp)
            loops_figure(items, axes=list(axes[row]), legend=False)
            axes[row, 0].set_title(
                f"run {self.fd.names[r]}, {self.fd.currents[r]:g} A", fontsize="medium"
            )
        figure_legend(fig, axes[0, 0])
        self.figure(fig)
