"""Damping that differs in tension and compression (issue 35 item 3):
``asymmetric_damping``, a share ``r_c`` of the model's viscous damping that changes sign
with the velocity, ``c(i) theta_dot (1 + r_c sign(theta_dot))``.

The term in the compiled torque against its reference (numpy) evaluation, the share of
the whole damping law (current laws, a saturating law, an effect that adds to it), the
bounds that keep the damping non-negative in both directions (which the energy check
cannot see), and the closing loop on driven data generated with ``r_c`` drawn at random
(fixed seeds): it names the effect, recovers ``r_c`` and predicts held-out conditions at
the noise; on the same damper without it, it claims nothing.
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
CURRENTS = (0.0, 0.5, 1.0)
DRIVES = ["0.1@1.0", "0.3@2.0"]
NOISE = 0.01  # N*m
#: Absolute tolerance on r_c (measured: within 2e-4 of the truth).
R_TOL = 2e-3


def _truth(seed: int) -> float:
    """``r_c`` drawn at random: 0.1-0.9 of the damping, random sign."""
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


# ----------------------------------------------------------------------------- the loop


@cache
def _driven(r_c: float | None, seed: int):
    eff = {} if r_c is None else {NAME: {"r_c": r_c}}
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


@pytest.mark.parametrize("seed", [1, 2])
def test_loop_finds_asymmetric_damping(seed):
    r_c = _truth(seed)
    disc = _driven(r_c, seed)
    res = disc.results_
    assert disc.effects_ == [NAME], res.effects_tried
    (entry,) = res.effects
    assert entry["rms_before"] > 5 * NOISE
    assert abs(entry["rms_after"] / NOISE - 1.0) < 0.05
    assert entry["heldout_rms_before"] > 5 * NOISE
    assert entry["heldout_rms_after"] < 1.05 * NOISE
    p = entry["parameters"]["r_c"]
    assert p["value"] == pytest.approx(r_c, abs=R_TOL)
    assert p["ci95"][0] < p["value"] < p["ci95"][1]
    assert res.final.admissible is True
    assert res.unexplained is False


def test_nothing_is_claimed_without_asymmetric_damping():
    disc = _driven(None, 1)
    assert disc.effects_ == [], disc.results_.effects_tried
    assert disc.results_.unexplained is False
    assert NAME not in {s["name"] for s in disc.loop_.skipped}  # it was a candidate
