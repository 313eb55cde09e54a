"""Release of the SAS rig's beam from a known angle (only the angle is measured)."""

from hystdisc.experiments.base import Experiment

RELEASE = Experiment(
    name="release",
    title="release from a known angle (theta'' = -k_s theta - T per unit inertia)",
    output="theta",
    extra_column=None,
    motion_imposed=False,
    has_input=False,
    inertia_identifiable=False,
    starts_at_rest=True,
    target="-theta_ddot",
)
