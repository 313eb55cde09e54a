"""Current laws by the seed's flowchart (issue 15 item 3): per-level fits, the law chosen by
leaving one level out, the joint fit with the chosen laws."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data import Dataset
from hystdisc.errors import HystdiscError
from hystdisc.estimator import Discovery
from hystdisc.fitting import FamilyParametrization
from hystdisc.fitting.laws import LawParametrization, choose_law, fit_law, law_value
from hystdisc.fitting.staged import heldout_level, staged_fit
from hystdisc.models import Model
from hystdisc.report import render_report
from hystdisc.results import Results
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
    """The discovery with the staged step (the estimator's hook)."""
    data = synthetic(alpha)
    d = Discovery(model="bouc-wen-std", close_loop=False, staged=True).fit(data)
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


def test_law_parametrization_rejects_an_undeclared_law():
    base = FamilyParametrization("dahl", "driven", {}, fixed={"k_wb": 0.0})
    with pytest.raises(HystdiscError, match="dahl has no current law 'alpha'; fix: use one of k_w"):
        LawParametrization(base, {"alpha": "linear"}, {})


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
    lin = heldout_level(fd, fit, st.laws, {"alpha": "linear", "c": "linear"}, 0.5)
    law = heldout_level(fd, fit, st.laws, st.chosen, 0.5)
    assert law < 1.2 * NOISE < 5 * NOISE < lin, (
        f"held-out RMS at 0.5 A: chosen laws {law:.4g}, linear {lin:.4g}"
    )


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


def test_staged_fit_needs_three_levels():
    data = synthetic(alpha_linear)
    two = Dataset([r for r in data.runs if r.current in (0.0, 1.0)], "driven", "two levels")
    d = Discovery(model="bouc-wen-std", close_loop=False, heldout=False).fit(two)
    with pytest.raises(HystdiscError, match="2 current level.s.: the staged fit needs 3"):
        staged_fit(d.fit_data_, d.family_fits_["bouc-wen-std"])


def test_cli_staged_prints_the_steps_and_keeps_a_linear_truth(tmp_path, capsys):
    from pathlib import Path

    from hystdisc.cli import main

    csv = Path(__file__).resolve().parents[1] / "data_synth" / "driven_bouc-wen.csv"
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
