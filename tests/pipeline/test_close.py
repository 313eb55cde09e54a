"""The closing stage of the pipeline: what it decides before the loop runs."""

from __future__ import annotations

from hystdisc.models import EFFECTS
from hystdisc.pipeline.close import decided_by_spring


class _Fit:
    """What :func:`decided_by_spring` reads of a fit: ``k_s`` and its interval."""

    def __init__(self, ks: float, lo: float) -> None:
        self.params, self.ci95 = {"k_s": ks}, {"k_s": (lo, 2 * ks - lo)}


def test_a_rig_spring_decides_the_effects_that_are_its_neutral_angle():
    """On a rig with a spring a constant force is the spring's neutral angle (a spring
    effect): the effects that say so (role ``no_spring``) are decided, the others not;
    without a spring nothing is."""
    decided = decided_by_spring(_Fit(158.0, 150.0))
    assert set(decided) == {"bias", "current_bias"}
    assert not any(EFFECTS[name].has_role("spring") for name in decided)
    assert all("neutral angle" in why for why in decided.values())
    assert decided_by_spring(_Fit(0.01, -0.05)) == {}
    assert decided_by_spring(_Fit(0.0, 0.0)) == {}
