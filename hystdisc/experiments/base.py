"""What an experiment type is: what is measured, what is simulated, what stage 1 regresses.

An experiment type says how a run was made (release, driven, forced; doc/design.rst
section 1). Code that needs to know asks the experiment object for the property it needs,
instead of comparing names: ``experiment.output`` is the signal the output-error fit
compares, ``experiment.motion_imposed`` says whether the angle is an input, and so on.

Examples
--------
>>> from hystdisc.registry import get_experiment
>>> exp = get_experiment("driven")
>>> exp.output, exp.motion_imposed, exp.initial_state(has_z=True)
('torque', True, [])
>>> get_experiment("forced").initial_state(has_z=True)
['theta0', 'theta_dot0', 'z0']
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Experiment:
    """One experiment type.

    Attributes
    ----------
    name : str
        ``release``, ``driven`` or ``forced``.
    title : str
        A short description for reports.
    output : str
        The measured signal the output-error fit compares: ``theta`` or ``torque``.
    extra_column : str or None
        The column a record needs besides ``t``, ``theta`` and ``current``.
    motion_imposed : bool
        The angle is imposed (an input of the model, smoothed and differentiated); only
        the hysteretic states are integrated and the torque is the output.
    has_input : bool
        A known external input ``u(t)`` drives the rig (``J theta'' = u - T``).
    inertia_identifiable : bool
        ``J`` is a parameter of the fit (it is 1 when the torque is per unit inertia).
    starts_at_rest : bool
        Runs start at rest with ``z = 0`` (a release from a known angle).
    target : str
        What stage 1 regresses on the torque library (``-theta_ddot``, ``torque``, ``input``).
    """

    name: str
    title: str
    output: str
    extra_column: str | None
    motion_imposed: bool
    has_input: bool
    inertia_identifiable: bool
    starts_at_rest: bool
    target: str

    def initial_state(self, has_z: bool) -> list[str]:
        """Names of the per-run initial-state parameters the fit estimates (nuisance).

        Parameters
        ----------
        has_z : bool
            The model carries a hysteretic state.
        """
        if self.motion_imposed:
            return []
        if self.starts_at_rest:
            return ["theta0"]
        # a forced record may start mid-motion: the whole initial state is unknown
        return ["theta0", "theta_dot0", "z0"] if has_z else ["theta0", "theta_dot0"]

    @property
    def output_label(self) -> str:
        """Axis label of the output signal."""
        return "torque [N*m]" if self.output == "torque" else "angle [rad]"

    def __str__(self) -> str:
        return self.name
