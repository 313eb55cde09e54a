"""Export to python-control (issue 18 item 2): the exported damper simulates to the force
``hystdisc predict`` gives (max difference < 1e-6 of the peak), for a term family and a
state-space family, each at two currents, on a driven record the fit did not see.

Both sides integrate the same ODE with the motion linear between samples: hystdisc with
its own integrators (the fixed-step RK4 kernel of the term form, Dormand-Prince at
``rtol=1e-11`` for a state-space family's prediction), python-control with ``solve_ivp`` at
``rtol=1e-11``. What is left of the difference is the integrators' error, and the
state-space test shows which side it is on.
"""

from __future__ import annotations

import sys
import warnings

import numpy as np
import pytest

ct = pytest.importorskip("control")

from hystdisc import Discovery  # noqa: E402
from hystdisc.apply.control import (  # noqa: E402
    SOLVE_IVP_KWARGS,
    damper_model,
    driven_inputs,
    to_control,
)
from hystdisc.apply.predict import predict_dataset  # noqa: E402
from hystdisc.errors import HystdiscError  # noqa: E402
from hystdisc.models import Model  # noqa: E402
from hystdisc.models.families.spencer import SPENCER  # noqa: E402
from hystdisc.models.wheel import TermsOnCompliantMount, TermsOnCompliantWheel  # noqa: E402
from hystdisc.results import Results  # noqa: E402
from hystdisc.results.control import load_control  # noqa: E402
from hystdisc.simulation import simulate_driven, simulate_system  # noqa: E402
from hystdisc.simulation.synth import generate  # noqa: E402

CURRENTS = (0.0, 1.0)
TRAIN = ["0.2@1.0", "0.1@2.0"]
#: The record the export is compared on: a drive the fit did not see (inside its envelope).
TEST = ["0.15@1.2"]
TOL = 1e-6  # of the peak force


