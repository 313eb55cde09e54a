"""Current laws by the seed's flowchart (issue 15 item 3): per-level fits, the law chosen by
leaving one level out, the joint fit with the chosen laws."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data import Dataset
from hystdisc.errors import HystdiscError
from hystdisc.estimator import Discovery
from hystdisc.fitting import FamilyParametrization
from hystdisc.models import Model
from hystdisc.report import render_report
from hystdisc.results import Results
from hystdisc.selection.laws import choose_law, fit_law, law_value
from hystdisc.selection.staged import heldout_level, staged_fit
from hystdisc.simulation.synth import generate

CURRENTS = (0.0, 0.25, 0.5, 0.75, 1.0)
DRIVES = ["0.3@1.0", "0.1@3.0", "0.2@0.5"]
NOISE = 0.02  # N*m on the torque (about 1 % of the peak at 1 A)
SHAPE = {"beta": 5.0, "gamma": 15.0, "delta": 20.0, "n": 2.0, "k_s": 0.0}


def alpha_linear(i):
    return 0.5 + 1.5 * i


def alpha_saturating(i):
    return 0.5 + 3.0 * 0.3 * np.tanh(i / 0.3)  # slope 3 at 0 A, 1.4 N*m at large currents


def synthetic(alpha, seed=1):
    """Driven standard Bouc-Wen, three sines at each of five currents; at each current the
    family at that current's values (alpha by ``alpha``, c linear: 0.5 + 0.6 i)."""
    runs = []
    for k, i in enumerate(CURRENTS):
        p = {"alpha_1": alpha(i), "alpha_2": 0.0, "c_1": 0.5 + 0.6 * i, "c_2": 0.0, **SHAPE}
        ds = generate(
            Model("bouc-wen-std", p),
            "driven",
            currents=(i,),
            drives=DRIVES,
            duration=2.0,
            fs=500.0,
            noise=NOISE,
            seed=seed + k,
        )
        for j, r in enumerate(ds.runs):
            r.name = f"{j}_{k}"
            runs.append(r)
    return Dataset(runs, "driven", "synthetic")


def staged(alpha):
    """The discovery with the staged step (the estimator's hook) and the closing loop."""
    data = synthetic(alpha)
    d = Discovery(model="bouc-wen-std", staged=True).fit(data)
    return d.fit_data_, d.family_fits_["bouc-wen-std"], d.staged_, d, data


@pytest.fixture(scope="module")
def linear_case():
    return staged(alpha_linear)


@pytest.fixture(scope="module")
def saturating_case():
    return staged(alpha_saturating)


def test_fit_law_recovers_each_law_exactly():
    i = np.array(CURRENTS)
    truth = {
        "linear": {"a": 1.0, "b": 2.0},
        "quadratic": {"a": 1.0, "b": 2.0, "q": -0.8},
        "saturating": {"a": 1.0, "b": 2.0, "i0": 0.4},
    }
    for law, c in truth.items():
        got = fit_law(law, i, law_value(law, c, i), np.full(5, 0.01))
        assert got == pytest.approx(c, rel=1e-6), law


def test_nonlinear_laws_need_four_levels():
    i = [0.0, 0.5, 1.0]
    out = choose_law(i, [1.0, 1.8, 2.0], [0.01] * 3)
    assert out["law"] == "linear"
    assert out["candidates"]["quadratic"] is None and out["candidates"]["saturating"] is None


def test_a_family_with_laws_rejects_an_undeclared_law():
    with pytest.raises(HystdiscError, match="dahl has no current law 'alpha'; fix: use one of k_w"):
        FamilyParametrization("dahl", "driven", {}, laws={"alpha": "linear"})
    with pytest.raises(HystdiscError, match="unknown current law 'cubic'; fix: use one of linear"):
        FamilyParametrization("dahl", "driven", {}, laws={"k_w": "cubic"})


def test_linear_truth_keeps_the_linear_laws(linear_case):
    fd, fit, st, *_ = linear_case
    assert st.chosen == {"alpha": "linear", "c": "linear"}
    assert not st.changed and st.joint is fit
    # per-level values: within 1 % of the truth
    for lv in st.levels:
        assert lv.fit.params["alpha_1"] == pytest.approx(alpha_linear(lv.current), rel=0.01)
    # the law fitted to the levels and the joint fit: within 1 % of the truth
    assert st.laws["alpha"]["coefs"] == pytest.approx({"a": 0.5, "b": 1.5}, rel=0.01)
    assert st.laws["c"]["coefs"] == pytest.approx({"a": 0.5, "b": 0.6}, rel=0.01)
    p = st.joint.params
    assert [p["alpha_1"], p["alpha_2"], p["c_1"], p["c_2"]] == pytest.approx(
        [0.5, 1.5, 0.5, 0.6], rel=0.01
    )
    assert st.joint.heldout_rms < 1.1 * NOISE


