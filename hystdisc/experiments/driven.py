"""A characterization machine imposes the motion and measures the torque (or force)."""

from hystdisc.experiments.base import Experiment

DRIVEN = Experiment(
    name="driven",
    title="imposed motion, measured torque",
    output="torque",
    extra_column="torque",
    motion_imposed=True,
    has_input=False,
    inertia_identifiable=False,
    starts_at_rest=False,
    target="torque",
)
