"""The driven stress suite (``benchmarks/stress_driven.py``, issue 33 items 4-5).

Its sampler (deterministic, inside its bounds, the acceptance sets held back), its floors,
the command lines of a case (the data ``hystdisc simulate`` writes are the suite's own
dataset), its reading of success on hand-made ``results.json`` dicts (each criterion
failed on purpose), and one real small case end to end.
"""

from __future__ import annotations

import copy
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))

import stress_driven as sd  # noqa: E402
from stress_common import Z95, joint_z  # noqa: E402

from hystdisc.cli import main  # noqa: E402
from hystdisc.data import load  # noqa: E402
from hystdisc.measurement.chain import causal_average  # noqa: E402


@pytest.fixture(scope="module")
def bw_std():
    """Set 0 of the standard Bouc-Wen under ``white`` (a development set)."""
    p, rej, scale = sd.sample_set("bouc-wen-std", 0)
    return sd.Case("bouc-wen-std", 0, "white", p, scale, rej)


def test_sampler_is_deterministic_inside_its_bounds_and_holds_back_the_acceptance_sets(
    tmp_path,
):
    for family in ("tanh", "spencer", "dahl"):
        p, _, scale = sd.sample_set(family, 1)
        assert (p, scale) == sd.sample_set(family, 1)[::2]
        for name, (_, lo, hi) in sd.BOUNDS[family].items():
            assert lo * (1 - 1e-5) <= p[name] <= hi * (1 + 1e-5), (family, name)
        assert scale > 0
    assert sd.BOUNDS["spencer"]["A"][1] > sd.BOUNDS["spencer"]["beta"][2]  # gamma > 0
    assert set(sd.FAMILIES) == set(sd.BOUNDS) and len(sd.FAMILIES) == 7
    for k in sd.ACCEPTANCE_SETS:
        with pytest.raises(ValueError, match="acceptance set"):
            sd.sample_set("dahl", k)
    with pytest.raises(SystemExit):
        sd.main(["--first-set", "9", "--sets", "2", "--out", str(tmp_path / "x.md")])
    assert not list(tmp_path.iterdir())


def test_out_names_the_markdown_and_a_json_name_is_refused(tmp_path, capsys):
    """``--out X.json`` once wrote the markdown over the JSON beside it (the same name)."""
    import stress

    for suite in (sd.main, stress.main):
        with pytest.raises(SystemExit) as exit_:
            suite(["--sets", "1", "--out", str(tmp_path / "x.json")])
        assert exit_.value.code == 2
        err = capsys.readouterr().err.strip().splitlines()[-1]
        assert err.endswith(
            f"--out {tmp_path / 'x.json'}: name the markdown file (.md); its .json is written "
            "beside it"
        )
    assert not list(tmp_path.iterdir())


def test_a_set_that_generates_energy_is_rejected(monkeypatch):
    p = {"c_a": 1.0, "c_b": 0.0, "f_a": 0.0, "f_b": 0.0, "k_s": 1.0}
    assert sd.driven_check("bingham", p) == ("", pytest.approx(0.8654, abs=1e-4))
    # values the model refuses are rejected with its reason
    why, _ = sd.driven_check("bingham", {**p, "c_a": -2.0})
    assert why.startswith("diverges") and "c_a=-2" in why, why
    # a torque that pushes along the motion (every run's work negative) is rejected
    real = sd.driven_data

    def pushing(*args, **kw):
        ds = real(*args, **kw)
        for r in ds.runs:
            r.torque[:] = -r.torque
        return ds

    monkeypatch.setattr(sd, "driven_data", pushing)
    why, _ = sd.driven_check("bingham", p)
    assert why.startswith("does not dissipate (cycle work -"), why