def test_saturating_truth_is_found_and_predicts_a_left_out_level(saturating_case):
    fd, fit, st, *_ = saturating_case
    assert st.chosen["alpha"] in ("saturating", "quadratic")
    assert st.chosen["c"] == "linear"
    cand = st.laws["alpha"]["candidates"]
    assert cand[st.chosen["alpha"]]["z"] < cand["linear"]["z"] / 10, cand
    # the joint fit with the chosen laws reaches the noise floor, the linear one does not
    assert st.joint.rms < 1.1 * NOISE < st.linear.rms
    assert st.joint.heldout_rms < 1.1 * NOISE < st.linear.heldout_rms
    if st.chosen["alpha"] == "saturating":
        p = st.joint.params
        assert [p["alpha_1"], p["alpha_2"], p["alpha_i0"]] == pytest.approx(
            [0.5, 3.0, 0.3], rel=0.02
        )
    # a current level no fit saw (0.5 A): the laws fitted to the other four levels
    lin = heldout_level(fd, st.linear, st.laws, {"alpha": "linear", "c": "linear"}, 0.5)
    law = heldout_level(fd, st.linear, st.laws, st.chosen, 0.5)
    assert law < 1.2 * NOISE < 5 * NOISE < lin, (
        f"held-out RMS at 0.5 A: chosen laws {law:.4g}, linear {lin:.4g}"
    )


def test_the_chosen_law_is_the_final_model(saturating_case):
    fd, fit, st, d, data = saturating_case
    assert st.chosen == {"alpha": "saturating", "c": "linear"}
    # the selected family's fit is the joint fit with the chosen law; the loop ran on it
    assert fit is st.joint and fit.par.laws == {"alpha": "saturating"}
    final = d.final_fit_
    assert final.par.laws == {"alpha": "saturating"} and d.effects_ == []
    p = final.params
    assert [p["alpha_1"], p["alpha_2"], p["alpha_i0"], p["c_1"], p["c_2"]] == pytest.approx(
        [0.5, 3.0, 0.3, 0.5, 0.6], rel=0.02
    )
    # leave one condition out, as the loop reports it: at the noise (linear laws: not)
    assert final.heldout_rms < 1.1 * NOISE < 2 * NOISE < st.linear.heldout_rms
    skipped = {s.name: s.reason for s in d.loop_.skipped}
    assert (
        "the staged fit chose the current laws (alpha_1 saturating" in skipped["current_saturation"]
    )
    # results.json: the selected family, the final model and its term form carry the law
    res = Results.from_json(d.results_.to_json())
    assert res.selected.parameters["alpha_i0"].value == pytest.approx(0.3, rel=0.02)
    assert res.final.parameters["alpha_i0"].value == pytest.approx(0.3, rel=0.02)
    assert res.model.get("saturation")["z"] == pytest.approx(0.3, rel=0.02)
    tm = res.term_model()
    assert tm.saturation == pytest.approx(final.term_model.saturation, rel=1e-9)
    line = tm.equations().splitlines()[0]
    assert f"tanh(i/{tm.saturation['z']:.4g})*z" in line and "i*z" not in line


def test_a_linear_truth_keeps_a_linear_final_model(linear_case):
    fd, fit, st, d, data = linear_case
    assert d.final_fit_.par.laws == {} and d.effects_ == []
    assert not any(k.endswith(("_i0", "_i2")) for k in d.final_fit_.params)
    assert d.final_fit_.heldout_rms < 1.1 * NOISE
    res = Results.from_json(d.results_.to_json())
    assert "saturation" not in res.model and "alpha_i0" not in res.final.parameters


def test_results_json_and_predict_reproduce_the_final_model(saturating_case, tmp_path, capsys):
    from hystdisc.cli import main
    from hystdisc.data import write_csv

    fd, fit, st, d, data = saturating_case
    path = d.results_.save(tmp_path / "results.json")
    csv = write_csv(data, tmp_path / "data.csv")
    out = tmp_path / "pred.csv"
    assert main(["predict", str(path), str(csv), "-o", str(out), "--quiet"]) == 0
    lines = [line.split(",") for line in out.read_text().splitlines()[1:]]
    ours = d.predict(data)
    scale = max(float(np.max(np.abs(p))) for p in ours)
    for r, p in zip(data.runs, ours, strict=True):
        got = np.array([float(w[-1]) for w in lines if w[0] == r.name])
        assert np.max(np.abs(got - p)) < 1e-6 * scale, r.name
    # the prediction is the saturating model's: at the noise on every run, where the
    # linear laws' model is not
    e = np.concatenate([p - r.torque for p, r in zip(ours, data.runs, strict=True)])
    from hystdisc.apply.predict import predict_dataset

    lin = predict_dataset(st.linear.model, data, "driven")
    e_lin = np.concatenate([p - r.torque for p, r in zip(lin, data.runs, strict=True)])
    assert np.sqrt(np.mean(e * e)) < 1.1 * NOISE < 2 * NOISE < np.sqrt(np.mean(e_lin * e_lin))


