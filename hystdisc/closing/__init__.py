"""Closing the loop: residual -> the catalogued effect the model lacks -> refit -> whiteness.

:func:`close_loop` (and :func:`augment`, which it wraps) returns a :class:`LoopResult`;
:func:`score_effects` diagnoses a residual, :func:`candidate_effects` lists what a model
could still lack, :func:`refit_with` refits it with one effect, :func:`assess_residual`
gives the verdict on what remains.
"""

from hystdisc.closing.diagnostics import residual_spectrum, residual_summary
from hystdisc.closing.loop import LoopResult, augment, close_loop
from hystdisc.closing.refit import (
    EFFECT_BIC_MARGIN,
    candidate_effects,
    has_spring,
    refit_with,
    screen_starts,
    stage1_start,
)
from hystdisc.closing.residual import (
    NOISE_RATIO,
    accuracy_floor,
    assess_residual,
    natural_frequency,
)
from hystdisc.closing.scores import EffectScore, score_effects, wald_chi2

__all__ = [
    "EFFECT_BIC_MARGIN",
    "NOISE_RATIO",
    "EffectScore",
    "LoopResult",
    "accuracy_floor",
    "assess_residual",
    "augment",
    "candidate_effects",
    "close_loop",
    "has_spring",
    "natural_frequency",
    "refit_with",
    "residual_spectrum",
    "residual_summary",
    "score_effects",
    "screen_starts",
    "stage1_start",
    "wald_chi2",
]
