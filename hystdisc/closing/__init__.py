"""Closing the loop: residual -> the catalogued effect the model lacks -> refit -> whiteness.

:func:`close_loop` (and :func:`augment`, which it wraps) returns a :class:`LoopResult`
(each refit's :class:`EffectVerdict`, the :class:`AcceptedEffect` entries, each round's
:class:`Diagnosis`, the :class:`EffectSkipped` and the final :class:`ResidualVerdict`);
:func:`score_effects` diagnoses a residual, :func:`candidate_effects` lists what a model
could still lack, :func:`refit_with` refits it with one effect, :func:`assess_residual`
gives the verdict on what remains.
"""

from hystdisc.closing.diagnostics import residual_spectrum, residual_summary
from hystdisc.closing.loop import augment, close_loop
from hystdisc.closing.records import (
    AcceptedEffect,
    Diagnosis,
    EffectParameter,
    EffectVerdict,
    LoopResult,
)
from hystdisc.closing.refit import (
    EFFECT_BIC_MARGIN,
    EffectSkipped,
    candidate_effects,
    has_spring,
    refit_with,
    screen_starts,
    stage1_start,
)
from hystdisc.closing.residual import (
    NOISE_RATIO,
    ResidualVerdict,
    accuracy_floor,
    assess_residual,
    natural_frequency,
)
from hystdisc.closing.scores import EffectScore, score_effects, wald_chi2

__all__ = [
    "EFFECT_BIC_MARGIN",
    "NOISE_RATIO",
    "AcceptedEffect",
    "Diagnosis",
    "EffectParameter",
    "EffectScore",
    "EffectSkipped",
    "EffectVerdict",
    "LoopResult",
    "ResidualVerdict",
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