def test_filtered_noise_floor():
    assert sd.filtered_noise_factor([1, 1], 1000) == 1.0
    # long records: 1/sqrt(W); the start (zero initial state) lowers it a little
    assert sd.filtered_noise_factor([100], 10**6) == pytest.approx(0.1, rel=1e-3)
    rng = np.random.default_rng(0)
    e = rng.standard_normal((400, 300))
    mc = np.sqrt(np.mean(np.array([causal_average(x, 25) for x in e]) ** 2))
    assert sd.filtered_noise_factor([25], 300) == pytest.approx(mc, rel=0.02)
    assert sd.prefilter_windows("prefilter") == [100] * 3 + [25] * 3 + [10] * 3
    assert sd.prefilter_windows("white") == [1] * 9


def test_the_floor_is_the_noise_of_the_samples_the_fit_counts():
    """Under the prefilter each run has its own noise (``s/sqrt(W)``), and the fit counts
    a driven run only once its motion has swept its range (``runs[].fitted``): the floor
    is the noise of those samples. The counts of ``bingham/11/prefilter``: 1446, 1858 and
    1941 of 2000 (windows 100, 25, 10)."""
    case = sd.Case("bingham", 11, "prefilter", {}, 1.0)
    fitted = [1446] * 3 + [1858] * 3 + [1941] * 3
    s = case.noise
    var = (1446 / 100 + 1858 / 25 + 1941 / 10) / (1446 + 1858 + 1941)
    assert case.force_floor_on(fitted) == pytest.approx(s * np.sqrt(var), rel=1e-12)
    assert case.force_floor_on(fitted) == pytest.approx(1.041 * case.force_floor, rel=1e-3)
    assert case.n_eff_on(fitted) == pytest.approx(3 * (14.46 + 74.32 + 194.1))
    assert case.force_floor_on(None) == case.force_floor  # older results: every sample
    white = sd.Case("bingham", 11, "white", {}, 1.0)  # one noise: the samples do not matter
    assert white.force_floor_on(fitted) == pytest.approx(white.force_floor, rel=1e-12)


def test_the_commands_write_the_suites_dataset(tmp_path):
    p, rej, scale = sd.sample_set("dahl", 0)
    for cond in ("enc16", "prefilter", "delay"):
        case = sd.Case("dahl", 0, cond, p, scale, rej)
        csv = tmp_path / f"{cond}.csv"
        assert main(case.simulate_args(csv)) == 0
        c = sd.CONDITIONS[cond]
        ref = sd.driven_data(
            "dahl",
            p,
            noise=case.noise,
            seed=case.seed,
            encoder_counts=c["encoder"],
            delay=c["delay"],
            prefilter=c["prefilter"],
        )
        rig = None
        if case.rig_text() is not None:
            rig = tmp_path / "rig.toml"
            rig.write_text(case.rig_text())
        back = load([csv], rig=rig)
        assert len(back) == 9
        for a, b in zip(back.runs, ref.runs, strict=True):
            np.testing.assert_allclose(a.torque, b.torque, rtol=1e-6, atol=1e-9)
            np.testing.assert_allclose(a.theta, b.theta, rtol=1e-6, atol=1e-12)
        if cond == "enc16":  # 2^16 counts over +-0.2 rad
            q = 2 * np.pi / sd.ENC16
            assert q == pytest.approx(0.4 / 2**16, rel=1e-6)
            th = ref.runs[0].theta
            np.testing.assert_allclose(th / q, np.round(th / q), atol=1e-6)
        if cond == "prefilter":  # the rig file declares the filter the data went through
            assert back.filter["period_fraction"] == 0.1
            assert back.filter["channels"] == ["theta", "torque"]
    assert case.noise == float(f"{0.01 * scale:.3g}")


def _results(case, values, se_rel, family=None, heldout=None, effects=()):
    """A results.json of ``case``: ``values`` with 95 % intervals of +-1.96 SE (SE =
    ``se_rel`` of the value) and a held-out error (default: the floor)."""
    h = case.force_floor if heldout is None else heldout
    pars = {
        n: {
            "value": v,
            "ci95": [v - Z95 * se_rel * abs(v), v + Z95 * se_rel * abs(v)],
            "identifiable": True,
        }
        for n, v in values.items()
    }
    fit = {
        "family": family or case.family,
        "effects": list(effects),
        "parameters": pars,
        "rms": h,
        "heldout_rms": h,
    }
    return {"final": fit, "families": {case.family: copy.deepcopy(fit)}, "equal_fits": []}


