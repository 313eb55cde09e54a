"""The term library: named torque-side features on pysindy, and hysteresis-side shapes.

The torque side is linear in its coefficients once the latent state ``z`` is known, so it
is a pysindy feature library (:class:`TorqueLibrary`, a ``BaseFeatureLibrary``) evaluated
on the state ``[theta, theta_dot, z]`` with the coil current as pysindy's control input
``u`` (appended as the last column, the way ``pysindy.SINDy`` passes it).

The hysteresis side is nonlinear in a few *shape constants* (a rate, an exponent); each
candidate :class:`HysteresisShape` turns its shape constants into the coefficient vector
of the hysteretic rate, from which ``z(t)`` is integrated given the velocity record.

Examples
--------
>>> import numpy as np
>>> lib = TorqueLibrary(["theta", "theta_dot", "i*z"]).fit(np.zeros((3, 4)))
>>> lib.get_feature_names()
['theta', 'theta_dot', 'i*z']
>>> X = np.array([[0.1, 2.0, 0.5, 1.0]])  # theta, theta_dot, z, current
>>> lib.transform(X).tolist()
[[0.1, 2.0, 0.5]]
>>> SHAPES["dahl"].vector(np.log([20.0]))
(array([ 20., -20.,   0.,   0.,   0.]), 1.0)
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pysindy.feature_library.base import BaseFeatureLibrary

from hystdisc.models import (
    HYSTERESIS_TERM_NAMES,
    TORQUE_TERM_NAMES,
    TORQUE_TERMS,
    Z_TORQUE_TERMS,
)

#: Exponents searched by discovery (smaller n makes the seed form Dahl-like and the state
#: non-Lipschitz at z = 0, which no fixed-step search should chase; fit Dahl instead).
N_RANGE = (0.25, 6.0)

#: Torque-side terms of the discovery library (DESIGN.md section 3), spring first.
DEFAULT_TORQUE_TERMS: tuple[str, ...] = (
    "theta",
    "theta_dot",
    "i*theta_dot",
    "z",
    "i*z",
    "|theta_dot|*z",
    "sign(theta_dot)",
    "i*sign(theta_dot)",
)


class TorqueLibrary(BaseFeatureLibrary):
    """pysindy feature library of named torque terms of ``[theta, theta_dot, z, i]``.

    Parameters
    ----------
    terms : sequence of str
        Term names from :data:`hystdisc.models.TORQUE_TERM_NAMES`.
    """

    def __init__(self, terms: Sequence[str] = DEFAULT_TORQUE_TERMS) -> None:
        self.terms = terms

    def fit(self, x, y=None):
        unknown = [t for t in self.terms if t not in TORQUE_TERMS]
        if unknown:
            raise ValueError(f"unknown torque terms {unknown}; known: {TORQUE_TERM_NAMES}")
        x = np.asarray(x)
        if x.ndim != 2 or x.shape[1] != 4:
            raise ValueError("TorqueLibrary expects columns [theta, theta_dot, z, i]")
        self.n_features_in_ = 4
        self.n_output_features_ = len(self.terms)
        return self

    def transform(self, x):
        x = np.asarray(x, dtype=float)
        th, w, z, i = x[:, 0], x[:, 1], x[:, 2], x[:, 3]
        return np.column_stack([TORQUE_TERMS[t](th, w, z, i) for t in self.terms])

    def get_feature_names(self, input_features=None) -> list[str]:
        return list(self.terms)


@dataclass(frozen=True)
class HysteresisShape:
    """A hysteresis-side candidate: its terms and the map shape constants -> rate coefficients.

    Shape constants are handled in an unconstrained space: rates as ``log`` values, the
    exponent as ``log n``. The seed-form Bouc-Wen splits ``delta`` as ``beta = phi * delta``,
    ``gamma = (1 - phi) * delta`` (``z_sat = 1``). The standard form uses an angle instead,
    ``beta = delta cos(psi)``, ``gamma = delta sin(psi)``, which also covers loops that never
    saturate (``beta + gamma <= 0``, as in the Noel-Schoukens hysteretic benchmark).
    """

    name: str
    terms: tuple[str, ...]
    shape_names: tuple[str, ...]

    def vector(self, s: np.ndarray) -> tuple[np.ndarray, float]:
        """Rate coefficients (in ``HYSTERESIS_TERM_NAMES`` order) and exponent for ``s``."""
        b = np.zeros(len(HYSTERESIS_TERM_NAMES))
        if self.name == "none":
            return b, 1.0
        if self.name == "dahl":
            rho = float(np.exp(s[0]))
            b[0], b[1] = rho, -rho
            return b, 1.0
        d = self.shape_dict(s)
        b[0] = d["delta"]
        b[2] = -d["beta"]
        b[3 if self.name == "bouc-wen" else 4] = -d["gamma"]
        return b, d["n"]

    def grid(self, scale: float) -> list[np.ndarray]:
        """Starting grid of shape constants for a displacement amplitude ``scale``."""
        if self.name == "none":
            return [np.zeros(0)]
        rates = np.log(np.geomspace(0.3, 300.0, 13) / max(scale, 1e-12))
        if self.name == "dahl":
            return [np.array([r]) for r in rates]
        # seed form: phi; standard form: psi (saturating at 0..120 deg and -30 deg, never
        # saturating at 150, 170 and -70 deg)
        splits = (
            (-0.5, 0.0, 0.5, 0.9)
            if self.name == "bouc-wen"
            else np.deg2rad((0.0, 45.0, 90.0, 120.0, -30.0, 150.0, 170.0, -70.0))
        )
        out = []
        for r in rates[::2]:
            for phi in splits:
                for n in (0.5, 1.0, 2.0):
                    out.append(np.array([r, phi, np.log(n)]))
        return out

    def clip(self, s: np.ndarray, scale: float) -> np.ndarray:
        """Keep shape constants in the searched box (rates 0.1..300 per amplitude ``scale``;
        beyond it z is a sign function, which the Bingham terms already cover)."""
        s = np.asarray(s, dtype=float).copy()
        if self.name == "none":
            return s
        lo = np.log(0.1 / max(scale, 1e-12))
        s[0] = np.clip(s[0], lo, lo + np.log(3e3))
        if self.name == "bouc-wen":
            s[1] = np.clip(s[1], -3.0, 3.0)
        elif self.name == "bouc-wen-std":
            s[1] = np.angle(np.exp(1j * s[1]))  # wrap to (-pi, pi]
        if self.name != "dahl":
            s[2] = np.clip(s[2], np.log(N_RANGE[0]), np.log(N_RANGE[1]))
        return s

    def shape_dict(self, s: np.ndarray) -> dict[str, float]:
        """Shape constants in physical units (``rho`` or ``delta, beta, gamma, n``)."""
        if self.name == "none":
            return {}
        if self.name == "dahl":
            return {"rho": float(np.exp(s[0]))}
        delta = float(np.exp(s[0]))
        if self.name == "bouc-wen-std":
            beta, gamma = delta * float(np.cos(s[1])), delta * float(np.sin(s[1]))
        else:
            beta, gamma = float(s[1]) * delta, (1.0 - float(s[1])) * delta
        return {
            "delta": delta,
            "beta": beta,
            "gamma": gamma,
            "n": float(np.clip(np.exp(s[2]), N_RANGE[0], N_RANGE[1])),
        }


SHAPES: dict[str, HysteresisShape] = {
    "none": HysteresisShape("none", (), ()),
    "dahl": HysteresisShape("dahl", ("theta_dot", "|theta_dot|*z"), ("log_rho",)),
    "bouc-wen": HysteresisShape(
        "bouc-wen",
        ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^n"),
        ("log_delta", "phi", "log_n"),
    ),
    "bouc-wen-std": HysteresisShape(
        "bouc-wen-std",
        ("theta_dot", "theta_dot*|z|^n", "|theta_dot|*z*|z|^(n-1)"),
        ("log_delta", "psi", "log_n"),
    ),
}

#: Hysteresis shape of each family (LuGre shares Dahl's, on another z scale).
FAMILY_SHAPE = {
    "bingham": "none",
    "dahl": "dahl",
    "lugre": "dahl",
    "bouc-wen": "bouc-wen",
    "bouc-wen-std": "bouc-wen-std",
}


def torque_terms_for(shape: str, terms: Sequence[str]) -> list[str]:
    """Drop the z-dependent torque terms when the shape carries no state."""
    if shape == "none":
        return [t for t in terms if t not in Z_TORQUE_TERMS]
    return list(terms)
