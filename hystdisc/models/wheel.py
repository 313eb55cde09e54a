"""The SAS beam on a compliant wheel: a damper family with two extra states.

The seed's rig simulation takes the damper's lower end as fixed; its results suspect the
"neglected tyre damping". Here the damper acts between the beam (angle ``theta``, what
the sensor reads) and a wheel (``y``) that rests on a spring ``k_w`` and a dashpot
``c_w`` with inertia ``m_w`` (all per unit beam inertia)::

    theta'' = -k_s theta - T(r, r', z, i)              r = theta - y
    m_w y'' =  T(r, r', z, i) - k_w y - c_w y'
    z'      =  g(r', z)                                 (the family's hysteresis)

``T`` and ``g`` are the damper family's torque and rate (its term form, without the rig
spring). With a stiff wheel (``k_w`` large) the model is the seed's rig. Nothing outside
this module knows about it: it is a :class:`~hystdisc.models.system.StateSpaceModel`
like any other.

Examples
--------
>>> m = BeamOnCompliantWheel("dahl")
>>> m.states
('theta', 'theta_dot', 'z', 'y', 'y_dot')
>>> [p.name for p in m.params][-4:]
['k_s', 'm_w', 'k_w', 'c_w']
>>> p = m.run_parameters({"k_w": 2000.0}, current=0.5)
>>> p[-4:].tolist()  # k_s, m_w, k_w, c_w
[158.0, 0.2, 2000.0, 5.0]
"""

from __future__ import annotations

from collections.abc import Mapping

import numba
import numpy as np

from hystdisc.models.compiled import N_BASE, TERM_SIZE, term_torque, term_vector, vector_rate
from hystdisc.models.params import BIG, RIG_PARAMS, Param
from hystdisc.models.system import StateSpaceModel
from hystdisc.models.terms import SIGN_EPS
from hystdisc.registry import get_family

WHEEL_PARAMS = (
    Param("m_w", "kg*m^2 per unit J", 1e-9, BIG, 0.2, "wheel inertia"),
    Param("k_w", "N*m/rad per unit J", 0.0, BIG, 5000.0, "wheel (tyre) stiffness"),
    Param("c_w", "N*m*s/rad per unit J", 0.0, BIG, 5.0, "wheel (tyre) damping"),
)

# p layout: the damper's term_vector (no rig spring in it), eps, k_s, m_w, k_w, c_w
_EPS = TERM_SIZE
_KS = _EPS + 1


@numba.njit(cache=True, nogil=True)
def _rate(x, u, p, dx):
    th, w, z, y, v = x[0], x[1], x[2], x[3], x[4]
    r_dot = w - v
    T = term_torque(p[:N_BASE], th - y, r_dot, z, p[_EPS])
    dx[0] = w
    dx[1] = -p[_KS] * th - T
    dx[2] = vector_rate(p, r_dot, z)
    dx[3] = v
    dx[4] = (T - p[_KS + 2] * y - p[_KS + 3] * v) / p[_KS + 1]


@numba.njit(cache=True, nogil=True)
def _output(x, u, p):
    return x[0]


class BeamOnCompliantWheel(StateSpaceModel):
    """A damper family between the SAS beam and a compliant wheel (release experiments).

    Parameters
    ----------
    family : str
        The damper family (any registered family).
    """

    states = ("theta", "theta_dot", "z", "y", "y_dot")
    inputs = ()
    output = "theta"
    rate = staticmethod(_rate)
    observe = staticmethod(_output)

    def __init__(self, family: str = "dahl") -> None:
        self.family = get_family(family)
        self.name = f"{self.family.name} on a compliant wheel"
        self.params = (*self.family.params, RIG_PARAMS[0], *WHEEL_PARAMS)

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        v = self.check(values)
        tm = self.family.to_terms(v)  # the damper alone: no rig spring in its terms
        tail = [SIGN_EPS, v["k_s"], v["m_w"], v["k_w"], v["c_w"]]
        return np.concatenate([term_vector(tm, current), tail])

    def equations(self) -> str:
        return (
            "theta'' = -k_s*theta - T(theta - y, theta_dot - y_dot, z, i)\n"
            "m_w*y'' = T - k_w*y - c_w*y_dot\n"
            f"with T, dz/dt of {self.family.name}:\n{self.family.equations()}"
        )