def test_each_criterion_fails_when_it_should(bw_std):
    case = bw_std
    truth = sd.normalized_truth(case.family, case.params)
    assert truth["delta"] == pytest.approx(truth["beta"] + truth["gamma"])  # z_sat = 1
    good = _results(case, truth, 1e-3)
    rec = sd.evaluate(good, case)
    assert rec["success"] and all(rec["criteria"].values()), sd.why(rec)
    assert sorted(rec["checked"]) == sorted(truth)
    # family: another one selected (the true one fitted as well, not named equal)
    res = _results(case, truth, 1e-3, family="bouc-wen")
    res["families"][case.family] = good["final"]
    rec = sd.evaluate(res, case)
    assert not rec["criteria"]["family"] and not rec["success"]
    assert rec["criteria"]["params"] and rec["criteria"]["ci"], "judged on the true fit"
    # ... named among the equal fits with the same held-out error: right
    rec = sd.evaluate(res | {"equal_fits": [case.family]}, case)
    assert rec["criteria"]["family"] and rec["success"], sd.why(rec)
    # ... but with a held-out error worse by more than the band: wrong
    worse = copy.deepcopy(res) | {"equal_fits": [case.family]}
    band = 2 * case.force_floor / np.sqrt(2 * case.n_eff)
    worse["families"][case.family]["heldout_rms"] = case.force_floor + 1.5 * band
    rec = sd.evaluate(worse, case)
    assert not rec["criteria"]["family"] and rec["criteria"]["rms"]
    # an effect the data do not have
    rec = sd.evaluate(_results(case, truth, 1e-3, effects=["coulomb"]), case)
    assert not rec["criteria"]["family"]
    # params: 10 % off with a 1 % SE fails params and the intervals
    off = dict(truth, c_1=truth["c_1"] * 1.10)
    rec = sd.evaluate(_results(case, off, 1e-2), case)
    assert not rec["criteria"]["params"] and not rec["criteria"]["ci"]
    assert [o["name"] for o in rec["outside_data"]] == ["c_1"]
    # ... with a 5 % SE (the data cannot tell it to 5 %) it is within the data's limit
    rec = sd.evaluate(_results(case, off, 5e-2), case)
    assert rec["criteria"]["params"] and rec["criteria"]["ci"] and "c_1" in rec["data_limited"]
    # ci: 1 % off (within 5 %) but at 3.5 SE: beyond the simultaneous bound for 9
    near = dict(truth, alpha_2=truth["alpha_2"] * 1.01)
    rec = sd.evaluate(_results(case, near, 0.01 / 1.01 / 3.5), case)
    assert rec["criteria"]["params"] and not rec["criteria"]["ci"]
    assert rec["z"]["alpha_2"] == pytest.approx(3.5, rel=1e-6)
    assert rec["z_bound"] == pytest.approx(joint_z(len(truth))) and 2.7 < rec["z_bound"] < 3.5
    # ... at 2.5 SE: outside the plain interval (coverage counts it), inside the joint one
    rec = sd.evaluate(_results(case, near, 0.01 / 1.01 / 2.5), case)
    assert rec["criteria"]["ci"] and rec["success"] and len(rec["outside_ci"]) == 1
    # rms: the held-out error 20 % above the floor
    rec = sd.evaluate(_results(case, truth, 1e-3, heldout=1.2 * case.force_floor), case)
    assert not rec["criteria"]["rms"] and rec["heldout_ratio"] == pytest.approx(1.2)
    # ... and the propagated motion noise raises the floor
    rec = sd.evaluate(
        _results(case, truth, 1e-3, heldout=1.2 * case.force_floor),
        case,
        motion_floor=0.66 * case.force_floor,
    )
    assert rec["criteria"]["rms"] and rec["floor"] == pytest.approx(1.198 * case.force_floor, 1e-3)
    # ... but no model predicts the force noise itself: 15 % below it fails
    rec = sd.evaluate(
        _results(case, truth, 1e-3, heldout=0.85 * case.force_floor),
        case,
        motion_floor=0.66 * case.force_floor,
    )
    assert not rec["criteria"]["rms"]
    # ran: the true family missing from results.json (dropped by the fit)
    res = _results(case, truth, 1e-3, family="bouc-wen")
    res["families"] = {"bouc-wen": res["final"]}
    res["failed"] = {case.family: "diverged"}
    rec = sd.evaluate(res, case)
    assert not rec["success"] and "diverged" in rec["error"] and rec["criteria"]["ran"]
    rec = sd.crash_record(case, "hystdisc discover exited with 3: boom")
    assert not any(rec["criteria"].values()) and sd.why(rec).endswith("boom")


