"""Shear thinning (issue 15 item 2a): a post-yield viscous torque ``c_st sign(w) |w|^m``.

The compiled term against its reference (numpy) evaluation, the effect's admissible
bounds, and the closing loop on synthetic Bouc-Wen data (driven and release, three
currents, noise) generated with the effect: it accepts ``shear_thinning`` (not a negative
``quadratic_damping``) with ``c_st`` and ``m`` near the truth and the error at the noise
floor; on the same family's data without the effect it claims nothing.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from hystdisc.cli import main
from hystdisc.data import read_csv
from hystdisc.data.envelope import Envelope, RunEnvelope
from hystdisc.estimator import Discovery
from hystdisc.models import (
    EFFECTS,
    SHEAR_M0,
    SHEAR_TERM,
    SIGN_EPS,
    Model,
    TermModel,
    smooth_power,
)
from hystdisc.models.compiled import N_BASE, base_coefficients, term_torque
from hystdisc.models.system import TermSystem
from hystdisc.results import term_model_from_dict, term_model_to_dict
from hystdisc.simulation import simulate_system
from hystdisc.simulation.admissibility import check_admissible
from hystdisc.simulation.runs import simulate_driven_runs, simulate_release
from hystdisc.simulation.synth import generate

FAMILY = "bouc-wen-std"
CURRENTS = (0.0, 0.5, 1.0)
DRIVES = ["0.1@1.0", "0.3@2.0"]
DRIVEN_NOISE = 0.01  # N*m
RELEASE_NOISE = 1e-3  # rad
# truths: driven c_st = 0.8, m = 0.45; release c_st = 0.8, m = 0.55
DRIVEN_TRUTH = {"c_st": 0.8, "m_st": 0.45}
RELEASE_TRUTH = {"c_st": 0.8, "m_st": 0.55}
#: tolerance on c_st (relative) and m (absolute)
C_TOL, M_TOL = 0.05, 0.03


# ----------------------------------------------------------------------------- the term


def test_compiled_term_matches_the_reference():
    rng = np.random.default_rng(3)
    for m in (0.2, 0.45, 1.0):
        tm = Model(FAMILY, effects={"shear_thinning": {"c_st": 0.7, "m_st": m}}).to_terms()
        assert tm.m == m and tm.torque[SHEAR_TERM] == 0.7
        for i in (0.0, 0.6):
            c = base_coefficients(tm, i)
            assert c.shape == (N_BASE,) and c[8] == 0.7 and c[9] == m
            for th, w, z in rng.normal(scale=(0.3, 3.0, 0.8), size=(20, 3)):
                ref = float(tm.eval_torque(th, w, z, i))
                assert term_torque(c, th, w, z, SIGN_EPS) == pytest.approx(ref, rel=1e-12)
    # the smoothed term is the power law beyond a few eps, odd, and exact at m = 1
    w = np.array([0.01, 0.1, 2.0, 30.0])
    np.testing.assert_allclose(smooth_power(w, 0.4), w**0.4, rtol=(1 - 0.4) * SIGN_EPS**2 / 2e-4)
    np.testing.assert_array_equal(smooth_power(-w, 0.4), -smooth_power(w, 0.4))
    np.testing.assert_array_equal(smooth_power(w, 1.0), w)
    # the slope at 0 is bounded: eps^(m - 1)
    assert float(smooth_power(1e-9, 0.3)) / 1e-9 == pytest.approx(SIGN_EPS**-0.7, rel=1e-6)


def test_absent_term_changes_nothing():
    """Without the term, its slots are 0 and the old coefficients are where they were."""
    tm = Model(FAMILY).to_terms()
    c = base_coefficients(tm, 0.5)
    assert c[8] == 0.0 and SHEAR_TERM not in tm.torque
    assert list(c[:8]) == [
        tm.torque.get("theta", 0.0),
        tm.torque["theta_dot"] + 0.5 * tm.torque["i*theta_dot"],
        tm.torque["z"] + 0.5 * tm.torque["i*z"],
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
    ]


def test_driven_kernel_adds_the_term_at_its_exponent():
    t = np.arange(2000) / 1000.0
    th, w = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    base = Model(FAMILY)
    eff = Model(FAMILY, effects={"shear_thinning": {"c_st": 0.5, "m_st": 0.35}})
    (p,), _ = simulate_driven_runs(base, [t], [0.7], [th], [w])
    (q,), _ = simulate_driven_runs(eff, [t], [0.7], [th], [w])
    np.testing.assert_array_equal(p.z, q.z)
    np.testing.assert_allclose(q.torque - p.torque, 0.5 * smooth_power(w, 0.35), atol=1e-12)


def test_release_kernel_matches_the_error_controlled_integrator():
    """The fixed-step kernel resolves the steep slope near w = 0 (release, m = 0.3)."""
    model = Model(FAMILY, effects={"shear_thinning": {"c_st": 1.5, "m_st": 0.3}})
    tm = model.to_terms()
    t = np.arange(3000) / 1000.0
    fixed = simulate_release(tm, t, 0.5, 0.3)
    ref = simulate_system(TermSystem(tm, "release"), t, [0.3, 0.0, 0.0], current=0.5)
    np.testing.assert_allclose(fixed.theta, ref.y, atol=2e-5 * 0.3)


def test_exponent_survives_sums_records_and_equations():
    tm = TermModel({"z": 1.0, SHEAR_TERM: 0.3}, {"theta_dot": 2.0}, m=0.4)
    assert (tm + TermModel({"theta": 5.0})).m == 0.4
    assert (TermModel({"theta": 5.0}) + tm).m == 0.4
    d = term_model_to_dict(tm)
    assert d["m"] == 0.4 and term_model_from_dict(d).m == 0.4
    assert "m" not in term_model_to_dict(TermModel({"z": 1.0}))
    assert "0.3 sign(theta_dot)*|theta_dot|^0.4" in tm.equations()


def test_admissible_bounds():
    eff = EFFECTS["shear_thinning"]
    assert eff.inadmissible({"c_st": 0.0, "m_st": 1.0}) == []
    assert eff.inadmissible({"c_st": 2.0, "m_st": 1e-3}) == []
    assert eff.inadmissible({"c_st": -0.1, "m_st": 0.5}) == ["c_st"]
    assert eff.inadmissible({"c_st": 0.1, "m_st": 1.2}) == ["m_st"]
    assert eff.inadmissible({"c_st": 0.1, "m_st": 0.0}) == ["m_st"]
    assert eff.off_values() == {"c_st": 0.0, "m_st": SHEAR_M0}
    env = Envelope([RunEnvelope("0", 0.0, 0.3, 3.0, 6.0), RunEnvelope("1", 1.0, 0.3, 3.0, 6.0)])
    for c_st, m in [(0.0, 0.5), (2.0, 0.05), (2.0, 0.5), (0.5, 1.0)]:
        tm = Model(FAMILY, effects={"shear_thinning": {"c_st": c_st, "m_st": m}}).to_terms()
        assert check_admissible(tm, env).ok
    # the negative coefficient generates energy; the hint of quadratic damping names it
    tm = Model(FAMILY, {"c_1": 0.0, "c_2": 0.0}).to_terms()
    tm.torque[SHEAR_TERM] = -0.5
    assert not check_admissible(tm, env).ok
    assert "shear_thinning" in EFFECTS["quadratic_damping"].hint


def test_simulate_command_generates_the_effect(tmp_path, capsys):
    out = tmp_path / "st.csv"
    args = ["simulate", "--model", FAMILY, "--experiment", "driven", "--drive", "0.3@1"]
    args += ["--currents", "0,1", "--duration", "1", "--noise", "0", "--quiet", "-o", str(out)]
    assert main([*args, "--effect", "shear_thinning:c_st=0.8,m_st=0.45"]) == 0
    assert main([*args[:-1], str(tmp_path / "plain.csv")]) == 0
    capsys.readouterr()
    with_eff, plain = read_csv(out), read_csv(tmp_path / "plain.csv")
    for a, b in zip(with_eff.runs, plain.runs, strict=True):
        w = 0.3 * 2 * np.pi * np.cos(2 * np.pi * a.t)  # the drive's velocity
        # the CSV keeps 7 significant digits of each torque
        tol = 1e-6 * np.abs(a.torque).max()
        np.testing.assert_allclose(a.torque - b.torque, 0.8 * smooth_power(w, 0.45), atol=tol)


# ----------------------------------------------------------------------------- the loop


@cache
def _driven(effect: bool):
    eff = {"shear_thinning": DRIVEN_TRUTH} if effect else {}
    data = generate(
        Model(FAMILY, effects=eff),
        "driven",
        currents=CURRENTS,
        duration=2.0,
        noise=DRIVEN_NOISE,
        seed=21,
        drives=DRIVES,
    )
    return Discovery(model=FAMILY, heldout=False).fit(data)


@cache
def _release(effect: bool):
    eff = {"shear_thinning": RELEASE_TRUTH} if effect else {}
    data = generate(
        Model(FAMILY, effects=eff), currents=CURRENTS, duration=3.0, noise=RELEASE_NOISE, seed=22
    )
    return Discovery(model=FAMILY, heldout=False).fit(data)


def _check_found(disc, truth, noise):
    res = disc.results_
    assert disc.effects_ == ["shear_thinning"], res.effects_tried
    tried = {e["name"]: e for e in res.effects_tried}
    assert "quadratic_damping" not in tried or not tried["quadratic_damping"]["accepted"]
    (entry,) = res.effects
    assert entry["rms_before"] > 1.3 * noise
    assert abs(entry["rms_after"] / noise - 1.0) < 0.10
    c, m = entry["parameters"]["c_st"], entry["parameters"]["m_st"]
    assert c["value"] == pytest.approx(truth["c_st"], rel=C_TOL)
    assert m["value"] == pytest.approx(truth["m_st"], abs=M_TOL)
    assert 0.0 < m["value"] <= 1.0
    for p in (c, m):
        assert p["ci95"][0] < p["value"] < p["ci95"][1]
    assert res.final.admissible is True
    assert res.term_model().m == pytest.approx(m["value"])


def test_loop_finds_shear_thinning_in_driven_data():
    _check_found(_driven(True), DRIVEN_TRUTH, DRIVEN_NOISE)


def test_loop_finds_shear_thinning_in_release_data():
    _check_found(_release(True), RELEASE_TRUTH, RELEASE_NOISE)


@pytest.mark.parametrize("case", [_driven, _release], ids=["driven", "release"])
def test_nothing_is_claimed_without_the_effect(case):
    disc = case(False)
    assert disc.effects_ == [], disc.results_.effects_tried
    assert disc.results_.unexplained is False
