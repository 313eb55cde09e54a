"""How a fit integrates its candidate models: :class:`Integration`.

A fit simulates thousands of candidates, so it integrates them more loosely than a
prediction does (:mod:`hystdisc.apply.predict` keeps its own, tighter tolerances): the
fixed-step term kernels with fewer sub-steps, the error-controlled integrator of a
state-space model with the tolerances its Jacobian needs. The settings travel with the
data of a fit (:attr:`hystdisc.measurement.FitData.integration`), so a fit, its
Jacobian, its held-out folds and every refit of the same data integrate alike; the
pipeline takes them from :attr:`hystdisc.pipeline.Options.integration`.

Examples
--------
>>> Integration().rtol
1e-10
>>> Integration(rtol=1e-8, atol=1e-11).max_steps
200
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Integration:
    """The integrators' settings inside a fit (the defaults are the fits' own).

    Attributes
    ----------
    ratio : float
        Sub-step ratio of the fixed-step term kernels (``h * lambda`` per RK4 sub-step;
        errors about 1e-6 of the signal, far below any noise).
    min_sub : int
        Fewest sub-steps per sample interval.
    max_sub : int
        Sub-step cap per measured sample interval (a decimated run gets its factor more):
        a candidate with a near-discontinuous state (a Dahl rate fitted to Bingham data)
        is not worth resolving exactly inside the optimizer.
    rtol, atol : float
        Tolerances of the error-controlled integrator (state-space models): forward
        differences of separately controlled runs need 1e-10 / 1e-13; the lockstep
        Jacobian needs only
        :data:`~hystdisc.fitting.system_jacobian.LOCKSTEP_INTEGRATION`'s.
    max_steps : int
        Steps of the error-controlled integrator per measured sample interval: a
        candidate whose dynamics need more (a series mass driven towards zero, a stiff
        wheel) counts as diverged, and the optimizer backs away.
    """

    ratio: float = 0.4
    min_sub: int = 1
    max_sub: int = 8
    rtol: float = 1e-10
    atol: float = 1e-13
    max_steps: int = 200