def test_the_delay_condition_expects_the_channel_delay_effect(bw_std):
    case = sd.Case(bw_std.family, 0, "delay", bw_std.params, bw_std.torque_rms, bw_std.rejected)
    truth = sd.normalized_truth(case.family, case.params)
    rec = sd.evaluate(_results(case, truth, 1e-3), case)
    assert not rec["criteria"]["family"] and "expected ['channel_delay']" in sd.why(rec)
    found = _results(case, {**truth, "tau_d": 0.00301}, 1e-2, effects=["channel_delay"])
    rec = sd.evaluate(found, case)
    assert rec["success"] and "tau_d" in rec["checked"], sd.why(rec)
    wrong = _results(case, {**truth, "tau_d": 0.0036}, 1e-2, effects=["channel_delay"])
    rec = sd.evaluate(wrong, case)
    assert not rec["criteria"]["params"] and rec["outside_data"][0]["name"] == "tau_d"


def test_one_small_case_end_to_end(tmp_path):
    # Bingham set 0 under white force noise, 2 s records, compared with Dahl only: a
    # fast, reduced case through the suite's own commands, floor and reading. Bingham has
    # no internal state; every criterion holds (held-out 1.014x the floor, largest z 0.89
    # against 2.58). The same case under ``motion`` fails today on rms (1.12x) and ci
    # (c_b at 6.4 SE): the intervals ignore the motion noise (issue 33 item 3)
    p, rej, scale = sd.sample_set("bingham", 0)
    case = sd.Case("bingham", 0, "white", p, scale, rej, duration=2.0, families=("bingham", "dahl"))
    rec = sd.run_case(case, tmp_path)
    assert rec["criteria"]["ran"], rec.get("error")
    assert rec["motion_floor"] == 0 and rec["floor"] == case.force_floor
    assert rec["success"], sd.why(rec)
    assert rec["selected"] == "bingham" and not rec["effects"]
    assert sorted(rec["checked"]) == sorted(sd.normalized_truth("bingham", p))


def test_release_reading_of_stored_cases(tmp_path):
    base = {
        "family": "dahl",
        "effects": [],
        "z": {"k_x": 1.0, "rho": 3.0},
        "checked": ["k_x", "rho"],
        "outside_ci": [{"name": "rho"}],
        "rms_ratio": 1.0,
        "criteria": {"family": True, "params_data": True, "rms": True, "ci_joint": True},
    }
    cases = [
        {**base, "case": "dahl/0/white", "condition": "white", "z": {"k_x": 1.0}},
        {**base, "case": "dahl/1/white", "condition": "white"}
        | {"criteria": {**base["criteria"], "ci_joint": False}},
        {**base, "case": "dahl/2/white", "condition": "white", "equal_fits": ["dahl"]}
        | {"criteria": {**base["criteria"], "family": False}},
    ]
    path = tmp_path / "stress_x.json"
    path.write_text(__import__("json").dumps({"cases": cases}))
    text = sd.release_reading([path])
    assert "| white | 3 | 2/3 | 3 | 3 | 3 | 2 | 3/6 (0.500) |" in text
    assert "`dahl/1/white`: fails ci" in text and "dahl/2/white" not in text
