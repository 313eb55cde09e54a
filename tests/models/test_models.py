"""The models layer: parameters, the registry, state-space systems and their integrator.

The two-extra-state model (the SAS beam on a compliant wheel) is simulated by the one
generic integrator and held against ``scipy.integrate.solve_ivp`` with an independent
right-hand side written out here from the equations.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from hystdisc import registry
from hystdisc.errors import HystdiscError
from hystdisc.models import FAMILIES, Model, TermModel
from hystdisc.models.system import TermSystem
from hystdisc.models.wheel import BeamOnCompliantWheel, TermsOnCompliantMount
from hystdisc.simulation import simulate_driven, simulate_forced, simulate_release
from hystdisc.simulation.ode import simulate_system

T = np.arange(0.0, 3.0, 1e-3)


def _dahl_wheel_rhs(p, current):
    """theta'' = -k_s theta - T, m_w y'' = T - k_w y - c_w y', Dahl on r' = theta' - y'."""

    def f(t, x):
        th, w, z, y, v = x
        rd = w - v
        T = p["k_x"] * rd + (p["k_wa"] + p["k_wb"] * current) * z
        return [
            w,
            -p["k_s"] * th - T,
            p["rho"] * (rd - abs(rd) * z),
            v,
            (T - p["k_w"] * y - p["c_w"] * v) / p["m_w"],
        ]

    return f


@pytest.mark.parametrize("current", [0.0, 0.5, 1.0])
def test_compliant_wheel_matches_solve_ivp(current):
    # parameter values picked within the physical bounds, away from the demo defaults
    values = {"k_x": 0.6, "k_wa": 0.4, "k_wb": 1.2, "rho": 25.0, "k_s": 150.0}
    values |= {"m_w": 0.3, "k_w": 900.0, "c_w": 3.0}
    model = BeamOnCompliantWheel("dahl")
    x0 = model.initial_state(theta=0.3)
    ours = simulate_system(model, T, x0, values, current=current, rtol=1e-10, atol=1e-13)
    ref = solve_ivp(
        _dahl_wheel_rhs(model.check(values), current),
        (T[0], T[-1]),
        x0,
        method="DOP853",
        t_eval=T,
        rtol=1e-12,
        atol=1e-14,
    )
    assert ref.success
    for j, name in enumerate(model.states):
        scale = np.max(np.abs(ref.y[j]))
        assert np.max(np.abs(ours.x[name] - ref.y[j])) < 1e-7 * scale, name
    assert np.array_equal(ours.y, ours.x["theta"])
    # the wheel really moves: the extra states matter to the measured angle
    assert np.ptp(ours.x["y"]) > 1e-3 * np.ptp(ours.x["theta"])


def test_stiff_wheel_is_the_seed_rig():
    """With a very stiff, heavy-damped wheel the beam moves as on the fixed rig."""
    model = BeamOnCompliantWheel("bouc-wen")
    vals = {"k_w": 1e6, "c_w": 2e3, "m_w": 1.0}
    out = simulate_system(model, T, model.initial_state(theta=0.3), vals, current=0.5)
    rig = simulate_release(Model("bouc-wen"), T, current=0.5, theta0=0.3)
    assert np.max(np.abs(out.x["theta"] - rig.theta)) < 2e-3 * 0.3


def test_compliant_mount_matches_solve_ivp():
    """The driven damper behind a mount: the mount's equations written out here, the
    damper's torque and rate from the term model's own (numpy) evaluation."""
    values = {"alpha_1": 0.4, "alpha_2": 1.2, "c_1": 0.3, "c_2": 0.5, "beta": 4.0}
    values |= {"gamma": 12.0, "n": 2.0, "k_s": 50.0}
    tm = Model("bouc-wen-std", values).to_terms()
    mount = {"m_w": 0.05, "k_w": 500.0, "c_w": 3.0}
    model = TermsOnCompliantMount(tm)
    om, amp, current = 2 * np.pi * 2.0, 0.3, 0.5

    th, w = amp * np.sin(om * T), amp * om * np.cos(om * T)

    def rhs(t, s):
        d, v, z = s
        x, xd = np.interp(t, T, th), np.interp(t, T, w)  # the simulator's linear inputs
        force = float(tm.eval_torque(x - d, v, z, current))
        acc = (mount["k_w"] * d + mount["c_w"] * (xd - v) - force) / mount["m_w"]
        return [xd - v, acc, float(tm.eval_rate(v, z))]

    ours = simulate_system(
        model,
        T,
        model.initial_state(),
        mount,
        current,
        {"theta": th, "theta_dot": w},
        rtol=1e-10,
        atol=1e-13,
    )
    ref = solve_ivp(
        rhs, (T[0], T[-1]), [0.0, 0.0, 0.0], method="DOP853", t_eval=T, rtol=1e-12, atol=1e-14
    )
    assert ref.success
    force = tm.eval_torque(th - ref.y[0], ref.y[1], ref.y[2], current)
    assert np.max(np.abs(ours.y - force)) < 1e-6 * np.max(np.abs(force))
    # the mount really deflects: a few per cent of the motion
    assert np.ptp(ours.x["d"]) > 0.01 * np.ptp(th)
    # a very stiff mount is the damper driven directly
    stiff = {"m_w": 1e-3, "k_w": 1e7, "c_w": 2e2}
    rigid = simulate_driven(tm, T, current=current, theta=th, theta_dot=w)
    out = simulate_system(
        model, T, model.initial_state(), stiff, current, {"theta": th, "theta_dot": w}
    )
    late = T > 0.2  # after the mount's start-up from rest
    assert np.max(np.abs(out.y - rigid.torque)[late]) < 2e-3 * np.max(np.abs(rigid.torque))


@pytest.mark.parametrize("family", registry.term_family_names())
def test_term_system_matches_fixed_step_kernels(family):
    """Both integrators of the term form agree (release, forced and driven)."""
    tm = Model(family).to_terms()
    rel = simulate_release(tm, T, current=0.5, theta0=0.3)
    sys = TermSystem(tm, "release")
    out = simulate_system(sys, T, sys.initial_state(theta=0.3), current=0.5)
    assert np.max(np.abs(out.y - rel.theta)) < 1e-6 * 0.3

    tm.J = 2.0
    u = 0.5 * np.sin(2 * np.pi * 1.5 * T)
    forced = simulate_forced(tm, T, current=0.5, u=u, hold="linear")
    fsys = TermSystem(tm, "forced")
    out = simulate_system(fsys, T, fsys.initial_state(), current=0.5, inputs={"u": u})
    assert np.max(np.abs(out.y - forced.theta)) < 1e-6 * np.ptp(forced.theta)

    th = 0.2 * np.sin(2 * np.pi * T)
    w = 0.4 * np.pi * np.cos(2 * np.pi * T)
    drv = simulate_driven(tm, T, current=0.5, theta=th, theta_dot=w)
    dsys = TermSystem(tm, "driven")
    out = simulate_system(dsys, T, [0.0], current=0.5, inputs={"theta": th, "theta_dot": w})
    assert np.max(np.abs(out.y - drv.torque)) < 1e-6 * np.max(np.abs(drv.torque))


def test_simulate_system_errors():
    sys = TermSystem(TermModel({"theta": 1.0}), "forced")
    with pytest.raises(HystdiscError, match="input\\(s\\) u missing; fix: pass inputs"):
        simulate_system(sys, T, sys.initial_state())
    with pytest.raises(HystdiscError, match="initial state has 2 values"):
        simulate_system(sys, T, [0.0, 0.0], inputs={"u": np.zeros(T.size)})
    with pytest.raises(HystdiscError, match="input 'u' has 3 samples"):
        simulate_system(sys, T, sys.initial_state(), inputs={"u": np.zeros(3)})
    wheel = BeamOnCompliantWheel()
    with pytest.raises(HystdiscError, match="parameter m_w=-1 is outside its physical bounds"):
        simulate_system(wheel, T, wheel.initial_state(), {"m_w": -1.0})
    with pytest.raises(ValueError, match="no state 'q'"):
        wheel.initial_state(q=1.0)


def test_registry_is_the_one_list():
    assert tuple(FAMILIES) == registry.family_names()
    for name in registry.family_names():
        assert registry.get_family(name).name == name
    for name in registry.effect_names():
        assert registry.get_effect(name).name == name
    for name in registry.experiment_names():
        assert registry.get_experiment(name).name == name
    assert registry.get_family("BW").name == "bouc-wen"
    with pytest.raises(HystdiscError, match="unknown model 'spring'; fix: use one of bingham"):
        registry.get_family("spring")
    with pytest.raises(HystdiscError, match="unknown experiment type 'drop'"):
        registry.get_experiment("drop")


@pytest.mark.parametrize("family", registry.term_family_names())
def test_family_round_trip_through_terms(family):
    """from_terms(to_terms(p)) gives p back (each family's normalization)."""
    fam = registry.get_family(family)
    p = fam.defaults()
    back = fam.from_terms(fam.to_terms(p))
    if family.startswith("bouc-wen"):
        p["delta"] = p["beta"] + p["gamma"]  # the z_sat = 1 normalization of the demo values
        back = fam.from_terms(fam.to_terms(p))
    for k, v in p.items():
        assert back[k] == pytest.approx(v, rel=1e-9, abs=1e-12), k


def test_state_space_parameters_are_bounded():
    wheel = BeamOnCompliantWheel("lugre")
    names = [p.name for p in wheel.params]
    assert names[: len(registry.get_family("lugre").params)] == [
        p.name for p in registry.get_family("lugre").params
    ]
    for p in wheel.params:
        assert p.lower <= p.default <= p.upper and p.unit


B = 1e9  # models.params.BIG
FAMILY_PARAMS = {  # every family's parameters as they were written before the text tables
    "bingham": [
        ("c_a", "N*m*s/rad", 0.0, B, 0.8, "passive viscous damping"),
        ("c_b", "N*m*s/(rad*A)", 0.0, B, 0.6, "current-dependent viscous damping"),
        ("f_a", "N*m", 0.0, B, 0.3, "passive yield (Coulomb) torque"),
        ("f_b", "N*m/A", 0.0, B, 1.0, "current-dependent yield torque"),
    ],
    "dahl": [
        ("k_x", "N*m*s/rad", 0.0, B, 0.8, "viscous damping"),
        ("k_wa", "N*m", 0.0, B, 0.5, "passive hysteretic torque"),
        ("k_wb", "N*m/A", 0.0, B, 1.5, "current-dependent hysteretic torque"),
        ("rho", "1/rad", 1e-9, B, 20.0, "hysteresis rate (loop sharpness)"),
    ],
    "lugre": [
        ("sigma_a", "N*m/rad", 0.0, B, 10.0, "passive stiffness of z"),
        ("sigma_0", "N*m/(rad*A)", 1e-9, B, 30.0, "current-dependent stiffness of z"),
        ("sigma_1", "N*m*s/rad", 0.0, B, 0.5, "damping of z (acts through dz/dt)"),
        ("sigma_2", "N*m*s/rad", 0.0, B, 0.5, "viscous damping"),
        ("sigma_b", "N*m*s/(rad*A)", 0.0, B, 0.6, "current-dependent viscous damping"),
        ("a_0", "A/(N*m)", 1e-12, B, 2.0 / 3.0, "rate constant (z_sat = 1/(sigma_0 a_0))"),
    ],
    **{
        name: [
            ("alpha_1", "N*m", 0.0, B, 0.5, "passive hysteretic torque"),
            ("alpha_2", "N*m/A", 0.0, B, 1.5, "current-dependent hysteretic torque"),
            ("c_1", "N*m*s/rad", 0.0, B, 0.5, "passive viscous damping"),
            ("c_2", "N*m*s/(rad*A)", 0.0, B, 0.6, "current-dependent viscous damping"),
            ("beta", "1/rad", -B, B, beta, "shape (theta_dot |z|^n term)"),
            ("gamma", "1/rad", -B, B, gamma, f"shape (|theta_dot| {shape} term)"),
            ("delta", "1/rad", 1e-12, B, 20.0, "initial slope of z against theta"),
            ("n", "-", 1e-4, 10.0, n, "exponent"),
        ]
        for name, beta, gamma, shape, n in [
            ("bouc-wen", 10.0, 10.0, "z |z|^n", 1.0),
            ("bouc-wen-std", 5.0, 15.0, "z |z|^(n-1)", 2.0),
        ]
    },
}


@pytest.mark.parametrize("family", registry.term_family_names())
def test_family_param_tables_are_unchanged(family):
    """The text tables give every name, unit, bound, default and doc to the last bit."""
    params = registry.get_family(family).params
    rows = [(p.name, p.unit, p.lower, p.upper, p.default, p.doc) for p in params]
    assert rows == FAMILY_PARAMS[family]
    for p in params:
        assert all(type(v) is float for v in (p.lower, p.upper, p.default)), p.name
