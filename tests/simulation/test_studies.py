"""The seed paper's qualitative statements (sections 4.2-4.6), checked on simulated loops.

Every loop is the steady-state last cycle of ``theta = 0.3 sin(2 pi t)`` (see
:func:`hystdisc.simulation.studies.loop`); the torque is the damper torque.
"""

from __future__ import annotations

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

from hystdisc.cli import main
from hystdisc.errors import HystdiscError
from hystdisc.plotting import loops_figure, plot_loops, plot_runs, plot_study
from hystdisc.simulation.studies import loop, parameter_study
from hystdisc.simulation.synth import generate

# ------------------------------------------------------------------ loop measurements


def post_yield_slope(lp: dict) -> float:
    """dT/d(theta_dot) on the post-yield part: high positive velocity, after theta = 0.

    There the hysteretic state has travelled at least one amplitude since the reversal and
    is saturated, so the branch is the linear (viscous) part of the loop.
    """
    w, th = lp["theta_dot"], lp["theta"]
    m = (w > 0.5 * w.max()) & (th > 0)
    return float(np.polyfit(w[m], lp["torque"][m], 1)[0])


def knee_torque(lp: dict) -> float:
    """Torque at the velocity reversal at theta = +A (the 'knee' at zero velocity)."""
    return float(lp["torque"][np.argmax(lp["theta"])])


def width_at_zero_torque(lp: dict) -> float:
    """Velocity span between the two zero crossings of the torque (loop width)."""
    w, tq = lp["theta_dot"], lp["torque"]
    k = np.flatnonzero(np.sign(tq[:-1]) != np.sign(tq[1:]))
    ws = w[k] - tq[k] * (w[k + 1] - w[k]) / (tq[k + 1] - tq[k])
    return float(ws.max() - ws.min())


def displacement_to_90(lp: dict, hysteretic: np.ndarray, saturated: float) -> float:
    """Travel after the reversal at +A until the hysteretic torque reaches -90 % of saturation."""
    k0 = int(np.argmax(lp["theta"]))
    h = hysteretic[k0:]
    hit = np.flatnonzero(h <= -0.9 * saturated)
    if hit.size == 0:
        return np.inf
    return float(lp["theta"][k0] - lp["theta"][k0 + hit[0]])


# ------------------------------------------------------------------ Dahl (4.2)

SEED_DAHL = {"k_x": 5.0, "k_wa": 80.0, "k_wb": 80.0, "rho": 15.0}  # seed figures 4-6


def test_dahl_kx_steepens_linear_part_knees_stay():
    lo, hi = parameter_study("dahl", "k_x", [5.0, 15.0], base=SEED_DAHL)
    # the post-yield slope grows by exactly the added viscous damping ...
    assert post_yield_slope(hi) - post_yield_slope(lo) == pytest.approx(10.0, rel=0.01)
    assert post_yield_slope(hi) > 2.5 * post_yield_slope(lo)
    # ... while the knees stay at (0, +-80): same hysteretic torque
    assert knee_torque(lo) == pytest.approx(80.0, rel=0.01)
    assert knee_torque(hi) == pytest.approx(knee_torque(lo), rel=1e-9)


def test_dahl_rho_sharpens_the_knee():
    base = {k: v for k, v in SEED_DAHL.items() if k != "rho"}
    study = parameter_study("dahl", "rho", [2.0, 15.0, 40.0], base=base)
    travel = [displacement_to_90(s, 80.0 * s["z"], 80.0) for s in study]
    # rho = 2 (seed figure 6, blue): the torque never gets within 10 % of its saturated
    # value (k_wa = 80) in the 0.3 rad stroke
    assert travel[0] == np.inf
    # w = -1 + 2 exp(-rho * travel)  ->  90 % after ln(20) / rho
    assert travel[1] == pytest.approx(np.log(20) / 15.0, rel=0.05)
    assert travel[2] == pytest.approx(np.log(20) / 40.0, rel=0.05)
    assert travel[2] < travel[1]
    # and the loop (velocity panel) gets wider at zero torque as the knee sharpens
    assert width_at_zero_torque(study[1]) < width_at_zero_torque(study[0])


@pytest.mark.parametrize("param, values", [("current", [0.0, 10.0]), ("k_wb", [40.0, 80.0, 160.0])])
def test_dahl_current_or_kwb_raise_the_torque(param, values):
    cur = 0.0 if param == "current" else 1.0
    study = parameter_study("dahl", param, values, current=cur, base=SEED_DAHL)
    knees = [knee_torque(s) for s in study]
    peaks = [float(s["torque"].max()) for s in study]
    assert np.all(np.diff(knees) > 0) and np.all(np.diff(peaks) > 0)
    for s, knee in zip(study, knees, strict=True):
        i = s["value"] if param == "current" else 1.0
        k_wb = s["value"] if param == "k_wb" else SEED_DAHL["k_wb"]
        assert knee == pytest.approx(SEED_DAHL["k_wa"] + k_wb * i, rel=0.01)  # T0 = k_wa + v k_wb


