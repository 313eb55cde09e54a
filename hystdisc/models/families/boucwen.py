"""Bouc-Wen, in the seed's printed form and in the standard form."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping

import numpy as np

from hystdisc.models.families.base import Family
from hystdisc.models.params import param_table
from hystdisc.models.terms import TermModel

#: The parameters of both forms: their demo defaults and the gamma term's shape differ.
_PARAMS = """
    # name   unit           lower  upper  default  doc
    alpha_1  N*m            0      BIG    0.5      passive hysteretic torque
    alpha_2  N*m/A          0      BIG    1.5      current-dependent hysteretic torque
    c_1      N*m*s/rad      0      BIG    0.5      passive viscous damping
    c_2      N*m*s/(rad*A)  0      BIG    0.6      current-dependent viscous damping
    beta     1/rad          -BIG   BIG    {beta}   shape (theta_dot |z|^n term)
    gamma    1/rad          -BIG   BIG    {gamma}  shape (|theta_dot| {gamma_shape} term)
    delta    1/rad          1e-12  BIG    20       initial slope of z against theta
    n        -              1e-4   10     {n}      exponent
"""


class BoucWen(Family):
    """Bouc-Wen in the seed's printed form: ``dz = -gamma|w| z|z|^n - beta w |z|^n + delta w``."""

    name = "bouc-wen"
    title = "Bouc-Wen (seed form)"
    color = "tab:green"
    correspondence = {"theta_dot": "c_1", "z": "alpha_1", "i*z": "alpha_2", "i*theta_dot": "c_2"}
    normalizations = ("z_sat", "alpha_1")
    params = param_table(_PARAMS.format(beta=10, gamma=10, gamma_shape="z |z|^n", n=1))
    normalization = "z_sat = 1 (delta = beta + gamma)"
    current_params = ("alpha_2", "c_2")
    current_laws = {"alpha": ("alpha_1", "alpha_2"), "c": ("c_1", "c_2")}
    law_terms = {"alpha": "z", "c": "theta_dot"}
    torque_terms = ("theta_dot", "i*theta_dot", "z", "i*z")
    linear_torque = {"z": "alpha_1", "i*z": "alpha_2", "theta_dot": "c_1", "i*theta_dot": "c_2"}
    hysteresis_terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^n")
    _gamma_term = "|theta_dot|*z*|z|^n"
    start_from = ("bouc-wen-std", "dahl", "lugre")
    #: Degree of z in the gamma term beyond ``|z|^n`` (seed form: z|z|^n, one more).
    gamma_extra_degree = 1
    #: The exponent at which the gamma term is Dahl's ``|theta_dot|*z`` (seed form: n -> 0,
    #: its lower bound).
    dahl_exponent = 1e-4

    def to_terms(self, p):
        return TermModel(
            self.linear_coefs(p),
            {"theta_dot": p["delta"], "theta_dot*|z|^n": -p["beta"], self._gamma_term: -p["gamma"]},
            n=p["n"],
        )

    def z_scale(self, start: Mapping[str, float]) -> tuple[dict[str, float], str]:
        """Loops that saturate are fitted with ``z_sat = 1``; loops that never saturate
        (``beta + gamma <= 0``) have no such scale, so z is taken in torque units
        (``alpha_1 = 1``) and the start is rescaled to it (:meth:`in_torque_units`).

        Examples
        --------
        >>> p = {"alpha_1": 2.0, "alpha_2": 1.0, "delta": 3.0, "beta": -2.0, "gamma": -1.0,
        ...      "n": 1.0}
        >>> BOUC_WEN.z_scale(p)[1], BOUC_WEN.z_scale({**p, "gamma": 6.0})[1]
        ('alpha_1', 'z_sat')
        """
        zs = self.z_sat(start["delta"], start["beta"], start["gamma"], start["n"])
        if np.isfinite(zs) and zs > 0:
            return dict(start), "z_sat"
        return self.in_torque_units(start), "alpha_1"

    def derived_names(self, normalization: str) -> tuple[str, ...]:
        """``z_sat = 1``: ``delta = beta + gamma`` is not fitted."""
        return ("delta",) if normalization == "z_sat" else ()

    def fixed_by(self, normalization: str) -> dict[str, float]:
        """``alpha_1 = 1``: z in torque units."""
        return {"alpha_1": 1.0} if normalization == "alpha_1" else {}

    def complete(self, p: dict[str, float], normalization: str) -> dict[str, float]:
        if normalization == "z_sat":
            p["delta"] = p["beta"] + p["gamma"]
        return p

    def in_torque_units(self, params: Mapping[str, float]) -> dict[str, float]:
        """``params`` with z rescaled to torque units (``alpha_1 = 1``).

        The same model: z is multiplied by ``a = alpha_1``, so ``delta``, ``beta`` and
        ``gamma`` take the powers of ``a`` their terms carry and ``alpha_2`` is divided
        by it. Parameters without a positive ``alpha_1`` get ``alpha_1 = 1`` alone.

        Examples
        --------
        >>> p = {"alpha_1": 2.0, "alpha_2": 1.0, "delta": 3.0, "beta": 2.0, "gamma": 1.0,
        ...      "n": 1.0}
        >>> q = BOUC_WEN.in_torque_units(p)
        >>> q["alpha_1"], q["alpha_2"], q["delta"], q["beta"], q["gamma"]
        (1.0, 0.5, 6.0, 2.0, 0.5)
        """
        q = dict(params)
        a = params.get("alpha_1", 0.0)
        if np.isfinite(a) and a > 0:
            n = params["n"]
            q["delta"] = params["delta"] * a
            q["beta"] = params["beta"] * a ** (1.0 - n)
            q["gamma"] = params["gamma"] * a ** (1.0 - n - self.gamma_extra_degree)
            q["alpha_2"] = params.get("alpha_2", 0.0) / a
        q["alpha_1"] = 1.0
        return q

    def saturation_torque(self, p: Mapping[str, float | None], which: str) -> float | None:
        return p.get("alpha_1") if which == "a" else p.get("alpha_2")

    def z_sat(self, delta: float, beta: float, gamma: float, n: float) -> float:
        """Saturation value of z on a monotone loading branch (root of delta = beta s^n + gamma s^(n+1))."""
        from scipy.optimize import brentq

        def f(s):
            return delta - beta * s**n - gamma * s ** (n + self.gamma_extra_degree)

        if not delta > 0:  # z never leaves 0 upwards (a start that maps to delta <= 0)
            return float("nan")
        hi = 1.0
        try:
            while f(hi) >= 0:
                hi *= 2.0
                if hi > 1e12:
                    return float("inf")  # no saturation (e.g. beta + gamma <= 0)
        except OverflowError:
            return float("inf")
        return float(brentq(f, 0.0, hi, xtol=1e-14, rtol=1e-12))

    def from_terms(self, tm):
        delta = tm.hysteresis.get("theta_dot", 0.0)
        beta = -tm.hysteresis.get("theta_dot*|z|^n", 0.0)
        gamma = -tm.hysteresis.get(self._gamma_term, 0.0)
        n = tm.n
        dahl = -tm.hysteresis.get("|theta_dot|*z", 0.0)
        if dahl and not gamma and not beta:
            # a Dahl or LuGre state (dz = delta w - g |w| z) is this family's gamma term
            # at the exponent where |z|-powers vanish: n = 0 (seed form, its lower bound)
            # or n = 1 (standard form)
            gamma, n = dahl, self.dahl_exponent
        g = tm.torque.get
        s = self.z_sat(delta, beta, gamma, n)
        if not np.isfinite(s) or s <= 0:
            s = 1.0
        # z = s * zn ;  dzn = delta/s w - beta s^(n-1) w|zn|^n - gamma s^n |w| zn |zn|^n
        return {
            "alpha_1": g("z", 0.0) * s,
            "alpha_2": g("i*z", 0.0) * s,
            "c_1": g("theta_dot", 0.0),
            "c_2": g("i*theta_dot", 0.0),
            "beta": beta * s ** (n - 1.0),
            "gamma": self._scaled_gamma(gamma, s, n),
            "delta": delta / s,
            "n": n,
        }

    def term_starts(self, tm: TermModel) -> list[dict[str, float]]:
        """Readings of ``tm`` in this form; the other Bouc-Wen form's gamma term
        (``|w| z |z|^(n-1)`` against the seed's ``|w| z |z|^n``) is this form's at an
        exponent one apart, which moves its beta term's exponent too: two starts, one
        keeping the gamma term exact (``n`` shifted by one) and one keeping the beta term
        exact (``n`` kept).

        Examples
        --------
        >>> std = BOUC_WEN_STD.to_terms({"alpha_1": 1, "alpha_2": 0, "c_1": 0.5, "c_2": 0,
        ...                              "beta": 5, "gamma": 15, "delta": 20, "n": 2})
        >>> [round(s["n"], 3) for s in BOUC_WEN.term_starts(std)]
        [1.0, 2.0]
        """
        other = next(
            (
                k
                for k in ("|theta_dot|*z*|z|^n", "|theta_dot|*z*|z|^(n-1)")
                if k != self._gamma_term
            ),
        )
        if self._gamma_term in tm.hysteresis or not tm.hysteresis.get(other):
            return [self.from_terms(tm)]
        hyst = {k: v for k, v in tm.hysteresis.items() if k != other}
        hyst[self._gamma_term] = tm.hysteresis[other]
        shift = 1.0 if self.gamma_extra_degree == 0 else -1.0  # std reads seed: n + 1
        lower = next(p.lower for p in self.params if p.name == "n")
        starts = []
        for n in (max(tm.n + shift, lower), tm.n):
            starts.append(self.from_terms(dataclasses.replace(tm, hysteresis=hyst, n=n)))
        return starts

    def _scaled_gamma(self, gamma: float, s: float, n: float) -> float:
        """The gamma of the normalized state ``zn = z / s`` (seed form: ``gamma s^n``)."""
        return gamma * s**n

    def equations(self):
        return (
            "T = (alpha_1 + alpha_2*i)*z + (c_1 + c_2*i)*theta_dot\n"
            "dz/dt = -gamma*|theta_dot|*z*|z|^n - beta*theta_dot*|z|^n + delta*theta_dot"
        )