def test_results_report_and_plot_carry_the_laws(saturating_case):
    fd, fit, st, d, data = saturating_case
    res = Results.from_json(d.results_.to_json())
    cl = res.current_laws
    assert cl["laws"]["alpha"]["law"] == st.chosen["alpha"]
    assert [lv["current"] for lv in cl["levels"]] == list(CURRENTS)
    assert cl["laws"]["alpha"]["values"] == pytest.approx(
        [alpha_saturating(i) for i in CURRENTS], rel=0.01
    )
    assert cl["joint"]["heldout_rms"] < cl["linear"]["heldout_rms"]
    html, md = render_report(d, data, max_runs=2, dpi=40)
    assert 'id="current-laws"' in html and "held-out saturating" in md
    assert md.count("| chosen laws |") == 1


def test_staged_fit_needs_three_levels(linear_case):
    *_, data = linear_case  # synthetic(alpha_linear), which no fit changes
    two = Dataset([r for r in data.runs if r.current in (0.0, 1.0)], "driven", "two levels")
    d = Discovery(model="bouc-wen-std", close_loop=False, heldout=False).fit(two)
    with pytest.raises(HystdiscError, match="2 current level.s.: the staged fit needs 3"):
        staged_fit(d.fit_data_, d.family_fits_["bouc-wen-std"])


def test_cli_staged_prints_the_steps_and_keeps_a_linear_truth(tmp_path, capsys):
    from pathlib import Path

    from hystdisc.cli import main

    csv = Path(__file__).resolve().parents[2] / "data_synth" / "driven_bouc-wen.csv"
    out = tmp_path / "out"
    code = main(["discover", str(csv), "--staged", "--no-effects", "--quiet", "--out", str(out)])
    text = capsys.readouterr().out
    assert code == 0
    assert "Staged fit of bouc-wen" in text and "level 0.25 A (2 runs)" in text
    res = Results.load(out / "results.json")
    # the bundled set's truth is linear (alpha 0.5 + 1.5 i, c 0.5 + 0.6 i): kept linear
    laws = res.current_laws["laws"]
    assert {k: d["law"] for k, d in laws.items()} == {"alpha": "linear", "c": "linear"}
    assert list(laws["alpha"]["coefficients"].values()) == pytest.approx([0.5, 1.5], rel=0.01)
    assert list(laws["c"]["coefficients"].values()) == pytest.approx([0.5, 0.6], rel=0.01)


def _sine(t):
    return 0.3 * np.sin(2 * np.pi * t), 0.6 * np.pi * np.cos(2 * np.pi * t)


def test_spencer_folds_its_laws_into_its_block_and_simulation():
    from hystdisc.fitting import FamilySystemParametrization
    from hystdisc.models import get_family
    from hystdisc.simulation import simulate_system

    sp = get_family("spencer")
    laws = {"alpha": "saturating", "c0": "quadratic"}
    p = {**sp.defaults(), "alpha_a": 0.5, "alpha_b": 3.0, "alpha_i0": 0.3, "c0_i2": -0.1}
    sys_law = sp.system("driven", laws=laws)
    assert [q.name for q in sys_law.params if q.name.startswith(("alpha_i", "c0_i"))] == [
        "alpha_i0",
        "c0_i2",
    ]
    alpha = 0.5 + 3.0 * 0.3 * np.tanh(2.0 / 0.3)
    c0 = 0.5 + 0.6 * 2.0 - 0.1 * 4.0
    # the family's block closes the vector: A, 0, -beta, 0, -gamma, n, alpha, c0, ...
    block = sys_law.run_parameters(p, 2.0)[-sp.block(p, 2.0).size :]
    assert block[6:8] == pytest.approx([alpha, c0], rel=1e-12)
    # the same run as the linear model whose laws have those values at 2 A
    lin = {k: v for k, v in p.items() if k not in ("alpha_i0", "c0_i2")}
    lin.update(alpha_b=(alpha - 0.5) / 2.0, c0_b=(c0 - 0.5) / 2.0)
    t = np.linspace(0.0, 2.0, 1001)
    x, v = _sine(t)
    runs = [
        simulate_system(s, t, s.initial_state(), vals, 2.0, {"theta": x, "theta_dot": v}).y
        for s, vals in ((sys_law, p), (sp.system("driven"), lin))
    ]
    assert np.max(np.abs(runs[0] - runs[1])) < 1e-9 * np.max(np.abs(runs[1]))
    # the parametrization carries the laws through like() (the closing loop's refits)
    par = FamilySystemParametrization("spencer", "driven", p, laws=laws)
    assert par.like(p, ("coulomb",)).laws == laws
    system, values = par.model(par.x0)
    assert values["alpha_i0"] == pytest.approx(0.3) and "alpha = alpha_a" in system.equations()
    assert sp.derived(p)["alpha_yield_1"] > 0  # the combinations use the laws too


