"""Simulation: compiled integrators for every model and experiment, and synthetic data.

- :mod:`~hystdisc.simulation.runs`: simulate runs of a family, a family with effects or a
  discovered structure (release, forced, driven), on the fixed-step term kernels
  (:mod:`~hystdisc.simulation.kernels`, batched by :mod:`~hystdisc.simulation.batch`);
- :mod:`~hystdisc.simulation.ode`: any state-space model, with one error-controlled
  integrator; :class:`~hystdisc.simulation.integration.Integration`: the integrators'
  settings inside a fit;
- :mod:`~hystdisc.simulation.synth`: synthetic datasets (``hystdisc simulate``), their
  settings checked by :mod:`~hystdisc.simulation.synth_checks` and read from scenario
  files by :mod:`~hystdisc.simulation.scenarios`;
- :mod:`~hystdisc.simulation.studies`: the seed's parameter studies.
"""

from hystdisc.simulation.batch import (
    concat_runs,
    driven_batch,
    driven_shared,
    input_slopes,
    integrate_z,
    integrate_z_flat,
    mech_batch,
)
from hystdisc.simulation.integration import Integration
from hystdisc.simulation.kernels import HOLDS, MAX_SUBSTEPS, MIN_SUBSTEPS, STEP_RATIO
from hystdisc.simulation.ode import SystemResult, simulate_system
from hystdisc.simulation.runs import (
    SimResult,
    simulate_driven,
    simulate_driven_runs,
    simulate_forced,
    simulate_mech,
    simulate_release,
)

__all__ = [
    "HOLDS",
    "Integration",
    "MAX_SUBSTEPS",
    "MIN_SUBSTEPS",
    "STEP_RATIO",
    "SimResult",
    "SystemResult",
    "concat_runs",
    "driven_batch",
    "driven_shared",
    "input_slopes",
    "integrate_z",
    "integrate_z_flat",
    "mech_batch",
    "simulate_driven",
    "simulate_driven_runs",
    "simulate_forced",
    "simulate_mech",
    "simulate_release",
    "simulate_system",
]
