"""The experiment types, one row each: release, driven and forced.

* ``release``: the SAS rig's beam is released from a known angle; only the angle is
  measured.
* ``driven``: a characterization machine imposes the motion and measures the torque (or
  force).
* ``forced``: a known input force drives the rig; the angle is measured (the inertia is
  identifiable).

Examples
--------
>>> from hystdisc.experiments.catalog import FORCED
>>> FORCED.has_input, FORCED.target
(True, 'input')
"""

from hystdisc.experiments.base import Experiment

#: The columns are the fields of :class:`~hystdisc.experiments.base.Experiment` after
#: ``name`` and ``title``: output, extra_column, motion_imposed, has_input,
#: inertia_identifiable, starts_at_rest, target.
_TABLE = {
    "release": ("theta", None, False, False, False, True, "-theta_ddot"),
    "driven": ("torque", "torque", True, False, False, False, "torque"),
    "forced": ("theta", "input", False, True, True, False, "input"),
}
_TITLES = {
    "release": "release from a known angle (theta'' = -k_s theta - T per unit inertia)",
    "driven": "imposed motion, measured torque",
    "forced": "known input u(t): J theta'' + T = u",
}

RELEASE, DRIVEN, FORCED = (Experiment(name, _TITLES[name], *row) for name, row in _TABLE.items())