def test_term_families_fold_each_law_per_run():
    from hystdisc.models.compiled import base_coefficients

    # Bingham's Coulomb law, quadratic: the i^2*sign(theta_dot) term
    tm = Model("bingham", {"f_a": 0.3, "f_b": 1.0, "f_i2": -0.2, "c_b": 0.6, "c_i0": 0.5})
    tm = tm.to_terms()
    assert tm.torque["i^2*sign(theta_dot)"] == -0.2 and tm.saturation == {"theta_dot": 0.5}
    c = base_coefficients(tm, 2.0)
    assert c[4] == pytest.approx(0.3 + 1.0 * 2.0 - 0.2 * 4.0)
    assert c[1] == pytest.approx(0.8 + 0.6 * 0.5 * np.tanh(2.0 / 0.5))
    # the Python evaluation agrees with the compiled coefficients
    w = np.array([-2.0, 3.0])
    assert tm.eval_torque(0.0, w, 0.0, 2.0) == pytest.approx(c[1] * w + c[4] * np.tanh(w / 1e-3))
    with pytest.raises(HystdiscError, match="saturation current of 'z' is -1 A"):
        type(tm)({"i*z": 1.0}, saturation={"z": -1.0})


def test_spencer_staged_carries_a_saturating_law_into_results_and_predict():
    """Synthetic driven Spencer data whose alpha saturates (the package's simulator with
    the law): the staged fit chooses it, the final model carries it, results.json and
    predict reproduce it."""
    import warnings

    from hystdisc.apply.predict import predict_dataset
    from hystdisc.errors import HystdiscWarning

    truth = {
        **{"alpha_a": 0.4, "alpha_b": 3.0, "alpha_i0": 0.3, "c0_a": 0.3, "c0_b": 0.5},
        **{"c1_a": 4.0, "c1_b": 3.0, "k0": 0.3, "k1": 0.5, "A": 20.0, "beta": 8.0, "n": 2.0},
    }
    m = Model("spencer", truth)
    kw = {
        "currents": CURRENTS,
        "duration": 2.0,
        "fs": 250,
        "drives": ["0.2@0.5", "0.4@1.0", "0.1@2.0"],
    }
    clean = generate(m, "driven", noise=0.0, seed=1, **kw)
    noise = 0.01 * float(np.median([np.max(np.abs(r.torque)) for r in clean.runs]))
    data = generate(m, "driven", noise=noise, seed=1, **kw)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HystdiscWarning)
        d = Discovery(model="spencer", staged=True).fit(data)
    st = d.staged_
    assert st.chosen == {"alpha": "saturating", "c0": "linear", "c1": "linear"}
    final = d.final_fit_
    assert final.par.laws == {"alpha": "saturating"} and d.family_fits_["spencer"] is st.joint
    assert [final.params[k] for k in ("alpha_a", "alpha_b", "alpha_i0")] == pytest.approx(
        [0.4, 3.0, 0.3], rel=0.02
    )
    # each sine condition predicted by the fit without it: at the 1 % noise (linear: not)
    assert final.heldout_rms < 1.1 * noise < 2 * noise < st.linear.heldout_rms
    res = Results.from_json(d.results_.to_json())
    assert res.system_model["values"]["alpha_i0"] == pytest.approx(0.3, rel=0.02)
    system, values = res.simulation_model()
    assert "alpha = alpha_a + alpha_b*alpha_i0*tanh(i/alpha_i0)" in system.equations()
    ours, theirs = d.predict(data), predict_dataset((system, values), data, "driven")
    scale = max(float(np.max(np.abs(p))) for p in ours)
    assert max(float(np.max(np.abs(a - b))) for a, b in zip(ours, theirs, strict=True)) < (
        1e-6 * scale
    )