class BoucWenStd(BoucWen):
    """Standard Bouc-Wen: ``dz = delta w - beta w |z|^n - gamma |w| z |z|^(n-1)``."""

    name = "bouc-wen-std"
    title = "Bouc-Wen (standard form)"
    color = "tab:olive"
    params = param_table(_PARAMS.format(beta=5, gamma=15, gamma_shape="z |z|^(n-1)", n=2))
    hysteresis_terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^(n-1)")
    _gamma_term = "|theta_dot|*z*|z|^(n-1)"
    start_from = ("bouc-wen", "dahl", "lugre")
    gamma_extra_degree = 0
    dahl_exponent = 1.0
    # n = 1, beta = 0: dz/dt = delta theta_dot - gamma |theta_dot| z with delta = gamma
    # (z_sat = 1), Dahl's state with rho = delta; c_2 i theta_dot is the current-dependent
    # viscous effect
    reductions = (({"n": 1.0, "beta": 0.0}, "dahl", ("current_viscous",)),)

    def _scaled_gamma(self, gamma: float, s: float, n: float) -> float:
        # standard form: both shape terms scale as s^(n-1) after z = s*zn:
        # dzn = delta/s w - beta s^(n-1) w |zn|^n - gamma s^(n-1) |w| zn |zn|^(n-1)
        return gamma * s ** (n - 1.0)

    def equations(self):
        return (
            "T = (alpha_1 + alpha_2*i)*z + (c_1 + c_2*i)*theta_dot\n"
            "dz/dt = delta*theta_dot - beta*theta_dot*|z|^n - gamma*|theta_dot|*z*|z|^(n-1)"
        )

    def force_form(self, p: Mapping[str, float], current: float = 0.0) -> dict[str, float]:
        """The structural-dynamics form with z in force units (e.g. the hysteretic benchmark).

        ``m y'' + c y' + k y + z = u``, ``z' = alpha y' - gamma_beta |y'| |z|^(nu-1) z
        - delta_beta y' |z|^nu``: the benchmark's ``beta*gamma`` and ``beta*delta`` are the
        identifiable products (its ``beta``, ``gamma``, ``delta`` one by one are not).
        ``p`` holds the family parameters plus ``k_s`` and ``J`` (a forced fit).

        Examples
        --------
        >>> fam = BoucWenStd()
        >>> p = {"alpha_1": 1.0, "alpha_2": 0.0, "c_1": 10.0, "c_2": 0.0, "beta": -1100.0,
        ...      "gamma": 800.0, "delta": 5e4, "n": 1.0, "k_s": 5e4, "J": 2.0}
        >>> fam.force_form(p)
        {'m': 2.0, 'c': 10.0, 'k': 50000.0, 'alpha': 50000.0, 'beta*gamma': 800.0, 'beta*delta': -1100.0, 'nu': 1.0}
        """
        a = p["alpha_1"] + current * p.get("alpha_2", 0.0)  # z_force = a * z
        n = p["n"]
        s = a ** (1.0 - n)
        return {
            "m": float(p.get("J", 1.0)),
            "c": float(p["c_1"] + current * p.get("c_2", 0.0)),
            "k": float(p.get("k_s", 0.0)),
            "alpha": float(a * p["delta"]),
            "beta*gamma": float(p["gamma"] * s),
            "beta*delta": float(p["beta"] * s),
            "nu": float(n),
        }


BOUC_WEN = BoucWen()
BOUC_WEN_STD = BoucWenStd()
