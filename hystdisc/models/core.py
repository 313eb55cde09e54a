"""The four MR-damper families of the seed paper, the effect catalogue, and their terms.

Every model, whatever its family, is reduced to one generic form, a :class:`TermModel`:
a damper torque that is a linear combination of named *torque terms* and a hysteretic
state ``z`` whose rate is a linear combination of named *hysteresis terms*::

    T  = sum_k a_k * torque_term_k(theta, theta_dot, z, i)
    dz = sum_j b_j * hysteresis_term_j(theta_dot, z; n)

The rig spring ``k_s`` is the coefficient of the ``theta`` torque term. The simulator,
the term library of the sparse regression and the output-error fit all work on this one
form, so a discovered structure, a family, and a family plus effects are simulated by the
same compiled kernel.

Examples
--------
>>> from hystdisc.models.core import Model
>>> m = Model("dahl", {"k_s": 158.0})
>>> m.params["rho"]
20.0
>>> tm = m.to_terms()
>>> tm.torque["z"], tm.hysteresis["|theta_dot|*z"]
(0.5, -20.0)
>>> print(m.family.equations())
T = k_x*theta_dot + (k_wa + k_wb*i)*z
dz/dt = rho*(theta_dot - |theta_dot|*z)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from hystdisc.errors import HystdiscError

#: Width of the smoothed sign function ``tanh(theta_dot / SIGN_EPS)`` (rad/s or m/s).
SIGN_EPS = 1e-3


def smooth_sign(v: np.ndarray | float, eps: float = SIGN_EPS) -> np.ndarray:
    """Smoothed ``sign(v)``: ``tanh(v / eps)``, used for Coulomb-type terms."""
    return np.tanh(np.asarray(v, dtype=float) / eps)


def _pow_abs(z: np.ndarray, n: float) -> np.ndarray:
    return np.abs(z) ** n


# name -> f(theta, theta_dot, z, i); i is the run's coil current (scalar or array)
TORQUE_TERMS: dict[str, Callable[..., np.ndarray]] = {
    "theta": lambda th, w, z, i: th,
    "theta_dot": lambda th, w, z, i: w,
    "i*theta_dot": lambda th, w, z, i: i * w,
    "z": lambda th, w, z, i: z,
    "i*z": lambda th, w, z, i: i * z,
    "|theta_dot|*z": lambda th, w, z, i: np.abs(w) * z,
    "sign(theta_dot)": lambda th, w, z, i: smooth_sign(w),
    "i*sign(theta_dot)": lambda th, w, z, i: i * smooth_sign(w),
    "i^2*z": lambda th, w, z, i: i * i * z,
    "theta_dot*|theta_dot|": lambda th, w, z, i: w * np.abs(w),
    "theta^3": lambda th, w, z, i: th**3,
    "1": lambda th, w, z, i: np.ones_like(np.asarray(th, dtype=float)),
    "i^2*theta_dot": lambda th, w, z, i: i * i * w,
}
TORQUE_TERM_NAMES: tuple[str, ...] = tuple(TORQUE_TERMS)

# name -> f(theta_dot, z, n)
HYSTERESIS_TERMS: dict[str, Callable[..., np.ndarray]] = {
    "theta_dot": lambda w, z, n: w,
    "|theta_dot|*z": lambda w, z, n: np.abs(w) * z,
    "theta_dot*|z|^n": lambda w, z, n: w * _pow_abs(z, n),
    "|theta_dot|*z*|z|^n": lambda w, z, n: np.abs(w) * z * _pow_abs(z, n),
    "|theta_dot|*z*|z|^(n-1)": lambda w, z, n: np.abs(w) * np.sign(z) * _pow_abs(z, n),
}
HYSTERESIS_TERM_NAMES: tuple[str, ...] = tuple(HYSTERESIS_TERMS)

# Torque terms that depend on z (zero contribution when the model has no hysteresis).
Z_TORQUE_TERMS = ("z", "i*z", "|theta_dot|*z", "i^2*z")


@dataclass
class TermModel:
    """A model in generic term form (see module docstring).

    Parameters
    ----------
    torque : dict
        Torque term name -> coefficient (names from ``TORQUE_TERM_NAMES``).
    hysteresis : dict
        Hysteresis term name -> coefficient (names from ``HYSTERESIS_TERM_NAMES``).
    n : float
        Exponent used by the ``|z|^n`` hysteresis terms.
    J : float
        Inertia (mass); only used by ``forced`` experiments.
    """

    torque: dict[str, float] = field(default_factory=dict)
    hysteresis: dict[str, float] = field(default_factory=dict)
    n: float = 1.0
    J: float = 1.0

    def __post_init__(self) -> None:
        for name in self.torque:
            if name not in TORQUE_TERMS:
                raise HystdiscError(
                    f"unknown torque term '{name}'; fix: use one of {', '.join(TORQUE_TERM_NAMES)}"
                )
        for name in self.hysteresis:
            if name not in HYSTERESIS_TERMS:
                raise HystdiscError(
                    f"unknown hysteresis term '{name}'; fix: use one of "
                    f"{', '.join(HYSTERESIS_TERM_NAMES)}"
                )
        self.torque = {k: float(v) for k, v in self.torque.items()}
        self.hysteresis = {k: float(v) for k, v in self.hysteresis.items()}
        self.n = float(self.n)
        self.J = float(self.J)

    def torque_vector(self) -> np.ndarray:
        """Coefficients in ``TORQUE_TERM_NAMES`` order (absent terms are 0)."""
        return np.array([self.torque.get(k, 0.0) for k in TORQUE_TERM_NAMES])

    def hysteresis_vector(self) -> np.ndarray:
        """Coefficients in ``HYSTERESIS_TERM_NAMES`` order (absent terms are 0)."""
        return np.array([self.hysteresis.get(k, 0.0) for k in HYSTERESIS_TERM_NAMES])

    @property
    def has_state(self) -> bool:
        """True when the model carries a hysteretic state ``z``."""
        return any(v != 0.0 for v in self.hysteresis.values())

    def eval_torque(self, theta, theta_dot, z, i) -> np.ndarray:
        """Damper (plus spring) torque for arrays of states at current(s) ``i``."""
        out = np.zeros(np.broadcast(theta, theta_dot, z, i).shape)
        for name, c in self.torque.items():
            if c != 0.0:
                out = out + c * TORQUE_TERMS[name](theta, theta_dot, z, i)
        return out

    def eval_rate(self, theta_dot, z) -> np.ndarray:
        """Hysteretic rate ``dz/dt``."""
        out = np.zeros(np.broadcast(theta_dot, z).shape)
        for name, c in self.hysteresis.items():
            if c != 0.0:
                out = out + c * HYSTERESIS_TERMS[name](theta_dot, z, self.n)
        return out

    def __add__(self, other: TermModel) -> TermModel:
        torque = dict(self.torque)
        for k, v in other.torque.items():
            torque[k] = torque.get(k, 0.0) + v
        hyst = dict(self.hysteresis)
        for k, v in other.hysteresis.items():
            hyst[k] = hyst.get(k, 0.0) + v
        return TermModel(torque, hyst, self.n, self.J)

    def equations(self, precision: int = 4) -> str:
        """pysindy-style two-line print of the model."""

        def power(e: float) -> str:  # "*|z|^e", written plainly for e = 0 and 1
            txt = f"{e:.{precision}g}"
            return {"0": "", "1": "*|z|"}.get(txt, f"*|z|^{txt}")

        rate = format_equation("dz/dt", self.hysteresis, precision)
        rate = rate.replace("*|z|^(n-1)", power(self.n - 1.0)).replace("*|z|^n", power(self.n))
        return format_equation("T", self.torque, precision) + "\n" + rate


def format_equation(lhs: str, coefs: Mapping[str, float], precision: int = 4) -> str:
    """Format ``lhs = c1 term1 + c2 term2`` like pysindy's ``print()``."""
    parts = []
    for name, c in coefs.items():
        if c == 0.0:
            continue
        term = "" if name == "1" else f" {name}"
        parts.append(f"{c:.{precision}g}{term}")
    rhs = " + ".join(parts) if parts else "0"
    return f"{lhs} = {rhs}".replace("+ -", "- ")


