"""Series compliance: the SAS beam on a compliant wheel, a driven damper on a compliant mount.

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

In a driven experiment the same internal degree of freedom sits between the motion the
sensor measures (the actuator's ``x``) and the damper: the damper's end ``y`` (mass
``m_w``) is tied to ``x`` by a spring ``k_w`` and a dashpot ``c_w`` (bushings, mounts, a
compliant fixture; Spencer's internal spring in its simplest form), and the load cell
reads the damper's force on its fixed end (:class:`TermsOnCompliantMount`)::

    m_w y'' = k_w (x - y) + c_w (x' - y') - T(y, y', z, i)
    z'      = g(y', z)
    F       = T(y, y', z, i)

:func:`series_compliance_system` picks the realization for the experiment.

:class:`TermsOnCompliantWheel` is the same rig around any model in term form (a family
plus effects, as a fit builds it): the structural effect ``series_compliance``. The
terms in ``theta`` alone (:data:`RIG_TERMS`: the spring, its offset and cubic
stiffening) act between the beam and the ground; every other term acts across the
damper, on the relative motion ``r = theta - y``.

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

from hystdisc.models.compiled import (
    N_BASE,
    TERM_SIZE,
    base_coefficients,
    rate_grad,
    term_torque,
    term_vector,
    torque_grad,
    vector_rate,
)
from hystdisc.models.effects import Effect, Structure
from hystdisc.models.params import BIG, RIG_PARAMS, Param
from hystdisc.models.system import StateSpaceModel
from hystdisc.models.terms import SIGN_EPS, TermModel
from hystdisc.registry import get_experiment, get_family

#: The wheel's parameters (per unit beam inertia): those of the ``series_compliance`` effect.
WHEEL_PARAMS: tuple[Param, ...] = (
    Param(
        "m_w",
        "kg*m^2 per unit J (release); kg (driven)",
        1e-9,
        BIG,
        0.2,
        "wheel inertia, or the damper end's mass (series mass)",
    ),
    Param(
        "k_w",
        "N*m/rad per unit J (release); N/m (driven)",
        1e-9,
        BIG,
        5000.0,
        "wheel (tyre) or mount stiffness",
    ),
    Param(
        "c_w",
        "N*m*s/rad per unit J (release); N*s/m (driven)",
        0.0,
        BIG,
        5.0,
        "wheel (tyre) or mount damping",
    ),
)

#: Torque terms of the rig (beam to ground), not of the damper.
RIG_TERMS = ("theta", "theta^3", "1")

# p layout: the damper's term_vector (N_BASE + 6: no rig spring in it), eps, k_s, m_w,
# k_w, c_w
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


# p layout (terms on a wheel): the damper's term_vector, the rig's base coefficients,
# eps, m_w, k_w, c_w
_RIG = TERM_SIZE
_EPS2 = _RIG + N_BASE
_MW = _EPS2 + 1


@numba.njit(cache=True, nogil=True)
def _terms_rate(x, u, p, dx):
    th, w, z, y, v = x[0], x[1], x[2], x[3], x[4]
    r_dot = w - v
    T = term_torque(p[:N_BASE], th - y, r_dot, z, p[_EPS2])
    R = term_torque(p[_RIG:_EPS2], th, w, 0.0, p[_EPS2])
    dx[0] = w
    dx[1] = -R - T
    dx[2] = vector_rate(p, r_dot, z)
    dx[3] = v
    dx[4] = (T - p[_MW + 1] * y - p[_MW + 2] * v) / p[_MW]


# ---- partial derivatives, for the exact sensitivities (hystdisc.simulation.sensitivity_ode);
# work: dT/dc of the damper (N_BASE), dR/d(b, n) of its rate (6, from _WR), dR/dc of the
# rig (N_BASE, from _WG)
_WR = N_BASE
_WG = N_BASE + 6


@numba.njit(cache=True, inline="always")
def _hysteresis_rows(jp, i, work):
    """Row ``i`` (``z' = R(w, z)``) of ``d rate / d p``: the rate's coefficients and
    exponent (the term vector's hysteresis side), from ``work[_WR : _WR + 6]``."""
    for q in range(6):
        jp[i, N_BASE + q] = work[_WR + q]


@numba.njit(cache=True, nogil=True)
def _terms_rate_jac(x, u, p, need, jx, jp, work):
    th, w, z, y, v = x[0], x[1], x[2], x[3], x[4]
    eps, mw, kw, cw = p[_EPS2], p[_MW], p[_MW + 1], p[_MW + 2]
    tr, tw, tz = torque_grad(p[:N_BASE], th - y, w - v, z, eps, need[:N_BASE], work[:N_BASE])
    gth, gw, _ = torque_grad(
        p[_RIG:_EPS2], th, w, 0.0, eps, need[_RIG:_EPS2], work[_WG : _WG + N_BASE]
    )
    rw, rz = rate_grad(
        p[N_BASE : TERM_SIZE - 1], p[TERM_SIZE - 1], w - v, z, need[N_BASE:TERM_SIZE],
        work[_WR : _WR + 6],
    )  # fmt: skip
    force = term_torque(p[:N_BASE], th - y, w - v, z, eps)
    # theta'' = -R(theta, w) - T(theta - y, w - v, z)
    jx[0, 1] = 1.0
    jx[1, 0] = -(gth + tr)
    jx[1, 1] = -(gw + tw)
    jx[1, 2] = -tz
    jx[1, 3] = tr
    jx[1, 4] = tw
    for i in range(N_BASE):
        jp[1, i] = -work[i]
        jp[1, _RIG + i] = -work[_WG + i]
    # z' = R(w - v, z)
    jx[2, 1] = rw
    jx[2, 2] = rz
    jx[2, 4] = -rw
    _hysteresis_rows(jp, 2, work)
    # m_w y'' = T - k_w y - c_w v
    jx[3, 4] = 1.0
    jx[4, 0] = tr / mw
    jx[4, 1] = tw / mw
    jx[4, 2] = tz / mw
    jx[4, 3] = -(tr + kw) / mw
    jx[4, 4] = -(tw + cw) / mw
    for i in range(N_BASE):
        jp[4, i] = work[i] / mw
    jp[4, _MW] = -(force - kw * y - cw * v) / (mw * mw)
    jp[4, _MW + 1] = -y / mw
    jp[4, _MW + 2] = -v / mw


@numba.njit(cache=True, nogil=True)
def _angle_grad(x, u, p, need, gx, gp, work):
    gx[0] = 1.0


class TermsOnCompliantWheel(StateSpaceModel):
    """A model in term form between the SAS beam and a compliant wheel (release).

    The structural effect ``series_compliance``: the rig terms of ``terms``
    (:data:`RIG_TERMS`) act on the beam, every other term across the damper on
    ``theta - y``; the parameters are the wheel's (``m_w``, ``k_w``, ``c_w`` per unit
    beam inertia).

    Parameters
    ----------
    terms : TermModel
        Damper, rig spring and term effects (e.g. ``Model("dahl").to_terms()``).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> m = TermsOnCompliantWheel(Model("dahl").to_terms())
    >>> [p.name for p in m.params], m.states[3:]
    (['m_w', 'k_w', 'c_w'], ('y', 'y_dot'))
    >>> m.run_parameters({"k_w": 900.0}, current=0.0)[-3:].tolist()
    [0.2, 900.0, 5.0]
    """

    states = ("theta", "theta_dot", "z", "y", "y_dot")
    inputs = ()
    output = "theta"
    rate = staticmethod(_terms_rate)
    observe = staticmethod(_output)
    rate_jac = staticmethod(_terms_rate_jac)
    observe_grad = staticmethod(_angle_grad)
    params = WHEEL_PARAMS

    def __init__(self, terms: TermModel) -> None:
        self.terms = terms
        self.name = "term model on a compliant wheel"
        rig = {k: v for k, v in terms.torque.items() if k in RIG_TERMS}
        damper = {k: v for k, v in terms.torque.items() if k not in RIG_TERMS}
        self.rig = TermModel(rig)
        self.damper = TermModel(
            damper, dict(terms.hysteresis), terms.n, terms.J, terms.m, saturation=terms.saturation
        )

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        v = self.check(values)
        tail = [SIGN_EPS, v["m_w"], v["k_w"], v["c_w"]]
        return np.concatenate(
            [term_vector(self.damper, current), base_coefficients(self.rig, current), tail]
        )

    def equations(self) -> str:
        return (
            "theta'' = -R(theta) - T(theta - y, theta_dot - y_dot, z, i)\n"
            "m_w*y'' = T - k_w*y - c_w*y_dot\n"
            f"with R the rig terms ({', '.join(self.rig.torque) or 'none'}) and T, dz/dt of:\n"
            f"{self.damper.equations()}"
        )


# p layout (terms on a mount, driven): the damper's term_vector, eps, m_w, k_w, c_w
_EPS3 = TERM_SIZE


@numba.njit(cache=True, nogil=True)
def _mount_rate(x, u, p, dx):
    # states: the mount's deflection d = x - y, the damper end's velocity v, z;
    # inputs: the measured motion and its velocity
    d, v, z = x[0], x[1], x[2]
    T = term_torque(p[:N_BASE], u[0] - d, v, z, p[_EPS3])
    dx[0] = u[1] - v
    dx[1] = (p[_EPS3 + 2] * d + p[_EPS3 + 3] * (u[1] - v) - T) / p[_EPS3 + 1]
    dx[2] = vector_rate(p, v, z)


@numba.njit(cache=True, nogil=True)
def _mount_output(x, u, p):
    return term_torque(p[:N_BASE], u[0] - x[0], x[1], x[2], p[_EPS3])


@numba.njit(cache=True, nogil=True)
def _mount_rate_jac(x, u, p, need, jx, jp, work):
    d, v, z = x[0], x[1], x[2]
    eps, mw, kw, cw = p[_EPS3], p[_EPS3 + 1], p[_EPS3 + 2], p[_EPS3 + 3]
    # T at the damper's end y = x - d: its partial in d is -dT/dy
    ty, tv, tz = torque_grad(p[:N_BASE], u[0] - d, v, z, eps, need[:N_BASE], work[:N_BASE])
    rw, rz = rate_grad(
        p[N_BASE : TERM_SIZE - 1], p[TERM_SIZE - 1], v, z, need[N_BASE:TERM_SIZE],
        work[_WR : _WR + 6],
    )  # fmt: skip
    force = term_torque(p[:N_BASE], u[0] - d, v, z, eps)
    jx[0, 1] = -1.0
    # m_w y'' = k_w d + c_w (x' - v) - T
    jx[1, 0] = (kw + ty) / mw
    jx[1, 1] = -(cw + tv) / mw
    jx[1, 2] = -tz / mw
    for i in range(N_BASE):
        jp[1, i] = -work[i] / mw
    jp[1, _EPS3 + 1] = -(kw * d + cw * (u[1] - v) - force) / (mw * mw)
    jp[1, _EPS3 + 2] = d / mw
    jp[1, _EPS3 + 3] = (u[1] - v) / mw
    jx[2, 1] = rw
    jx[2, 2] = rz
    _hysteresis_rows(jp, 2, work)


@numba.njit(cache=True, nogil=True)
def _mount_output_grad(x, u, p, need, gx, gp, work):
    d, v, z = x[0], x[1], x[2]
    ty, tv, tz = torque_grad(p[:N_BASE], u[0] - d, v, z, p[_EPS3], need[:N_BASE], gp[:N_BASE])
    gx[0] = -ty
    gx[1] = tv
    gx[2] = tz


class TermsOnCompliantMount(StateSpaceModel):
    """A model in term form behind a compliant mount (driven experiments).

    The structural effect ``series_compliance`` when the motion is imposed: every term of
    ``terms`` acts across the damper on ``y = x - d``, where ``d`` is the deflection of the
    mount (spring ``k_w``, dashpot ``c_w``, the damper end's mass ``m_w``) between the
    measured motion ``x`` and the damper; the output is the damper's force. Both start at
    rest relative to the ground (``d = 0``, ``y' = 0``).

    Parameters
    ----------
    terms : TermModel
        The damper and its term effects (e.g. ``Model("bouc-wen-std").to_terms()``).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> m = TermsOnCompliantMount(Model("bouc-wen-std").to_terms())
    >>> m.states, m.inputs
    (('d', 'y_dot', 'z'), ('theta', 'theta_dot'))
    >>> m.run_parameters({"k_w": 3e5}, current=0.0)[-3:].tolist()
    [0.2, 300000.0, 5.0]
    """

    states = ("d", "y_dot", "z")
    inputs = ("theta", "theta_dot")
    output = "torque"
    rate = staticmethod(_mount_rate)
    observe = staticmethod(_mount_output)
    rate_jac = staticmethod(_mount_rate_jac)
    observe_grad = staticmethod(_mount_output_grad)
    params = WHEEL_PARAMS

    def __init__(self, terms: TermModel) -> None:
        self.terms = terms
        self.name = "term model behind a compliant mount"

    def run_parameters(self, values: Mapping[str, float], current: float) -> np.ndarray:
        v = self.check(values)
        tail = [SIGN_EPS, v["m_w"], v["k_w"], v["c_w"]]
        return np.concatenate([term_vector(self.terms, current), tail])

    def equations(self) -> str:
        return (
            "m_w*y'' = k_w*(theta - y) + c_w*(theta_dot - y_dot) - T(y, y_dot, z, i)\n"
            "measured: T\n"
            f"with T, dz/dt of:\n{self.terms.equations()}"
        )


def series_compliance_system(terms: TermModel, experiment: str = "release") -> StateSpaceModel:
    """The ``series_compliance`` realization of ``terms`` for ``experiment``: the beam on
    a compliant wheel (release) or the damper behind a compliant mount (driven).

    Examples
    --------
    >>> from hystdisc.models import Model
    >>> type(series_compliance_system(Model("dahl").to_terms(), "driven")).__name__
    'TermsOnCompliantMount'
    """
    if get_experiment(experiment).motion_imposed:
        return TermsOnCompliantMount(terms)
    return TermsOnCompliantWheel(terms)


SERIES_COMPLIANCE = Effect(
    "series_compliance",
    WHEEL_PARAMS,
    (),
    "an internal degree of freedom: the damper acts on a wheel on a spring and dashpot "
    "(release: k_w, c_w, inertia m_w per unit beam inertia), not on the ground; or the "
    "damper sits behind a compliant mount (driven: k_w, c_w between the measured motion "
    "and the damper end of mass m_w)",
    lambda p, ks: {},
    lambda c, ks: {},
    structure=Structure(series_compliance_system, "m_w", "k_w", "c_w"),
    significance=("k_w",),
    experiments=("release", "driven"),
    rig=True,
)
"""Series compliance (structural: :func:`series_compliance_system`): the SAS beam on a
compliant wheel (release) or the damper behind a compliant mount (driven). Its
significance is that of the compliance ``1/k_w`` (the same z-score as ``k_w``): a stiff
wheel or mount whose ``k_w`` the data do not bound is the model without it."""