# ------------------------------------------------------------------ Bouc-Wen (4.5, 4.6)


def test_bouc_wen_current_raises_peak_and_slope_keeps_shape():
    study = parameter_study("bouc-wen", "current", [0.0, 0.5, 1.0])
    peaks = [float(s["torque"].max()) for s in study]
    slopes = [post_yield_slope(s) for s in study]
    assert np.all(np.diff(peaks) > 0)
    assert np.all(np.diff(slopes) > 0)
    assert slopes == pytest.approx([0.5, 0.8, 1.1], rel=0.01)  # c_1 + c_2 i
    # torque against displacement: the same shape, scaled
    a, b = study[0], study[-1]
    na = a["torque"] / np.abs(a["torque"]).max()
    nb = b["torque"] / np.abs(b["torque"]).max()
    assert np.corrcoef(na, nb)[0, 1] > 0.99


def test_bouc_wen_alpha_raises_hysteretic_torque_linearly():
    alphas = [0.0, 0.5, 1.0, 1.5, 2.0]  # equally spaced (the seed used 0, 0.5, 1.5, 2)
    study = parameter_study("bouc-wen", "alpha_1", alphas, base={"alpha_2": 0.0})
    knees = np.array([knee_torque(s) for s in study])
    steps = np.diff(knees)
    assert steps.min() > 0
    assert np.ptp(steps) < 0.01 * steps.mean()  # equal increments within 1 %
    assert knees[0] == pytest.approx(0.0, abs=1e-9)  # alpha = 0: no hysteretic torque


SEED_BW = {"alpha_1": 1.0, "alpha_2": 0.0, "c_1": 0.5, "c_2": 0.0}


@pytest.mark.parametrize(
    "shape",
    [
        {"beta": 760.0, "gamma": 1.5, "delta": 840.0},
        {"beta": 740.0, "gamma": 1.0, "delta": 800.0},
        {"beta": 800.0, "gamma": 2.0, "delta": 860.0},
    ],
)
def test_bouc_wen_n_narrower_and_shorter(shape):
    # The seed's n values (figure 21) with beta, gamma, delta from its figures 19, 20, 22.
    # In the seed form, |z|^n multiplies beta: as n grows from 0.001 to 0.1 the saturation
    # value of z (and with it the torque) falls, and the velocity loop narrows, as the seed
    # says. The fall is strongly nonlinear in n.
    ns = [0.001, 0.01, 0.05, 0.1]
    study = parameter_study("bouc-wen", "n", ns, base={**SEED_BW, **shape})
    peaks = np.array([float(s["torque"].max()) for s in study])
    widths = np.array([width_at_zero_torque(s) for s in study])
    assert np.all(np.diff(peaks) < 0)  # shorter
    assert np.all(np.diff(widths) < 0)  # narrower
    rate_small = (peaks[0] - peaks[1]) / (ns[1] - ns[0])
    rate_large = (peaks[2] - peaks[3]) / (ns[3] - ns[2])
    assert rate_small > 5 * rate_large  # not linear in n


def test_bouc_wen_beta_gamma_delta_as_the_seed_says():
    base = {**SEED_BW, "beta": 760.0, "gamma": 1.5, "delta": 840.0, "n": 0.01}
    peak = {}
    width = {}
    for p, vals in (
        ("beta", [740, 760, 780, 800]),
        ("gamma", [1, 1.25, 1.5, 2]),
        ("delta", [800, 820, 840, 860]),
    ):
        st = parameter_study("bouc-wen", p, vals, base=base)
        peak[p] = np.array([float(s["torque"].max()) for s in st])
        width[p] = np.array([width_at_zero_torque(s) for s in st])
    assert np.all(np.diff(peak["beta"]) < 0)  # larger beta: less torque
    assert np.all(np.diff(peak["gamma"]) < 0)  # larger gamma: less torque ...
    assert np.all(np.diff(width["gamma"]) < 0)  # ... and a narrower loop
    assert np.all(np.diff(peak["delta"]) > 0)  # larger delta: larger loop


@pytest.mark.parametrize("param, current", [("c_1", 0.0), ("c_2", 1.0)])
def test_bouc_wen_c1_c2_steepen_linear_areas(param, current):
    study = parameter_study("bouc-wen", param, [0.2, 0.6, 1.0], current=current)
    slopes = np.array([post_yield_slope(s) for s in study])
    assert np.all(np.diff(slopes) > 0)
    np.testing.assert_allclose(np.diff(slopes), 0.4, rtol=0.01)
    # c_2 acts only with current applied
    if param == "c_2":
        passive = parameter_study("bouc-wen", "c_2", [0.2, 1.0], current=0.0)
        assert post_yield_slope(passive[1]) == pytest.approx(post_yield_slope(passive[0]), 1e-9)


