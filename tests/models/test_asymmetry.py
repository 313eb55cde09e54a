"""Damping and yield that differ in tension and compression (issue 35 item 3):
``asymmetric_damping``, a share ``r_c`` of the model's viscous damping that changes sign
with the velocity, ``c(i) theta_dot (1 + r_c sign(theta_dot))``, and ``asymmetric_yield``,
a share ``r_y`` of its hysteretic torque that changes sign with ``z``,
``alpha(i) z (1 + r_y sign(z))``.

The terms in the compiled torque against their reference (numpy) evaluation, the share of
the whole law (current laws, a saturating law, an effect that adds to it), the bounds
that keep the damping and the yield force non-negative in both directions (which the
energy check cannot see), and the closing loop on driven data generated with the share
drawn at random (fixed seeds): it names the effect (the yield's, not a per-current bias),
recovers the share and predicts held-out conditions at the noise; on the same damper
without them, it claims nothing.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from hystdisc.data.envelope import Envelope, RunEnvelope
from hystdisc.estimator import Discovery
from hystdisc.models import EFFECTS, SIGN_EPS, Model, TermModel, apply_effects
from hystdisc.models.compiled import base_coefficients, term_torque
from hystdisc.simulation.admissibility import check_admissible
from hystdisc.simulation.runs import simulate_driven_runs
from hystdisc.simulation.synth import generate

FAMILY = "bouc-wen-std"
NAME = "asymmetric_damping"
YIELD = "asymmetric_yield"
CURRENTS = (0.0, 0.5, 1.0)
DRIVES = ["0.1@1.0", "0.3@2.0"]
NOISE = 0.01  # N*m
#: Absolute tolerance on r_c and r_y (measured: within 2e-4 of the truth).
R_TOL = 2e-3


def _truth(seed: int) -> float:
    """A share drawn at random: 0.1-0.9, random sign."""
    rng = np.random.default_rng(seed)
    return float(rng.uniform(0.1, 0.9) * rng.choice([-1.0, 1.0]))


# ----------------------------------------------------------------------------- the term


def test_compiled_torque_is_the_damping_times_one_plus_or_minus_r():
    c1, c2, r = 0.5, 0.6, 0.4
    model = Model(FAMILY, {"c_1": c1, "c_2": c2}, effects={NAME: {"r_c": r}})
    tm = model.to_terms()
    assert tm.torque["|theta_dot|"] == pytest.approx(r * c1)
    assert tm.torque["i*|theta_dot|"] == pytest.approx(r * c2)
    plain = Model(FAMILY, {"c_1": c1, "c_2": c2}).to_terms()
    rng = np.random.default_rng(5)
    for i in (0.0, 0.8):
        c = base_coefficients(tm, i)
        assert c[10] == pytest.approx(r * (c1 + c2 * i))
        assert base_coefficients(plain, i)[10] == 0.0
        for th, w, z in rng.normal(scale=(0.3, 3.0, 0.8), size=(20, 3)):
            ref = float(tm.eval_torque(th, w, z, i))
            assert term_torque(c, th, w, z, SIGN_EPS) == pytest.approx(ref, rel=1e-12)
            # the viscous part is c(i) (1 + r sign(w)) w
            extra = ref - float(plain.eval_torque(th, w, z, i))
            assert extra == pytest.approx((c1 + c2 * i) * r * abs(w), rel=1e-12)


def test_driven_kernel_adds_the_share_in_each_direction():
    t = np.arange(2000) / 1000.0
    th, w = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    base = Model(FAMILY)
    eff = Model(FAMILY, effects={NAME: {"r_c": -0.3}})
    (p,), _ = simulate_driven_runs(base, [t], [0.7], [th], [w])
    (q,), _ = simulate_driven_runs(eff, [t], [0.7], [th], [w])
    np.testing.assert_array_equal(p.z, q.z)
    c = 0.5 + 0.6 * 0.7  # the defaults' damping at 0.7 A
    np.testing.assert_allclose(q.torque - p.torque, -0.3 * c * np.abs(w), atol=1e-12)


def test_the_share_is_of_the_whole_damping_law():
    """Its current laws (quadratic, saturating) and an effect that adds damping are
    scaled too, whatever the order the effects are given in."""
    tm = Model(FAMILY, {"c_2": 0.6, "c_i0": 0.4}).to_terms()  # a saturating damping law
    assert tm.saturation == {"theta_dot": 0.4}
    out = apply_effects(
        tm, [EFFECTS[NAME], EFFECTS["current_viscous"]], {"r_c": 0.5, "c_i": 0.2}, 0.0
    )
    assert out.saturation["|theta_dot|"] == 0.4
    assert out.torque["i*|theta_dot|"] == pytest.approx(0.5 * (0.6 + 0.2))
    for i in (0.3, 1.0):
        c = base_coefficients(out, i)
        assert c[10] == pytest.approx(0.5 * c[1])
    quad = TermModel({"theta_dot": 1.0, "i^2*theta_dot": 0.3})
    EFFECTS[NAME].apply(quad, {"r_c": -0.5}, 0.0)
    assert quad.torque["i^2*|theta_dot|"] == pytest.approx(-0.15)
    assert base_coefficients(quad, 2.0)[10] == pytest.approx(-0.5 * (1.0 + 0.3 * 4.0))


def test_bounds_keep_the_damping_non_negative_in_both_directions():
    eff = EFFECTS[NAME]
    assert eff.inadmissible({"r_c": 1.0}) == [] and eff.inadmissible({"r_c": -1.0}) == []
    assert eff.inadmissible({"r_c": 1.2}) == ["r_c"]
    assert eff.inadmissible({"r_c": -1.01}) == ["r_c"]
    assert eff.off_values() == {"r_c": 0.0}
    assert [p.unit for p in eff.params] == ["1"]
    assert eff.hint and eff.doc
    # |theta_dot| does no net work over a symmetric cycle: the energy check passes a
    # damping that is negative in one direction, so the bounds are what rule it out
    env = Envelope([RunEnvelope("0", 0.0, 0.3, 3.0, 6.0), RunEnvelope("1", 1.0, 0.3, 3.0, 6.0)])
    tm = Model(FAMILY).to_terms()
    EFFECTS[NAME].apply(tm, {"r_c": 1.5}, 0.0)  # 2.5 c forward, -0.5 c backward
    assert check_admissible(tm, env).ok
    # stage 1's coefficients map to the share (of the damping at 0.5 A), within bounds
    assert eff.from_torque({"theta_dot": 0.5, "i*theta_dot": 0.6, "|theta_dot|": 0.4}, 0.0) == {
        "r_c": pytest.approx(0.4 / 0.8)
    }
    assert eff.from_torque({"theta_dot": 0.1, "|theta_dot|": -0.4}, 0.0) == {"r_c": -1.0}
    assert eff.from_torque({"|theta_dot|": 0.4}, 0.0) == {"r_c": 0.0}


def test_compiled_torque_is_the_yield_times_one_plus_or_minus_r():
    a1, a2, r = 0.5, 1.5, -0.35
    model = Model(FAMILY, {"alpha_1": a1, "alpha_2": a2}, effects={YIELD: {"r_y": r}})
    tm = model.to_terms()
    assert tm.torque["|z|"] == pytest.approx(r * a1)
    assert tm.torque["i*|z|"] == pytest.approx(r * a2)
    plain = Model(FAMILY, {"alpha_1": a1, "alpha_2": a2}).to_terms()
    rng = np.random.default_rng(6)
    for i in (0.0, 0.8):
        c = base_coefficients(tm, i)
        assert c[11] == pytest.approx(r * (a1 + a2 * i))
        assert base_coefficients(plain, i)[11] == 0.0
        for th, w, z in rng.normal(scale=(0.3, 3.0, 0.8), size=(20, 3)):
            ref = float(tm.eval_torque(th, w, z, i))
            assert term_torque(c, th, w, z, SIGN_EPS) == pytest.approx(ref, rel=1e-12)
            # the hysteretic part is alpha(i) (1 + r sign(z)) z
            extra = ref - float(plain.eval_torque(th, w, z, i))
            assert extra == pytest.approx((a1 + a2 * i) * r * abs(z), rel=1e-12)
    # a saturating law of alpha is the share's too
    sat = Model(FAMILY, {"alpha_i0": 0.4}, effects={YIELD: {"r_y": 0.5}}).to_terms()
    assert sat.saturation["|z|"] == sat.saturation["z"] == 0.4
    assert base_coefficients(sat, 0.9)[11] == pytest.approx(0.5 * base_coefficients(sat, 0.9)[2])


def test_driven_kernel_adds_the_yield_share_on_the_same_state():
    t = np.arange(2000) / 1000.0
    th, w = 0.2 * np.sin(2 * np.pi * t), 0.4 * np.pi * np.cos(2 * np.pi * t)
    base = Model(FAMILY, {"k_s": 0.0})
    eff = Model(FAMILY, {"k_s": 0.0}, effects={YIELD: {"r_y": 0.45}})
    (p,), _ = simulate_driven_runs(base, [t], [0.7], [th], [w])
    (q,), _ = simulate_driven_runs(eff, [t], [0.7], [th], [w])
    np.testing.assert_array_equal(p.z, q.z)
    a = 0.5 + 1.5 * 0.7  # the defaults' hysteretic torque at 0.7 A
    np.testing.assert_allclose(q.torque - p.torque, 0.45 * a * np.abs(p.z), atol=1e-12)
    # the post-yield branches: (1 +- r) alpha where z is saturated
    up, down = q.z > 0.99, q.z < -0.99
    assert up.any() and down.any()
    hyst_up = (q.torque - (0.5 + 0.6 * 0.7) * w)[up]
    hyst_down = (q.torque - (0.5 + 0.6 * 0.7) * w)[down]
    assert np.max(np.abs(hyst_up - 1.45 * a * q.z[up])) < 1e-12
    assert np.max(np.abs(hyst_down - 0.55 * a * q.z[down])) < 1e-12


def test_yield_bounds_keep_the_yield_force_non_negative_in_both_directions():
    eff = EFFECTS[YIELD]
    assert eff.inadmissible({"r_y": -1.0}) == [] and eff.inadmissible({"r_y": 1.3}) == ["r_y"]
    assert eff.off_values() == {"r_y": 0.0}
    assert [p.unit for p in eff.params] == ["1"]
    assert eff.hint and eff.doc
    env = Envelope([RunEnvelope("0", 0.0, 0.3, 3.0, 6.0), RunEnvelope("1", 1.0, 0.3, 3.0, 6.0)])
    tm = Model(FAMILY).to_terms()
    EFFECTS[YIELD].apply(tm, {"r_y": -1.5}, 0.0)  # a negative yield force in tension
    assert check_admissible(tm, env).ok  # the energy check cannot see it: the bounds do
    assert eff.from_torque({"z": 0.5, "i*z": 1.5, "|z|": 0.5}, 0.0) == {
        "r_y": pytest.approx(0.5 / 1.25)
    }
    assert eff.from_torque({"z": 0.1, "|z|": 0.4}, 0.0) == {"r_y": 1.0}


# ----------------------------------------------------------------------------- the loop


@cache
def _driven(effect: str | None, share: float, seed: int):
    key = {NAME: "r_c", YIELD: "r_y"}
    eff = {} if effect is None else {effect: {key[effect]: share}}
    data = generate(
        Model(FAMILY, {"k_s": 0.0}, effects=eff),
        "driven",
        currents=CURRENTS,
        duration=2.0,
        noise=NOISE,
        seed=seed,
        drives=DRIVES,
    )
    return Discovery(model=FAMILY, heldout=False).fit(data)


@pytest.mark.parametrize(
    ("effect", "key", "seed"),
    [(NAME, "r_c", 1), (NAME, "r_c", 2), (YIELD, "r_y", 1), (YIELD, "r_y", 2)],
)
def test_loop_finds_the_asymmetry(effect, key, seed):
    share = _truth(seed)
    disc = _driven(effect, share, seed)
    res = disc.results_
    # the yield's asymmetry is not taken for a bias per current level, nor the other way
    assert disc.effects_ == [effect], res.effects_tried
    (entry,) = res.effects
    assert entry["rms_before"] > 5 * NOISE
    assert abs(entry["rms_after"] / NOISE - 1.0) < 0.05
    assert entry["heldout_rms_before"] > 5 * NOISE
    assert entry["heldout_rms_after"] < 1.05 * NOISE
    p = entry["parameters"][key]
    assert p["value"] == pytest.approx(share, abs=R_TOL)
    assert p["ci95"][0] < p["value"] < p["ci95"][1]
    assert res.final.admissible is True
    assert res.unexplained is False


def test_nothing_is_claimed_without_an_asymmetry():
    disc = _driven(None, 0.0, 1)
    assert disc.effects_ == [], disc.results_.effects_tried
    assert disc.results_.unexplained is False
    skipped = {s.name for s in disc.loop_.skipped}
    assert NAME not in skipped and YIELD not in skipped  # both were candidates
