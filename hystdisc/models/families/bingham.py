"""Bingham: viscous plus yield (Coulomb) torque, no hysteretic state."""

from __future__ import annotations

from hystdisc.models.families.base import Family
from hystdisc.models.params import BIG, Param
from hystdisc.models.terms import TermModel


class Bingham(Family):
    name = "bingham"
    title = "Bingham"
    params = (
        Param("c_a", "N*m*s/rad", 0.0, BIG, 0.8, "passive viscous damping"),
        Param("c_b", "N*m*s/(rad*A)", 0.0, BIG, 0.6, "current-dependent viscous damping"),
        Param("f_a", "N*m", 0.0, BIG, 0.3, "passive yield (Coulomb) torque"),
        Param("f_b", "N*m/A", 0.0, BIG, 1.0, "current-dependent yield torque"),
    )
    normalization = "none (no hysteretic state)"
    current_params = ("c_b", "f_b")
    torque_terms = ("theta_dot", "i*theta_dot", "sign(theta_dot)", "i*sign(theta_dot)")
    hysteresis_terms = ()

    def to_terms(self, p):
        return TermModel(
            {
                "theta_dot": p["c_a"],
                "i*theta_dot": p["c_b"],
                "sign(theta_dot)": p["f_a"],
                "i*sign(theta_dot)": p["f_b"],
            },
            {},
        )

    def from_terms(self, tm):
        g = tm.torque.get
        return {
            "c_a": g("theta_dot", 0.0),
            "c_b": g("i*theta_dot", 0.0),
            "f_a": g("sign(theta_dot)", 0.0),
            "f_b": g("i*sign(theta_dot)", 0.0),
        }

    def equations(self):
        return "T = (c_a + c_b*i)*theta_dot + (f_a + f_b*i)*sign(theta_dot)"


BINGHAM = Bingham()
