"""Dahl (seed eq. 9-10): a first-order hysteretic state that saturates at 1."""

from __future__ import annotations

from hystdisc.models.families.base import Family
from hystdisc.models.params import param_table
from hystdisc.models.terms import TermModel


class Dahl(Family):
    name = "dahl"
    title = "Dahl"
    color = "tab:blue"
    variants = {
        frozenset({"theta_dot", "z", "i*z", "i*theta_dot"}): "modified Dahl (Dahl + i*theta_dot)"
    }
    correspondence = {"theta_dot": "k_x", "z": "k_wa", "i*z": "k_wb"}

    params = param_table("""
        # name  unit       lower  upper  default  doc
        k_x     N*m*s/rad  0      BIG    0.8      viscous damping
        k_wa    N*m        0      BIG    0.5      passive hysteretic torque
        k_wb    N*m/A      0      BIG    1.5      current-dependent hysteretic torque
        rho     1/rad      1e-9   BIG    20       hysteresis rate (loop sharpness)
    """)
    normalization = "w saturates at 1 (by construction)"
    current_params = ("k_wb",)
    current_laws = {"k_w": ("k_wa", "k_wb")}
    law_terms = {"k_w": "z"}
    linear_torque = {"theta_dot": "k_x", "z": "k_wa", "i*z": "k_wb"}
    torque_terms = tuple(linear_torque)
    hysteresis_terms = ("theta_dot", "|theta_dot|*z")
    start_from = ("lugre",)

    def to_terms(self, p):
        return TermModel(
            self.linear_coefs(p),
            {"theta_dot": p["rho"], "|theta_dot|*z": -p["rho"]},
        )

    def from_terms(self, tm):
        # normalize z so that it saturates at 1: z_sat = b_theta_dot / -b_abs
        b1 = tm.hysteresis.get("theta_dot", 0.0)
        b2 = -tm.hysteresis.get("|theta_dot|*z", 0.0)
        s = b1 / b2 if b2 != 0.0 else 1.0  # z = s * w
        g = tm.torque.get
        return {
            "k_x": g("theta_dot", 0.0),
            "k_wa": g("z", 0.0) * s,
            "k_wb": g("i*z", 0.0) * s,
            "rho": b2,
        }

    def saturation_torque(self, p, which):
        """``w`` saturates at 1: the torque there is ``k_wa`` (0 A) and ``k_wb`` (per A)."""
        return p.get("k_wa") if which == "a" else p.get("k_wb")

    def equations(self):
        return "T = k_x*theta_dot + (k_wa + k_wb*i)*z\ndz/dt = rho*(theta_dot - |theta_dot|*z)"


DAHL = Dahl()