def _fit(family: str, tmp_path_factory):
    kw = {"currents": CURRENTS, "duration": 2.0, "fs": 500.0}
    data = generate(Model(family), "driven", noise=1e-3, seed=1, drives=TRAIN, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = Discovery(model=family, heldout=False, close_loop=False, n_starts=1).fit(data)
    path = d.results_.save(tmp_path_factory.mktemp(family) / "results.json")
    test = generate(Model(family), "driven", noise=1e-3, seed=2, drives=TEST, **kw)
    return path, test


@pytest.fixture(scope="module")
def bouc_wen(tmp_path_factory):
    return _fit("bouc-wen-std", tmp_path_factory)


@pytest.fixture(scope="module")
def spencer(tmp_path_factory):
    return _fit("spencer", tmp_path_factory)


def _compare(path, test):
    """Relative max differences (per run) of the exported system against predict."""
    res = Results.load(path)
    pred = predict_dataset(res.simulation_model(), test, res.experiment)
    sys_ = load_control(path)
    diffs, outputs = [], []
    for (T, U), p in zip(driven_inputs(test), pred, strict=True):
        resp = ct.input_output_response(sys_, T, U, solve_ivp_kwargs=SOLVE_IVP_KWARGS)
        outputs.append(resp.outputs[0])
        diffs.append(float(np.max(np.abs(resp.outputs[0] - p)) / np.max(np.abs(p))))
    return diffs, outputs, sys_


def test_bouc_wen_export_reproduces_predict_at_two_currents(bouc_wen):
    path, test = bouc_wen
    assert {r.current for r in test.runs} == set(CURRENTS)
    diffs, _, sys_ = _compare(path, test)
    assert sys_.state_labels == ["z"]
    assert max(diffs) < TOL, diffs


def test_spencer_export_reproduces_predict_at_two_currents(spencer):
    path, test = spencer
    diffs, outputs, sys_ = _compare(path, test)
    assert sys_.state_labels == ["d", "z"]
    assert max(diffs) < TOL, diffs
    print("spencer export vs predict, max difference / peak:", diffs)
    # what is left is the integrators' tolerance: against hystdisc's integrator at rtol
    # 1e-12 the export (solve_ivp at rtol 1e-11) agrees to 1e-8 of the peak
    system, values = Results.load(path).simulation_model()
    for (T, U), run, y in zip(driven_inputs(test), test.runs, outputs, strict=True):
        ref = simulate_system(
            system,
            T,
            system.initial_state(),
            values,
            current=run.current,
            inputs={"theta": U[0], "theta_dot": U[1]},
            rtol=1e-12,
            atol=1e-15,
        ).y
        assert np.max(np.abs(y - ref)) < 1e-8 * np.max(np.abs(ref))


def test_results_to_control_is_load_control(bouc_wen):
    path, _ = bouc_wen
    a, b = Results.load(path).to_control(name="mr"), load_control(path)
    assert a.name == "mr" and a.input_labels == b.input_labels == ["theta", "theta_dot", "current"]
    x, u = np.array([0.3]), np.array([0.1, -0.5, 0.7])
    assert np.array_equal(a.dynamics(0.0, x, u), b.dynamics(0.0, x, u))
    assert np.array_equal(a.output(0.0, x, u), b.output(0.0, x, u))


def test_a_current_switched_mid_record_follows_the_current_law():
    # z is continuous through a switch: the export after the switch equals hystdisc
    # started at 1 A from the state the export reached at 0 A
    tm = Model("bouc-wen").to_terms()
    t = np.linspace(0.0, 2.0, 1001)
    x, v = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    k = 500
    first = simulate_driven(tm, t[: k + 1], 0.0, x[: k + 1], v[: k + 1])
    second = simulate_driven(tm, t[k:], 1.0, x[k:], v[k:], z0=[first.z[-1]])
    sys_ = to_control(tm)
    kw = {"solve_ivp_kwargs": SOLVE_IVP_KWARGS}
    a = ct.input_output_response(sys_, t[: k + 1], [x[: k + 1], v[: k + 1], 0 * t[: k + 1]], **kw)
    b = ct.input_output_response(
        sys_, t[k:], [x[k:], v[k:], 1.0 + 0 * t[k:]], X0=a.states[:, -1], **kw
    )
    peak = np.max(np.abs(second.torque))
    assert np.max(np.abs(b.outputs[0] - second.torque)) < TOL * peak
    assert b.outputs[0][0] != pytest.approx(a.outputs[0][-1], rel=1e-3)  # the law switched


def test_a_release_fit_exports_the_damper_without_the_rig_spring():
    tm = Model("bouc-wen").to_terms()  # release: T holds the rig spring k_s theta
    assert tm.torque["theta"] > 100.0
    sys_ = to_control(tm, "release")
    x, u = np.array([0.4]), np.array([0.2, 0.3, 0.5])  # z; theta, theta_dot, current
    c = tm.torque
    damper = (c["z"] + 0.5 * c["i*z"]) * 0.4 + (c["theta_dot"] + 0.5 * c["i*theta_dot"]) * 0.3
    assert set(c) == {"theta", "z", "i*z", "theta_dot", "i*theta_dot"}
    assert float(sys_.output(0.0, x, u)[0]) == pytest.approx(damper, rel=1e-12)


def test_a_release_spencer_exports_the_driven_damper_without_k1():
    values = {k: v for k, v in SPENCER.defaults().items() if k not in SPENCER.mech_drop}
    values["k_s"] = 150.0
    system, kept = damper_model((SPENCER.system("release"), values), "release")
    assert system.inputs == ("theta", "theta_dot") and kept["k1"] == 0.0 and "k_s" not in kept
    t = np.linspace(0.0, 1.0, 401)
    x, v = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    ref = simulate_system(
        SPENCER.system("driven"),
        t,
        np.zeros(2),
        {**SPENCER.defaults(), "k1": 0.0},
        current=0.5,
        inputs={"theta": x, "theta_dot": v},
        rtol=1e-12,
        atol=1e-15,
    ).y
    resp = ct.input_output_response(
        to_control((SPENCER.system("release"), values), "release"),
        t,
        [x, v, 0.5 + 0 * t],
        solve_ivp_kwargs=SOLVE_IVP_KWARGS,
    )
    assert np.max(np.abs(resp.outputs[0] - ref)) < 1e-8 * np.max(np.abs(ref))


def test_a_driven_mount_is_exported_with_its_states():
    system = TermsOnCompliantMount(Model("bouc-wen-std").to_terms())
    values = {"m_w": 0.05, "k_w": 500.0, "c_w": 1.0}
    sys_ = to_control((system, values), "driven")
    assert sys_.state_labels == ["d", "y_dot", "z"]
    t = np.linspace(0.0, 1.0, 501)
    x, v = 0.1 * np.sin(2 * np.pi * t), 0.2 * np.pi * np.cos(2 * np.pi * t)
    ref = simulate_system(
        system,
        t,
        system.initial_state(),
        values,
        current=1.0,
        inputs={"theta": x, "theta_dot": v},
        rtol=1e-12,
        atol=1e-15,
    ).y
    resp = ct.input_output_response(sys_, t, [x, v, 1.0 + 0 * t], solve_ivp_kwargs=SOLVE_IVP_KWARGS)
    assert np.max(np.abs(resp.outputs[0] - ref)) < 1e-8 * np.max(np.abs(ref))


def test_the_wheel_of_a_release_fit_is_not_exportable():
    system = TermsOnCompliantWheel(Model("dahl").to_terms())
    with pytest.raises(HystdiscError) as exc:
        to_control((system, {"k_w": 900.0}), "release")
    msg = str(exc.value)
    assert "\n" not in msg
    assert msg.startswith("term model on a compliant wheel: not exportable as a damper")
    assert "fix: export a family's own fit (family=...)" in msg


def test_without_python_control_the_error_names_the_extra(monkeypatch):
    monkeypatch.setitem(sys.modules, "control", None)  # import control raises ImportError
    with pytest.raises(HystdiscError, match=r"hystdisc\[control\]"):
        to_control(Model("dahl").to_terms())


def test_the_open_librarys_terms_are_exported_with_a_state_per_play():
    """The accepted terms of the open library (issue 35) are part of the exported damper:
    a term of the motion and the current from its name, a play's through a state of its
    own. Against ``predict``'s columns: the play's gap to 1e-4 of the force's RMS; its
    lost velocity, a numerical gradient in ``predict`` that spreads each engagement over
    two samples where the export's state takes it up at once, to 5e-3."""
    from hystdisc.apply.control import PLAY_SOLVE_IVP_KWARGS, to_control

    model = Model("bouc-wen-std")
    test = generate(model, "driven", currents=CURRENTS, duration=2.0, fs=500.0, noise=0.0,
                    seed=1, drives=["0.1@1.0"])  # fmt: skip
    tm = model.to_terms()
    gap = {"[theta_dot>0]": 0.5, "i*play(theta,0.005)-theta": 100.0, "i*theta_dot": 1.0}
    lost = {**gap, "d/dt[play(theta,0.005)-theta]": 2.0}
    without = predict_dataset(tm, test, "driven")
    for extra, tol in ((gap, 1e-4), (lost, 5e-3)):
        sys_ = to_control(tm, "driven", extra=extra)
        assert sys_.state_labels == ["z", "play_0"]
        with_terms = predict_dataset(tm, test, "driven", extra=extra)
        for (T, U), p, b in zip(driven_inputs(test), with_terms, without, strict=True):
            resp = ct.input_output_response(sys_, T, U, solve_ivp_kwargs=PLAY_SOLVE_IVP_KWARGS)
            rms = float(np.sqrt(np.mean(p**2)))
            assert np.sqrt(np.mean((resp.outputs - p) ** 2)) < tol * rms
            assert np.sqrt(np.mean((b - p) ** 2)) > 0.02 * rms  # the terms do count
    with pytest.raises(HystdiscError, match=r"unknown term 'theta\^7'.*fix: pass the open"):
        to_control(tm, "driven", extra={"theta^7": 1.0})