# ------------------------------------------------------------------ LuGre (4.3)


def test_lugre_sigma2_passive_slope_sigmab_current_slope():
    s2 = parameter_study("lugre", "sigma_2", [0.5, 1.5], current=0.0)
    assert post_yield_slope(s2[1]) - post_yield_slope(s2[0]) == pytest.approx(1.0, rel=0.01)
    sb0 = parameter_study("lugre", "sigma_b", [0.2, 1.2], current=0.0)
    sb1 = parameter_study("lugre", "sigma_b", [0.2, 1.2], current=1.0)
    assert post_yield_slope(sb0[1]) == pytest.approx(post_yield_slope(sb0[0]), rel=1e-9)
    assert post_yield_slope(sb1[1]) - post_yield_slope(sb1[0]) == pytest.approx(1.0, rel=0.01)


# ------------------------------------------------------------------ API details


def test_loop_is_one_steady_cycle():
    lp = loop("dahl", current=0.5, amplitude=0.2, frequency=2.0, cycles=4, fs=1000)
    assert lp["t"].size == 501 and lp["t"][0] == 0.0
    assert lp["theta"].max() == pytest.approx(0.2, rel=1e-4)
    assert lp["torque"][0] == pytest.approx(lp["torque"][-1], rel=1e-3)  # closed loop
    with pytest.raises(HystdiscError, match="cycles"):
        loop("dahl", cycles=1)


def test_parameter_study_errors_and_effect_parameters():
    with pytest.raises(HystdiscError, match="unknown parameter 'zz'"):
        parameter_study("dahl", "zz", [1.0])
    st = parameter_study("dahl", "c_i", [0.0, 1.0], current=1.0, effects={"current_viscous": {}})
    assert post_yield_slope(st[1]) - post_yield_slope(st[0]) == pytest.approx(1.0, rel=0.01)


# ------------------------------------------------------------------ plots


@pytest.fixture
def no_show(monkeypatch):
    def fail(*a, **k):
        raise AssertionError("plt.show() must not be called")

    monkeypatch.setattr(plt, "show", fail)
    yield
    plt.close("all")


def test_plot_study_lines(no_show):
    study = parameter_study("dahl", "rho", [2.0, 15.0, 40.0])
    fig = plot_study(study)
    assert isinstance(fig, Figure)
    assert [len(ax.lines) for ax in fig.axes] == [3, 3]
    assert fig.axes[0].get_xlabel().startswith("velocity")
    assert fig.axes[1].get_xlabel().startswith("angle")


def test_plot_functions_draw_into_given_axes(no_show):
    lp = loop("bouc-wen", current=1.0)
    fig, ax = plt.subplots()
    before = plt.get_fignums()
    out = plot_loops(lp["t"], lp["theta"], lp["theta_dot"], lp["torque"], current=1.0, ax=ax)
    out = plot_loops(lp["t"], lp["theta"], None, lp["torque"], ax=ax, kind="displacement")
    assert out is fig and len(ax.lines) == 2 and plt.get_fignums() == before
    assert ax.lines[0].get_label() == "1 A"
    fig2, axes = plt.subplots(1, 2)
    assert loops_figure([lp, lp, lp], axes=axes) is fig2
    assert [len(a.lines) for a in axes] == [3, 3]
    ds = generate("dahl", currents=(0.0, 0.5, 1.0), duration=1.0)
    fig3 = plot_runs(ds, predictions=[r.theta for r in ds])
    assert len(fig3.axes) == 3 and [len(a.lines) for a in fig3.axes] == [2, 2, 2]
    fig4, one = plt.subplots()
    assert plot_runs(ds, ax=one) is fig4 and len(one.lines) == 3
    driven = generate("dahl", "driven", currents=(0.0, 1.0), duration=1.0, drives=["0.3@1"])
    assert [len(a.lines) for a in loops_figure(driven).axes] == [2, 2]


def test_cli_study_writes_a_figure(tmp_path, capsys):
    out = tmp_path / "rho.png"
    assert main(["study", "--model", "dahl", "--vary", "rho=2,15", "-o", str(out)]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "2 loops" in capsys.readouterr().out
    assert main(["study", "--model", "dahl", "--vary", "rho=2,15", "-o", str(out)]) == 2
    err = capsys.readouterr().err
    assert "already exists" in err and err.count("\n") == 1
    assert main(["study", "--model", "dahl", "--vary", "rho", "-o", str(tmp_path / "x.png")]) == 2
    assert "NAME=V1,V2" in capsys.readouterr().err
