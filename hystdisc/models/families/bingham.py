"""Bingham: viscous plus yield (Coulomb) torque, no hysteretic state."""

from __future__ import annotations

from hystdisc.models.families.base import Family
from hystdisc.models.params import param_table
from hystdisc.models.terms import TermModel


class Bingham(Family):
    name = "bingham"
    title = "Bingham"
    color = "tab:purple"
    params = param_table("""
        # name  unit           lower  upper  default  doc
        c_a     N*m*s/rad      0      BIG    0.8      passive viscous damping
        c_b     N*m*s/(rad*A)  0      BIG    0.6      current-dependent viscous damping
        f_a     N*m            0      BIG    0.3      passive yield (Coulomb) torque
        f_b     N*m/A          0      BIG    1.0      current-dependent yield torque
    """)
    normalization = "none (no hysteretic state)"
    current_params = ("c_b", "f_b")
    current_laws = {"c": ("c_a", "c_b"), "f": ("f_a", "f_b")}
    law_terms = {"c": "theta_dot", "f": "sign(theta_dot)"}
    linear_torque = {
        "theta_dot": "c_a",
        "i*theta_dot": "c_b",
        "sign(theta_dot)": "f_a",
        "i*sign(theta_dot)": "f_b",
    }
    torque_terms = tuple(linear_torque)
    hysteresis_terms = ()

    def to_terms(self, p):
        return TermModel(self.linear_coefs(p), {})

    def from_terms(self, tm):
        return {name: tm.torque.get(term, 0.0) for term, name in self.linear_torque.items()}

    def equations(self):
        return "T = (c_a + c_b*i)*theta_dot + (f_a + f_b*i)*sign(theta_dot)"


BINGHAM = Bingham()
