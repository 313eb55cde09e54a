"""A known input force drives the rig; the angle is measured (the inertia is identifiable)."""

from hystdisc.experiments.base import Experiment

FORCED = Experiment(
    name="forced",
    title="known input u(t): J theta'' + T = u",
    output="theta",
    extra_column="input",
    motion_imposed=False,
    has_input=True,
    inertia_identifiable=True,
    starts_at_rest=False,
    target="input",
)
