"""The report's "What to test next" section: the runs :func:`hystdisc.design.design`
suggests and the 95 % intervals expected after them.

The section is written when the report is given a design (``hystdisc report --design N``,
or ``write_report(..., design=...)``), and left out otherwise.
"""

from __future__ import annotations

from hystdisc.design import DesignResult


class DesignSections:
    """The ``what-to-test-next`` section (a mixin of the report's :class:`Document`).

    Reads ``self.design``: a :class:`~hystdisc.design.DesignResult`, the reason there is
    none (a str), or None (not asked for).
    """

    design: DesignResult | str | None = None

    def what_to_test_next(self) -> None:
        """The "What to test next" section: the suggested runs and the expected widths
        (left out when no design was asked for)."""
        plan = self.design
        if plan is None:
            return
        self.h2("what-to-test-next")
        if isinstance(plan, str):
            self.p(f"Not computed: {plan}")
            return
        rb = plan.relative_before
        self.p(
            f"The {len(plan.runs)} runs below most shrink the widest 95 % interval of "
            f"{plan.family} relative to its value, predicted from the Fisher information of "
            "each candidate run (the fitted model's output sensitivities, noise at the fit's "
            f"RMS {plan.sigma:.3g}). Widest now: {plan.widest_before} "
            f"({100 * rb[plan.widest_before]:.3g} %); expected after them: "
            f"{plan.widest_after} ({100 * plan.relative_after[plan.widest_after]:.3g} %), "
            f"a factor {plan.predicted_factor:.2f}."
        )
        rows = [
            [str(k), s.label(), f"{100 * w:.3g} %"]
            for k, (s, w) in enumerate(zip(plan.runs, plan.widest_steps, strict=True), 1)
        ]
        self.table(["#", "run to record", "widest interval after it"], rows, left=2)
        header, rows = plan.table()
        self.table(header, rows)
        for fam, ranked in plan.separation.items():
            self.p(
                f"Runs that best tell {plan.family} from {fam} (which fits about as well): "
                "the expected sum of squared output differences in noise units (10 or more: "
                "one run tells them apart)."
            )
            self.table(["run", "separation"], [[s.label(), f"{v:.3g}"] for s, v in ranked])
        for note in plan.notes:
            self.p(note, cls="note")
