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
