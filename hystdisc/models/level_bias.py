"""A force bias that changes with the current, on a rig whose spring holds the constant.

A force bias ``f_0a + f_0i i`` that differs per control level (a field-dependent zero of
the force sensor, a magnetized part's pull) is the catalogued ``current_bias`` where the
model has no spring. Where it has one (a release rig's spring, a driven damper's
accumulator, the term ``theta`` with ``k_s``), a constant force is the spring's neutral
angle, ``k_s theta_off`` (the ``offset``), so ``current_bias`` is not tried there; its
part that grows with the current is no neutral angle, and before this effect it was left
to the open library (a driven damper with an accumulator, an asymmetric yield, a play and
a bias per level: the library's term ``i``, accepted, ``benchmarks/results/three_effects.md``).
This is that part: ``f_0i i``, tried only where the model has a spring (role
``"spring"``), beside the offset for the constant.

Examples
--------
>>> from hystdisc.models.terms import TermModel
>>> LEVEL_BIAS.apply(TermModel({"theta": 2.0}), {"f_0i": -0.3}, 2.0).torque
{'theta': 2.0, 'i': -0.3}
>>> LEVEL_BIAS.has_role("spring")
True
"""

from __future__ import annotations

from dataclasses import replace

from hystdisc.models.effects import one_term_effect
from hystdisc.models.params import BIG, Param

LEVEL_BIAS = replace(
    one_term_effect(
        "level_bias",
        Param("f_0i", "N*m/A", -BIG, BIG, -0.2, "growth of the force bias with the current"),
        "i",
        "a force bias that grows with the current, f_0i * i, where the spring holds the "
        "constant part (its neutral angle, the offset): a field-dependent zero of the force "
        "sensor, a magnetized part's pull",
    ),
    roles=("spring",),
)
"""The per-level part of a force bias on a model with a spring (see the module)."""
