"""The result of an experiment design: :class:`DesignResult`.

Examples
--------
>>> from hystdisc.design.runs import RunSpec
>>> d = DesignResult(family="dahl", experiment="release", sigma=0.001,
...     names=["k_x"], judged=["k_x"], values={"k_x": 0.8}, widths_before={"k_x": 0.08},
...     predicted_before={"k_x": 0.08}, widths_after={"k_x": 0.04},
...     runs=[RunSpec("release", 1.0, 0.3, duration=3.0, fs=500.0)], widest_steps=[0.05])
>>> d.widest_before, d.widest_after, d.predicted_factor
('k_x', 'k_x', 0.5)
>>> print(d.report().splitlines()[2])
  1. release from 0.3 rad at 1 A
"""

from __future__ import annotations

import html
from dataclasses import dataclass, field

from hystdisc.design.runs import RunSpec


def _relative(widths: dict[str, float], values: dict[str, float]) -> dict[str, float]:
    return {k: w / abs(values[k]) if values.get(k) else float("inf") for k, w in widths.items()}


@dataclass
class DesignResult:
    """The next runs to record, and the 95 % intervals expected after them.

    Attributes
    ----------
    family : str
        The family whose intervals are shrunk (the selected one).
    experiment : str
        ``"release"`` or ``"driven"``.
    sigma : float
        Residual standard deviation the information is scaled by (the fit's RMS).
    names : list of str
        The reported parameters (free and derived), in the fit's order.
    judged : list of str
        Those whose relative width counts for "widest" (not zero, not held by a bound).
    values : dict of str to float
        Their fitted values.
    widths_before : dict of str to float
        Width of each 95 % interval of the fit (``results.json``).
    predicted_before : dict of str to float
        The same widths predicted from the runs rebuilt from the training envelope (a
        check of the rebuild: near ``widths_before`` when it is faithful).
    widths_after : dict of str to float
        Expected widths after the chosen runs: ``widths_before`` times the predicted
        shrink of each interval.
    runs : list of RunSpec
        The runs to record, in order of choice.
    widest_steps : list of float
        The widest relative interval (width / value) expected after each chosen run.
    ranking : list of (RunSpec, float)
        Every candidate alone, best first, with the widest relative interval after it.
    separation : dict of str to list of (RunSpec, float)
        For each family that fits about as well: the candidates that best tell it from
        the selected family, with the expected ``sum((y_a - y_b)^2) / sigma^2``.
    notes : list of str
        Remarks in plain words.
    """

    family: str
    experiment: str
    sigma: float
    names: list[str]
    judged: list[str]
    values: dict[str, float]
    widths_before: dict[str, float]
    predicted_before: dict[str, float]
    widths_after: dict[str, float]
    runs: list[RunSpec]
    widest_steps: list[float]
    ranking: list[tuple[RunSpec, float]] = field(default_factory=list)
    separation: dict[str, list[tuple[RunSpec, float]]] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def relative_before(self) -> dict[str, float]:
        """Relative width (width divided by the absolute value) of each interval now."""
        return _relative(self.widths_before, self.values)

    @property
    def relative_after(self) -> dict[str, float]:
        """Expected relative width of each interval after the chosen runs."""
        return _relative(self.widths_after, self.values)

    @property
    def widest_before(self) -> str:
        """The parameter with the widest relative interval now."""
        rel = self.relative_before
        return max(self.judged, key=rel.get)

    @property
    def widest_after(self) -> str:
        """The parameter with the widest relative interval expected after the runs."""
        rel = self.relative_after
        return max(self.judged, key=rel.get)

    @property
    def predicted_factor(self) -> float:
        """Expected widest relative interval after the runs over the widest now."""
        return self.relative_after[self.widest_after] / self.relative_before[self.widest_before]

    def summary(self) -> dict:
        """The design as a plain, JSON-ready dict."""

        def run(s: RunSpec) -> dict:
            return {
                "kind": s.kind,
                "current": s.current,
                "amplitude": s.amplitude,
                "frequency": s.frequency,
                "band": list(s.band),
                "duration": s.duration,
                "fs": s.fs,
                "label": s.label(),
            }

        return {
            "family": self.family,
            "experiment": self.experiment,
            "sigma": self.sigma,
            "runs": [run(s) for s in self.runs],
            "widest_steps": list(self.widest_steps),
            "predicted_factor": self.predicted_factor,
            "judged": list(self.judged),
            "parameters": {
                k: {
                    "value": self.values[k],
                    "width_before": self.widths_before[k],
                    "width_predicted_before": self.predicted_before[k],
                    "width_after": self.widths_after[k],
                }
                for k in self.names
            },
            "ranking": [{**run(s), "widest_after": v} for s, v in self.ranking],
            "separation": {
                f: [{**run(s), "distance": v} for s, v in rows]
                for f, rows in self.separation.items()
            },
            "notes": list(self.notes),
        }

    def table(self) -> tuple[list[str], list[list[str]]]:
        """Header and rows of the interval table (now, rebuilt, expected after)."""
        header = ["parameter", "value", "95 % width now", "rebuilt", "expected after", "shrink"]
        rows = []
        rb, ra = self.relative_before, self.relative_after
        for k in self.names:
            b, a = self.widths_before[k], self.widths_after[k]
            judged = k in self.judged
            rows.append(
                [
                    k,
                    f"{self.values[k]:.4g}",
                    f"{b:.3g} ({100 * rb[k]:.3g} %)" if judged else f"{b:.3g} (not judged)",
                    f"{self.predicted_before[k]:.3g}",
                    f"{a:.3g} ({100 * ra[k]:.3g} %)" if judged else f"{a:.3g}",
                    f"{a / b:.2f}" if b > 0 else "-",
                ]
            )
        return header, rows

    def report(self) -> str:
        """The design in words: the runs to record, then the interval table."""
        lines = [f"What to test next ({self.family}, {self.experiment}): record these runs", ""]
        for k, (s, w) in enumerate(zip(self.runs, self.widest_steps, strict=True), 1):
            lines.append(f"  {k}. {s.label()}")
            lines.append(f"     widest 95 % interval after it: {100 * w:.3g} % of its value")
        rb, ra = self.relative_before, self.relative_after
        lines += [
            "",
            f"widest interval now: {self.widest_before} ({100 * rb[self.widest_before]:.3g} %)"
            f"; expected after: {self.widest_after} ({100 * ra[self.widest_after]:.3g} %),"
            f" a factor {self.predicted_factor:.2f}",
            "",
        ]
        header, rows = self.table()
        widths = [max(len(r[c]) for r in [header, *rows]) for c in range(len(header))]
        for r in [header, *rows]:
            lines.append("  " + "  ".join(x.ljust(w) for x, w in zip(r, widths, strict=True)))
        for fam, rows_ in self.separation.items():
            lines += ["", f"runs that tell {self.family} from {fam} (expected chi^2 difference):"]
            lines += [f"  {s.label()}: {v:.3g}" for s, v in rows_]
        lines += [f"note: {n}" for n in self.notes]
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.report()

    def _repr_html_(self) -> str:
        return f"<pre>{html.escape(self.report())}</pre>"
