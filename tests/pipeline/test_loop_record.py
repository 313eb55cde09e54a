"""The closing loop's typed records as the tables of ``results.json``
(hystdisc.pipeline.loop_record): every key, in the order the file has always had."""

from __future__ import annotations

from hystdisc.closing import AcceptedEffect, Diagnosis, EffectScore, EffectVerdict, ResidualVerdict
from hystdisc.closing.records import EffectParameter
from hystdisc.closing.structural import StartOutcome
from hystdisc.pipeline.loop_record import (
    diagnosis_round,
    effect_step,
    effect_trial,
    residual_summary,
)

BASE_TRIAL = [
    "name", "round", "evidence", "evidence_eq", "start_rms", "rms_before", "rms_after",
    "bic_before", "bic_after", "wald_chi2", "heldout_rms_before", "heldout_rms_after",
    "converged", "accepted", "admissible", "excess_share",
]  # fmt: skip


def _verdict(**kw) -> EffectVerdict:
    return EffectVerdict(
        "series_compliance", 2, evidence=0.5, rms_before=2e-3, rms_after=1e-3,
        bic_before=-100.0, bic_after=-200.0, converged=True, excess_share=0.9, **kw,
    )  # fmt: skip


def test_a_rejected_verdict_writes_its_note_then_what_it_points_at():
    v = _verdict()
    v.wants, v.improves, v.ok = "c_w = -1", False, True
    v.reject()
    d = effect_trial(v).to_dict()
    assert list(d) == [*BASE_TRIAL, "note", "points_at"]
    assert d["note"].startswith("the data want c_w = -1, which is not physical")


def test_a_structural_verdict_writes_its_starts_and_a_removed_one_why():
    starts = [StartOutcome("k_w", 400.0, 512.5, 1.0e-3, -200.0)]
    v = _verdict(starts=starts, starts_spread=None, restarted=True, accepted=False)
    v.removed, v.note = True, "offset made it redundant"
    d = effect_trial(v).to_dict()
    assert list(d) == [*BASE_TRIAL, "starts", "starts_spread", "restarted", "removed", "note"]
    assert d["starts"] == [{"k_w_start": 400.0, "k_w": 512.5, "rms": 0.001, "bic": -200.0}]
    assert d["starts_spread"] is None and d["restarted"] is True
    # an accepted refit writes the base keys alone
    assert list(effect_trial(_verdict(accepted=True)).to_dict()) == BASE_TRIAL


def test_an_accepted_effect_and_a_diagnosis_round_are_rounded_tables():
    a = AcceptedEffect(
        "coulomb", ("sign(theta_dot)",), {"f_c": EffectParameter(1 / 3, (float("nan"), 0.5))},
        2e-3, 1e-3, -100.0, -200.0, None, None, 0.25,
    )  # fmt: skip
    d = effect_step(a).to_dict()
    assert d["parameters"] == {"f_c": {"value": 0.3333333333, "ci95": [None, 0.5]}}
    assert d["terms"] == ["sign(theta_dot)"] and d["evidence_eq"] is None
    s = EffectScore("offset", ("1",), 0.2, [0.1, 0.3], 5.0, 1e-3, -20.0, {"theta_off": 0.02})
    row = diagnosis_round(Diagnosis(1, [s])).to_dict()
    assert row["round"] == 1 and list(row["candidates"][0])[-1] == "estimate"
    s.starts, s.signature = [{}, {}], "a resonance near 8 Hz"
    cand = diagnosis_round(Diagnosis(1, [s])).to_dict()["candidates"][0]
    assert cand["starts_screened"] == 2 and cand["signature"] == "a resonance near 8 Hz"


def test_the_residual_verdict_writes_the_noise_only_when_the_loop_used_one():
    r = ResidualVerdict(1e-3, 0.5, None, 1.0, None, "ljung-box", 0.5)
    assert "noise_used" not in residual_summary(r).to_dict()
    r.noise_used = 1e-3
    assert list(residual_summary(r).to_dict())[-1] == "noise_used"