@dataclass(frozen=True)
class Param:
    """A named parameter with unit, physical bounds and a demo default."""

    name: str
    unit: str
    lower: float
    upper: float
    default: float
    doc: str = ""


_BIG = 1e9

RIG_PARAMS = (
    Param("k_s", "N*m/rad per unit J", 0.0, _BIG, 158.0, "rig spring stiffness"),
    Param("J", "kg*m^2", 1e-12, _BIG, 1.0, "inertia (forced experiments only)"),
)


class Family:
    """One model family: its parameters and its mapping to and from the term form."""

    name: str = ""
    title: str = ""
    params: tuple[Param, ...] = ()
    normalization: str = ""
    torque_terms: tuple[str, ...] = ()
    hysteresis_terms: tuple[str, ...] = ()
    #: Parameters that multiply the current (fixed at 0 when every run has one current).
    current_params: tuple[str, ...] = ()

    def param_names(self) -> list[str]:
        """Names of the damper parameters (rig parameters excluded)."""
        return [p.name for p in self.params]

    def defaults(self) -> dict[str, float]:
        """Demo defaults of the damper parameters."""
        return {p.name: p.default for p in self.params}

    def to_terms(self, p: Mapping[str, float]) -> TermModel:  # pragma: no cover - abstract
        raise NotImplementedError

    def from_terms(self, tm: TermModel) -> dict[str, float]:  # pragma: no cover - abstract
        raise NotImplementedError

    def equations(self) -> str:  # pragma: no cover - abstract
        raise NotImplementedError

    def __repr__(self) -> str:
        return f"<Family {self.name}: {', '.join(self.param_names())}>"


