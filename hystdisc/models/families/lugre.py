"""LuGre (seed eq. 13-14): Dahl's bristle state with damping through dz/dt."""

from __future__ import annotations

from hystdisc.models.families.base import Family
from hystdisc.models.params import param_table
from hystdisc.models.terms import TermModel


class LuGre(Family):
    name = "lugre"
    title = "LuGre"
    color = "tab:red"
    correspondence = {"theta_dot": "sigma_2", "z": "sigma_a", "i*z": "sigma_0",
                      "i*theta_dot": "sigma_b", "|theta_dot|*z": "sigma_1"}  # fmt: skip

    params = param_table("""
        # name   unit           lower  upper  default  doc
        sigma_a  N*m/rad        0      BIG    10       passive stiffness of z
        sigma_0  N*m/(rad*A)    1e-9   BIG    30       current-dependent stiffness of z
        sigma_1  N*m*s/rad      0      BIG    0.5      damping of z (acts through dz/dt)
        sigma_2  N*m*s/rad      0      BIG    0.5      viscous damping
        sigma_b  N*m*s/(rad*A)  0      BIG    0.6      current-dependent viscous damping
        a_0      A/(N*m)        1e-12  BIG    2/3      rate constant (z_sat = 1/(sigma_0 a_0))
    """)
    normalization = (
        "seed scale (dz/dt = theta_dot - sigma_0 a_0 |theta_dot| z; z_sat = 1/(sigma_0 a_0))"
    )
    torque_terms = ("theta_dot", "i*theta_dot", "z", "i*z", "|theta_dot|*z")
    hysteresis_terms = ("theta_dot", "|theta_dot|*z")
    current_params = ("sigma_b",)
    current_laws = {"sigma_v": ("sigma_2", "sigma_b")}
    law_terms = {"sigma_v": "theta_dot"}
    # sigma_1 = 0: dz/dt no longer enters the torque, and sigma_b i theta_dot is the
    # current-dependent viscous effect (z = w / (sigma_0 a_0), rho = sigma_0 a_0)
    reductions = (({"sigma_1": 0.0}, "dahl", ("current_viscous",)),)
    start_from = ("dahl",)

    def to_terms(self, p):
        r = p["sigma_0"] * p["a_0"]
        return TermModel(
            {
                "z": p["sigma_a"],
                "i*z": p["sigma_0"],
                "theta_dot": p["sigma_1"] + p["sigma_2"],
                "i*theta_dot": p["sigma_b"],
                "|theta_dot|*z": -p["sigma_1"] * r,
            },
            {"theta_dot": 1.0, "|theta_dot|*z": -r},
        )

    def from_terms(self, tm):
        # bring z to the seed's scale, where the theta_dot coefficient of dz/dt is 1
        # z = s * z_seed with s = b1 gives dz_seed = theta_dot + b2 |theta_dot| z_seed
        b1 = tm.hysteresis.get("theta_dot", 1.0) or 1.0
        r = -tm.hysteresis.get("|theta_dot|*z", 0.0)
        g = tm.torque.get
        s = b1
        sigma_0 = g("i*z", 0.0) * s
        sigma_1 = -g("|theta_dot|*z", 0.0) * s / r if r != 0.0 else 0.0
        return {
            "sigma_a": g("z", 0.0) * s,
            "sigma_0": sigma_0,
            "sigma_1": sigma_1,
            "sigma_2": g("theta_dot", 0.0) - sigma_1,
            "sigma_b": g("i*theta_dot", 0.0),
            "a_0": r / sigma_0 if sigma_0 != 0.0 else float("inf"),
        }

    def saturation_torque(self, p, which):
        """``z`` saturates at ``1 / (sigma_0 a_0)``: ``sigma_a`` (0 A) and ``sigma_0`` (per A)
        times it."""
        try:
            zsat = 1.0 / (p["sigma_0"] * p["a_0"])
            return p["sigma_a"] * zsat if which == "a" else p["sigma_0"] * zsat
        except (KeyError, TypeError, ZeroDivisionError):
            return None

    def equations(self):
        return (
            "T = sigma_a*z + sigma_0*i*z + sigma_1*dz/dt + sigma_2*theta_dot + sigma_b*i*theta_dot\n"
            "dz/dt = theta_dot - sigma_0*a_0*|theta_dot|*z"
        )


LUGRE = LuGre()
