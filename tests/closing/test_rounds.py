"""Which candidates a round of the closing loop refits (hystdisc.closing.rounds)."""

from __future__ import annotations

from types import SimpleNamespace

from hystdisc.closing.rounds import MAX_REFITS_PER_ROUND, refit_queue
from hystdisc.closing.scores import EffectScore
from hystdisc.discovery.delay import DelayScan
from hystdisc.pipeline.close import seen_delay


def _score(name: str, dbic: float) -> EffectScore:
    return EffectScore(name, (), evidence=-dbic, per_run=[], lm=0.0, predicted_rms=1.0,
                       predicted_dbic=dbic, estimate={})  # fmt: skip


def test_the_queue_is_the_top_two_by_evidence_and_what_an_earlier_step_saw():
    scores = [_score("a", -90.0), _score("b", -50.0), _score("c", -20.0), _score("d", -3.0)]
    assert [s.name for s in refit_queue(scores)] == ["a", "b"]
    # an effect seen by an earlier step is refitted first, whatever its rank or its
    # predicted BIC drop (here below the margin), and the usual queue follows
    first = [s.name for s in refit_queue(scores, ("d",))]
    assert first == ["d", "a", "b"] and len(first) <= MAX_REFITS_PER_ROUND + 1
    assert [s.name for s in refit_queue(scores, ("a",))] == ["a", "b"]  # not twice
    assert [s.name for s in refit_queue(scores, ("x",))] == ["a", "b"]  # not a candidate


def test_a_delay_the_scan_saw_but_did_not_call_goes_to_the_loop():
    def state(found: bool, dbic: float) -> SimpleNamespace:
        return SimpleNamespace(delay_scan=DelayScan(0.0, dbic, 0.2, found, 0.01))

    assert seen_delay(state(False, -2400.0)) == ("channel_delay",)
    assert seen_delay(state(True, -2400.0)) == ()  # found: it entered every family
    assert seen_delay(state(False, 9.4)) == ()  # nothing seen
    assert seen_delay(SimpleNamespace(delay_scan=None)) == ()  # not scanned


def test_each_folds_heldout_error():
    """One RMS per held-out fold (a test condition's runs pooled), masked samples out."""
    import numpy as np

    from hystdisc.closing.records import EffectVerdict
    from hystdisc.closing.rounds import fold_rms

    y = [np.zeros(4), np.zeros(4), np.zeros(4)]
    data = SimpleNamespace(
        y=y,
        mask=[np.array([True, True, True, False])] * 3,
        folds=lambda: [[0, 2], [1]],  # runs 0 and 2 share a test condition
    )
    preds = [np.array([1.0, 1.0, 1.0, 99.0]), np.full(4, 2.0), np.array([3.0, 3.0, 3.0, 0.0])]
    rms = fold_rms(data, SimpleNamespace(heldout_predictions=preds))
    assert rms == [np.sqrt(5.0), 2.0]
    assert fold_rms(data, SimpleNamespace(heldout_predictions=None)) is None
    # the verdict says how many folds it lowered when that decided it
    v = EffectVerdict("shear_thinning", 1, 0.2, rms_before=2.0, rms_after=1.9, bic_before=0.0,
                      bic_after=-300.0, wald_chi2=100.0, heldout_rms_before=2.0,
                      heldout_rms_after=1.8, ok=True, significant=True, excess_share=0.05,
                      heldout_folds=6, heldout_folds_lower=5)  # fmt: skip
    assert v.rejection() == (
        "removes only 5 % of the residual's excess over the noise and lowers the held-out "
        "error in 5 of its 6 held-out folds"
    )


def test_a_verdict_rejected_for_its_share_alone_is_one_to_try_again():
    """The loop tries an effect again once the excess shrank when the share of the excess
    was the only test it failed; any other failed test keeps it rejected."""
    from dataclasses import replace

    from hystdisc.closing.records import EffectVerdict

    v = EffectVerdict("level_bias", 3, 0.07, rms_before=0.14, rms_after=0.137, bic_before=0.0,
                      bic_after=-1188.0, wald_chi2=400.0, heldout_rms_before=0.17,
                      heldout_rms_after=0.168, ok=True, significant=True, excess_share=0.07,
                      heldout_folds=3, heldout_folds_lower=3)  # fmt: skip
    assert v.share_only
    assert not replace(v, significant=False).share_only
    assert not replace(v, predicts=False).share_only
    assert not replace(v, admissible=False).share_only
    assert not replace(v, bic_after=-1.0).share_only  # BIC not lowered by the margin
    assert not replace(v, improves=True).share_only  # it passed the share: not rejected for it
    assert not replace(v, ok=False).share_only