class Bingham(Family):
    name = "bingham"
    title = "Bingham"
    params = (
        Param("c_a", "N*m*s/rad", 0.0, _BIG, 0.8, "passive viscous damping"),
        Param("c_b", "N*m*s/(rad*A)", 0.0, _BIG, 0.6, "current-dependent viscous damping"),
        Param("f_a", "N*m", 0.0, _BIG, 0.3, "passive yield (Coulomb) torque"),
        Param("f_b", "N*m/A", 0.0, _BIG, 1.0, "current-dependent yield torque"),
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


class Dahl(Family):
    name = "dahl"
    title = "Dahl"
    params = (
        Param("k_x", "N*m*s/rad", 0.0, _BIG, 0.8, "viscous damping"),
        Param("k_wa", "N*m", 0.0, _BIG, 0.5, "passive hysteretic torque"),
        Param("k_wb", "N*m/A", 0.0, _BIG, 1.5, "current-dependent hysteretic torque"),
        Param("rho", "1/rad", 1e-9, _BIG, 20.0, "hysteresis rate (loop sharpness)"),
    )
    normalization = "w saturates at 1 (by construction)"
    current_params = ("k_wb",)
    torque_terms = ("theta_dot", "z", "i*z")
    hysteresis_terms = ("theta_dot", "|theta_dot|*z")

    def to_terms(self, p):
        return TermModel(
            {"theta_dot": p["k_x"], "z": p["k_wa"], "i*z": p["k_wb"]},
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

    def equations(self):
        return "T = k_x*theta_dot + (k_wa + k_wb*i)*z\ndz/dt = rho*(theta_dot - |theta_dot|*z)"


class LuGre(Family):
    name = "lugre"
    title = "LuGre"
    params = (
        Param("sigma_a", "N*m/rad", 0.0, _BIG, 10.0, "passive stiffness of z"),
        Param("sigma_0", "N*m/(rad*A)", 1e-9, _BIG, 30.0, "current-dependent stiffness of z"),
        Param("sigma_1", "N*m*s/rad", 0.0, _BIG, 0.5, "damping of z (acts through dz/dt)"),
        Param("sigma_2", "N*m*s/rad", 0.0, _BIG, 0.5, "viscous damping"),
        Param("sigma_b", "N*m*s/(rad*A)", 0.0, _BIG, 0.6, "current-dependent viscous damping"),
        Param("a_0", "A/(N*m)", 1e-12, _BIG, 2.0 / 3.0, "rate constant (z_sat = 1/(sigma_0 a_0))"),
    )
    normalization = (
        "seed scale (dz/dt = theta_dot - sigma_0 a_0 |theta_dot| z; z_sat = 1/(sigma_0 a_0))"
    )
    torque_terms = ("theta_dot", "i*theta_dot", "z", "i*z", "|theta_dot|*z")
    hysteresis_terms = ("theta_dot", "|theta_dot|*z")
    current_params = ("sigma_b",)

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

    def equations(self):
        return (
            "T = sigma_a*z + sigma_0*i*z + sigma_1*dz/dt + sigma_2*theta_dot + sigma_b*i*theta_dot\n"
            "dz/dt = theta_dot - sigma_0*a_0*|theta_dot|*z"
        )


class BoucWen(Family):
    """Bouc-Wen in the seed's printed form: dz = -gamma|w| z|z|^n - beta w |z|^n + delta w."""

    name = "bouc-wen"
    title = "Bouc-Wen (seed form)"
    params = (
        Param("alpha_1", "N*m", 0.0, _BIG, 0.5, "passive hysteretic torque"),
        Param("alpha_2", "N*m/A", 0.0, _BIG, 1.5, "current-dependent hysteretic torque"),
        Param("c_1", "N*m*s/rad", 0.0, _BIG, 0.5, "passive viscous damping"),
        Param("c_2", "N*m*s/(rad*A)", 0.0, _BIG, 0.6, "current-dependent viscous damping"),
        Param("beta", "1/rad", -_BIG, _BIG, 10.0, "shape (theta_dot |z|^n term)"),
        Param("gamma", "1/rad", -_BIG, _BIG, 10.0, "shape (|theta_dot| z |z|^n term)"),
        Param("delta", "1/rad", 1e-12, _BIG, 20.0, "initial slope of z against theta"),
        Param("n", "-", 1e-4, 10.0, 1.0, "exponent"),
    )
    normalization = "z_sat = 1 (delta = beta + gamma)"
    current_params = ("alpha_2", "c_2")
    torque_terms = ("theta_dot", "i*theta_dot", "z", "i*z")
    hysteresis_terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^n")
    _gamma_term = "|theta_dot|*z*|z|^n"

    def to_terms(self, p):
        return TermModel(
            {
                "z": p["alpha_1"],
                "i*z": p["alpha_2"],
                "theta_dot": p["c_1"],
                "i*theta_dot": p["c_2"],
            },
            {"theta_dot": p["delta"], "theta_dot*|z|^n": -p["beta"], self._gamma_term: -p["gamma"]},
            n=p["n"],
        )

    def z_sat(self, delta: float, beta: float, gamma: float, n: float) -> float:
        """Saturation value of z on a monotone loading branch (root of delta = beta s^n + gamma s^(n+1))."""
        from scipy.optimize import brentq

        def f(s):
            return delta - beta * s**n - gamma * s ** (n + 1 if self.name == "bouc-wen" else n)

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
            "gamma": gamma * s**n,
            "delta": delta / s,
            "n": n,
        }

    def equations(self):
        return (
            "T = (alpha_1 + alpha_2*i)*z + (c_1 + c_2*i)*theta_dot\n"
            "dz/dt = -gamma*|theta_dot|*z*|z|^n - beta*theta_dot*|z|^n + delta*theta_dot"
        )


class BoucWenStd(BoucWen):
    """Standard Bouc-Wen: dz = delta w - beta w |z|^n - gamma |w| z |z|^(n-1)."""

    name = "bouc-wen-std"
    title = "Bouc-Wen (standard form)"
    params = (
        Param("alpha_1", "N*m", 0.0, _BIG, 0.5, "passive hysteretic torque"),
        Param("alpha_2", "N*m/A", 0.0, _BIG, 1.5, "current-dependent hysteretic torque"),
        Param("c_1", "N*m*s/rad", 0.0, _BIG, 0.5, "passive viscous damping"),
        Param("c_2", "N*m*s/(rad*A)", 0.0, _BIG, 0.6, "current-dependent viscous damping"),
        Param("beta", "1/rad", -_BIG, _BIG, 5.0, "shape (theta_dot |z|^n term)"),
        Param("gamma", "1/rad", -_BIG, _BIG, 15.0, "shape (|theta_dot| z |z|^(n-1) term)"),
        Param("delta", "1/rad", 1e-12, _BIG, 20.0, "initial slope of z against theta"),
        Param("n", "-", 1e-4, 10.0, 2.0, "exponent"),
    )
    hysteresis_terms = ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^(n-1)")
    _gamma_term = "|theta_dot|*z*|z|^(n-1)"

    def from_terms(self, tm):
        delta = tm.hysteresis.get("theta_dot", 0.0)
        beta = -tm.hysteresis.get("theta_dot*|z|^n", 0.0)
        gamma = -tm.hysteresis.get(self._gamma_term, 0.0)
        n = tm.n
        g = tm.torque.get
        s = self.z_sat(delta, beta, gamma, n)
        if not np.isfinite(s) or s <= 0:
            s = 1.0
        # standard form: both shape terms scale as s^(n-1)... after z = s*zn:
        # dzn = delta/s w - beta s^(n-1) w |zn|^n - gamma s^(n-1) |w| zn |zn|^(n-1)
        return {
            "alpha_1": g("z", 0.0) * s,
            "alpha_2": g("i*z", 0.0) * s,
            "c_1": g("theta_dot", 0.0),
            "c_2": g("i*theta_dot", 0.0),
            "beta": beta * s ** (n - 1.0),
            "gamma": gamma * s ** (n - 1.0),
            "delta": delta / s,
            "n": n,
        }

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
        >>> fam = get_family("bouc-wen-std")
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


FAMILIES: dict[str, Family] = {
    f.name: f for f in (Bingham(), Dahl(), LuGre(), BoucWen(), BoucWenStd())
}


def get_family(name: str) -> Family:
    """Look up a family by name (``bingham``, ``dahl``, ``lugre``, ``bouc-wen``, ``bouc-wen-std``)."""
    key = name.strip().lower().replace("_", "-")
    key = {"boucwen": "bouc-wen", "bw": "bouc-wen", "boucwen-std": "bouc-wen-std"}.get(key, key)
    if key not in FAMILIES:
        raise HystdiscError(f"unknown model '{name}'; fix: use one of {', '.join(FAMILIES)}")
    return FAMILIES[key]


# ----------------------------------------------------------------------------- effects


@dataclass(frozen=True)
class Effect:
    """A catalogued physical effect: parameters and the torque terms they add."""

    name: str
    params: tuple[Param, ...]
    terms: tuple[str, ...]
    doc: str
    to_torque: Callable[[Mapping[str, float], float], dict[str, float]]
    from_torque: Callable[[Mapping[str, float], float], dict[str, float]]


def _one_term_effect(name: str, param: Param, term: str, doc: str) -> Effect:
    """An effect whose single parameter is the coefficient of a single torque term."""
    return Effect(
        name,
        (param,),
        (term,),
        doc,
        lambda p, ks: {term: p[param.name]},
        lambda c, ks: {param.name: c.get(term, 0.0)},
    )


EFFECTS: dict[str, Effect] = {
    e.name: e
    for e in (
        _one_term_effect(
            "current_viscous",
            Param("c_i", "N*m*s/(rad*A)", -_BIG, _BIG, 0.6, "current-dependent viscous damping"),
            "i*theta_dot",
            "viscous damping that grows with current (the seed's finding for Dahl at 1 A)",
        ),
        _one_term_effect(
            "current_saturation",
            Param("a_ii", "N*m/A^2", -_BIG, _BIG, -0.6, "quadratic current dependence of z torque"),
            "i^2*z",
            "hysteretic torque not linear in current (saturating field): i^2 * z",
        ),
        _one_term_effect(
            "coulomb",
            Param("f_c", "N*m", -_BIG, _BIG, 0.3, "Coulomb (bearing) friction torque"),
            "sign(theta_dot)",
            "dry friction, f_c * sign(theta_dot)",
        ),
        _one_term_effect(
            "quadratic_damping",
            Param("c_q", "N*m*s^2/rad^2", -_BIG, _BIG, 0.3, "quadratic (aerodynamic) damping"),
            "theta_dot*|theta_dot|",
            "damping growing with velocity squared, c_q * theta_dot*|theta_dot|",
        ),
        _one_term_effect(
            "cubic_stiffness",
            Param("k_3", "N*m/rad^3", -_BIG, _BIG, 300.0, "cubic spring stiffness"),
            "theta^3",
            "large-angle stiffening of the spring (or gravity), k_3 * theta^3",
        ),
        Effect(
            "offset",
            (Param("theta_off", "rad", -_BIG, _BIG, 0.02, "neutral angle of the spring"),),
            ("1",),
            "the spring's neutral angle differs from the sensor zero: k_s*(theta - theta_off)",
            lambda p, ks: {"1": -ks * p["theta_off"]},
            lambda c, ks: {"theta_off": -c.get("1", 0.0) / ks if ks else 0.0},
        ),
    )
}


def get_effect(name: str) -> Effect:
    """Look up a catalogued effect by name."""
    key = name.strip().lower().replace("-", "_")
    if key not in EFFECTS:
        raise HystdiscError(f"unknown effect '{name}'; fix: use one of {', '.join(EFFECTS)}")
    return EFFECTS[key]


# ----------------------------------------------------------------------------- model


def _check_params(
    owner: str, specs: tuple[Param, ...], given: Mapping[str, float]
) -> dict[str, float]:
    known = {p.name: p for p in specs}
    for k in given:
        if k not in known:
            raise HystdiscError(
                f"{owner}: unknown parameter '{k}'; fix: use one of {', '.join(known)}"
            )
    out = {}
    for p in specs:
        v = given.get(p.name, p.default)
        try:
            v = float(v)
        except (TypeError, ValueError):
            raise HystdiscError(
                f"{owner}: parameter {p.name}={v!r} is not a number; fix: give a number"
            ) from None
        if not np.isfinite(v):
            raise HystdiscError(f"{owner}: parameter {p.name} is {v}; fix: give a finite number")
        if not (p.lower <= v <= p.upper):
            raise HystdiscError(
                f"{owner}: parameter {p.name}={v:g} is outside its physical bounds "
                f"[{p.lower:g}, {p.upper:g}]; fix: give a value within them"
            )
        out[p.name] = v
    return out


class Model:
    """A family with parameter values, rig parameters and optional effects.

    Parameters
    ----------
    family : str
        Family name (see :func:`get_family`).
    params : dict, optional
        Damper and rig parameters (``k_s``, ``J``); unset ones take the demo defaults.
    effects : dict, optional
        Effect name -> dict of its parameters (unset ones take defaults).

    Examples
    --------
    >>> m = Model("bouc-wen", {"c_2": 0.0}, effects={"coulomb": {"f_c": 0.2}})
    >>> m.to_terms().torque["sign(theta_dot)"]
    0.2
    >>> Model("dahl", {"rho": -1})
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: dahl: parameter rho=-1 is outside its physical bounds [1e-09, 1e+09]; fix: give a value within them
    """

    def __init__(
        self,
        family: str,
        params: Mapping[str, float] | None = None,
        effects: Mapping[str, Mapping[str, float]] | None = None,
    ) -> None:
        self.family = get_family(family)
        params = dict(params or {})
        specs = self.family.params + RIG_PARAMS
        self.params = _check_params(self.family.name, specs, params)
        self.effects: dict[str, dict[str, float]] = {}
        for name, ep in (effects or {}).items():
            eff = get_effect(name)
            self.effects[eff.name] = _check_params(f"effect {eff.name}", eff.params, ep or {})

    @property
    def k_s(self) -> float:
        return self.params["k_s"]

    def to_terms(self) -> TermModel:
        """The generic term form of this model (spring, damper and effects)."""
        tm = self.family.to_terms(self.params)
        tm.torque["theta"] = tm.torque.get("theta", 0.0) + self.params["k_s"]
        tm.J = self.params["J"]
        for name, ep in self.effects.items():
            for k, v in EFFECTS[name].to_torque(ep, self.params["k_s"]).items():
                tm.torque[k] = tm.torque.get(k, 0.0) + v
        return tm

    def __repr__(self) -> str:
        ps = ", ".join(f"{k}={v:g}" for k, v in self.params.items())
        eff = "".join(
            f" + {k}({', '.join(f'{pk}={pv:g}' for pk, pv in ep.items())})"
            for k, ep in self.effects.items()
        )
        return f"Model({self.family.name}{eff}: {ps})"
