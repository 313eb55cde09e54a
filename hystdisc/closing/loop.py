"""Closing the loop: residual -> the catalogued effect the model lacks -> refit -> whiteness.

Section 6 of ``doc/design.rst``, issue 4. After the output-error fit of the selected (or declared)
family:

1. **Candidates.** The effect catalogue (:data:`hystdisc.models.EFFECTS`) minus the effects
   whose torque terms the model already has (Bouc-Wen and LuGre carry ``i*theta_dot``,
   Bingham ``sign(theta_dot)``), the effects that need a hysteretic state the model lacks
   (``i^2*z`` in Bingham), the current effects the currents cannot identify (one current
   level; ``i^2`` needs three levels) and the spring effects (``offset``, ``cubic_stiffness``)
   when the rig has no spring (``k_s`` not significantly above 0, a characterization
   machine); ``channel_delay`` (no torque term) only for experiments with two recorded
   channels (driven, forced).
2. **Diagnosis** (:func:`~hystdisc.closing.scores.score_effects`): the score (Lagrange-multiplier) test in
   output-error space. All candidates are appended to the model at value 0, and one
   Jacobian of the fitter at the current optimum gives each effect's
   signature ``g`` (how the simulated output moves when the effect is switched on) beside
   the model's own columns ``A`` (parameters and initial angles). ``g`` is projected out of
   the span of ``A``; what the projected column explains of the residual is the
   Gauss-Newton predicted RSS reduction of adding the effect and refitting everything.
   Its share of the RSS is the effect's *evidence* (pooled, and each run's part), and it
   predicts the BIC change ``N log(1 - share) + q log N``. Two more views guard against
   the local view's blind spots (a fast hysteretic state mimics Coulomb friction to first
   order; a model stuck in a wrong optimum has a misleading Jacobian): the
   *equation-error evidence* (the same share for the equation residual
   ``target - T(theta, theta_dot, z, i)`` and the effect's torque term, the model's terms
   projected out) and, while the residual is clearly above the noise, the *stage-1 start*
   of each augmented structure (variable projection of family + effect on the
   equation-error data, simulated: :func:`~hystdisc.closing.refit.stage1_start`).
   A structural effect (a compliant wheel) is diagnosed by screening its grid of starts
   (:func:`~hystdisc.closing.structural.score_structural`, a dozen short fits; a later
   round screens the best cells of the first only). It is not deferred until the term
   refits have failed: a mild wheel leaves a misfit within 10 % of the noise, which cubic
   stiffness trims enough to look done.
3. **Augmentation** (:func:`augment`): per round, the top two candidates by output-error
   evidence and the top by equation-error evidence whose predicted BIC drop beats
   :data:`EFFECT_BIC_MARGIN` are refitted by output error (from the current optimum with
   the Gauss-Newton estimate of the effect); when that does not reach the noise, the
   candidate with the best stage-1 start is refitted from it (first, when the residual is
   far above the noise). A refit is accepted when it lowers BIC by more than the margin,
   its effect parameter is significant on its own (squared z-score above ``log N``) and it
   removes at least :data:`MIN_EXCESS_SHARE` of the residual's excess over the noise; the
   best accepted refit of the round wins, earlier effects that it makes redundant are
   dropped again, the residual is re-diagnosed, and the loop repeats until nothing is
   accepted. Only candidates with evidence are refitted: on data the model explains, the
   loop costs one Jacobian.
4. **Whiteness** (:func:`~hystdisc.closing.residual.assess_residual`): the final residual is tested by a Ljung-Box
   test pooled over runs and its spectrum is averaged over runs; with a sample of the
   noise (a periodic excitation), against the noise's own spectrum instead. When it is not white and
   its RMS is clearly above the noise (:data:`NOISE_RATIO`), ``unexplained`` is set with
   the dominant frequency and a sentence such as "a resonance near 6.0 Hz that no
   catalogued effect explains".

:func:`close_loop` runs all of it on the selected family's fit and returns the
:class:`LoopResult`; :class:`~hystdisc.estimator.Discovery` stores it (``loop_``,
``final_fit_``, ``effects_``) and the results layer writes it into ``results.json``.
The parts live in :mod:`~hystdisc.closing.scores` (diagnosis),
:mod:`~hystdisc.closing.refit` (candidates, starts, refits) and
:mod:`~hystdisc.closing.residual` (whiteness).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from hystdisc.closing.refit import (
    EFFECT_BIC_MARGIN,
    candidate_effects,
    fit_ok,
    refit_with,
    refit_without,
    screen_starts,
    stage1_start,
)
from hystdisc.closing.residual import (
    NOISE_RATIO,
    accuracy_floor,
    assess_residual,
    natural_frequency,
)
from hystdisc.closing.scores import EffectScore, score_effects, wald_chi2
from hystdisc.closing.structural import StructuralRefit, refit_structural, score_structural
from hystdisc.data.envelope import Envelope
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.faults import Failures, reason_of
from hystdisc.fitting import (
    FamilyParametrization,
    FamilySystemParametrization,
    OEFit,
    OutputErrorFitter,
)
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS
from hystdisc.simulation.admissibility import check_admissible
from hystdisc.stats import masked, sampling_rate

#: Local refits per round at most (two output-error leaders, the equation-error leader);
#: the stage-1 screening may add one more.
MAX_REFITS_PER_ROUND = 3
#: Refits from stage-1 starts per screening at most.
SCREEN_REFITS = 2
#: A stage-1 start within this factor of the current RMS is refitted when screened.
START_NEAR = 1.5
#: An accepted effect must also remove at least this share of the residual's excess over
#: the noise (RSS - N noise^2): a catalogued effect that only trims a structure it cannot
#: explain (a resonance) is not reported as found, whatever the sample size makes of it.
MIN_EXCESS_SHARE = 0.1
#: Above this many times the noise the current optimum may be a trap for the local views:
#: the stage-1 starts of the augmented structures are screened first.
FAR_RATIO = 5.0
#: ``restart(effect, values, par) -> start or None``: a full start of the model ``par``
#: (the current one) plus ``effect`` that does not rely on the current optimum, given
#: ``values`` of a start or refit of that structure (the effect's own among them): the
#: offset's (:func:`~hystdisc.closing.shift.shift_restart`) fits the family again on the
#: angle shifted by ``values["theta_off"]``; None for the other effects.
Restart = Callable[[str, dict, "FamilyParametrization"], "dict | None"]


@dataclass
class LoopResult:
    """Outcome of :func:`augment`.

    Attributes
    ----------
    base : OEFit
        The fit the loop started from.
    fit : OEFit
        The final fit (the base fit plus every accepted effect).
    effects : list of str
        Accepted effects, in the order they were added.
    tried : list of dict
        Every refitted effect: name, evidence, RMS and BIC before and after, accepted.
    accepted : list of dict
        Accepted effects in the ``results.json`` format (parameters from the final fit).
    diagnosis : list of dict
        One entry per round: the ranked scores of every candidate.
    skipped : list of dict
        Catalogued effects not considered, with the reason.
    residual : dict
        ``rms``, ``whiteness_p``, ``dominant_hz`` (and more) of the final residual.
    unexplained : bool
        True when structure remains that no catalogued effect removes.
    unexplained_text : str or None
        That structure in plain words.
    """

    base: OEFit
    fit: OEFit
    effects: list[str] = field(default_factory=list)
    tried: list[dict] = field(default_factory=list)
    accepted: list[dict] = field(default_factory=list)
    diagnosis: list[dict] = field(default_factory=list)
    skipped: list[dict] = field(default_factory=list)
    residual: dict = field(default_factory=dict)
    unexplained: bool = False
    unexplained_text: str | None = None


def _effect_entry(
    name: str, final: OEFit, step: dict, before: OEFit | None, after: OEFit | None
) -> dict:
    """An accepted effect in the ``results.json`` format.

    ``before``/``after`` are the fits without and with the effect along the final chain of
    accepted effects (when an effect was removed again, the chain is recomputed from the
    fits at hand); without them the values at the time of acceptance are used.
    """
    params = {}
    for p in EFFECTS[name].params:
        lo, hi = final.ci95.get(p.name, (float("nan"), float("nan")))
        params[p.name] = {"value": final.params.get(p.name), "ci95": [lo, hi]}
    pair = before is not None and after is not None
    return {
        "name": name,
        "terms": list(EFFECTS[name].terms),
        "parameters": params,
        "rms_before": before.rms if pair else step["rms_before"],
        "rms_after": after.rms if pair else step["rms_after"],
        "bic_before": before.bic if pair else step["bic_before"],
        "bic_after": after.bic if pair else step["bic_after"],
        "heldout_rms_before": before.heldout_rms if pair else step.get("heldout_rms_before"),
        "heldout_rms_after": after.heldout_rms if pair else step.get("heldout_rms_after"),
        "evidence": step["evidence"],
        "evidence_eq": step.get("evidence_eq"),
    }


def _structural_scores(data, current, names, cells: dict, say) -> list[EffectScore]:
    """The diagnoses of the structural effects ``names``; ``cells`` keeps each one's best
    screened cells, which a later round screens alone."""
    out = []
    for c in names:
        say(f"closing the loop: starts of {c}")
        sc = score_structural(data, current, c, cells=cells.get(c))
        if sc is not None:
            out.append(sc)
            cells[c] = sc.cells
    return out


def _refit_queue(scores: list[EffectScore]) -> list[EffectScore]:
    """Candidates worth a local output-error refit this round (at most three).

    The top two candidates by output-error evidence and the top by equation-error
    evidence (a second view that catches an effect the model's own terms mimic locally),
    each only when its predicted BIC drop beats the margin. Both output-error leaders are
    refitted because a hysteretic state mimics several effects to first order (a fast
    ``z`` looks like Coulomb friction), so the local ranking of close candidates is not
    trusted; the refits decide.
    """
    sig_oe = [s for s in scores if s.predicted_dbic < -EFFECT_BIC_MARGIN]
    sig_eq = sorted(
        (
            s
            for s in scores
            if s.predicted_dbic_eq is not None and s.predicted_dbic_eq < -EFFECT_BIC_MARGIN
        ),
        key=lambda s: -(s.evidence_eq or 0.0),
    )
    structural = [
        s
        for s in scores
        if s.starts is not None and (s.predicted_dbic < -EFFECT_BIC_MARGIN or s.signature)
    ]
    sig_oe = [s for s in sig_oe if s.starts is None]
    queue = sig_oe[:2]
    if sig_eq and sig_eq[0] not in queue:
        queue.append(sig_eq[0])
    # a structural effect's evidence is an achieved fit at a start, not a local
    # prediction: it is refitted whenever a start predicts a BIC drop or the residual
    # shows its signature
    return queue[:MAX_REFITS_PER_ROUND] + structural


def _start_pick(scores: list[EffectScore]) -> EffectScore | None:
    """The candidate whose stage-1 start predicts the largest BIC drop (if beyond the margin)."""
    good = [s for s in scores if s.start_dbic is not None and s.start_dbic < -EFFECT_BIC_MARGIN]
    return min(good, key=lambda s: s.start_dbic) if good else None


def _start_picks(scores: list[EffectScore], rms: float) -> list[EffectScore]:
    """The stage-1 starts worth a refit: :func:`_start_pick`'s, then the lowest start RMS
    within :data:`START_NEAR` of the current ``rms`` (an unconverged start of the right
    structure can begin above the current optimum: an offset's start at 1.26 times a
    distorted fit's RMS converged to the noise), :data:`SCREEN_REFITS` at most."""
    # a structural effect's starts were screened in its diagnosis, and its evidence
    # already decided whether it is refitted (:func:`_refit_queue`)
    scores = [s for s in scores if s.starts is None]
    out = [s for s in [_start_pick(scores)] if s is not None]
    near = sorted(
        (s for s in scores if s.start_rms is not None and s.start_rms < START_NEAR * rms),
        key=lambda s: s.start_rms,
    )
    for s in near:
        if len(out) >= SCREEN_REFITS:
            break
        if s not in out:
            out.append(s)
    return out


def _backward(data, fit, out: LoopResult, max_nfev, heldout, say, fits: dict) -> OEFit:
    """Drop earlier effects that a later one made redundant (parameter not significant)."""
    while len(out.effects) > 1:
        weak = [
            (wald_chi2(fit, e), e)
            for e in out.effects[:-1]
            if wald_chi2(fit, e) <= np.log(fit.n_obs)
        ]
        if not weak:
            break
        _, name = min(weak)
        keep = [e for e in out.effects if e != name]
        say(f"closing the loop: {name} became redundant, refit without it")
        par0 = fit.par
        start = {k: v for k, v in fit.params.items()}
        par = par0.like(start, tuple(keep))
        with np.errstate(all="ignore"):
            new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
        if not (fit_ok(new, fit) and new.bic < fit.bic):
            break
        out.effects.remove(name)
        fits[frozenset(out.effects)] = new
        for step in out.tried:
            if step["name"] == name and step["accepted"]:
                step["accepted"] = False
                step["removed"] = True
                step["note"] = (
                    f"{out.effects[-1]} made it redundant: its parameter was no longer significant"
                )
        fit = new
    return fit


class _Round:
    """The refits of one round of :func:`augment` (by effect: the best refit and its record)."""

    def __init__(
        self,
        data,
        current,
        round_no,
        max_nfev,
        heldout,
        noise_std,
        say,
        envelope,
        stage1=None,
        restart=None,
        failures: Failures | None = None,
    ):
        self.data = data
        #: where a refit that fails is recorded (``"effect <name>"``); None: it raises
        self.failures = failures
        #: the effects whose refit failed this round (not tried again)
        self.failed: set[str] = set()
        #: ``restart(effect, values, par)`` (:data:`Restart`), or None
        self.restart = restart
        #: effects already refitted from a restart this round (one restart each)
        self.restarted: set[str] = set()
        #: ``stage1(score)``: the stage-1 start of the current model plus the score's effect
        #: (made on first use), the fallback of a local refit; None without stage-1 data
        self.stage1 = stage1
        self.envelope = envelope
        self.noise_std = noise_std
        good_rms = NOISE_RATIO * noise_std
        self.current = current
        self.round_no = round_no
        self.max_nfev = max_nfev
        self.heldout = heldout
        self.good_rms = good_rms
        self.say = say
        self.results: dict[str, tuple[OEFit, dict]] = {}

    def attempt(self, s: EffectScore, start: dict | None = None, restarted: bool = False) -> None:
        """:meth:`refit` guarded: a refit that fails is recorded in :attr:`failures` (when
        given) as ``effect <name>``, the effect is not tried again, and the loop goes on."""
        if self.failures is None:
            self.refit(s, start, restarted)
            return
        before = len(self.failures)
        self.failures.guard(f"effect {s.name}", self.refit, s, start, restarted)
        if len(self.failures) > before:
            self.failed.add(s.name)
            self.say(f"closing the loop: the refit with {s.name} failed and is dropped")

    def refit(self, s: EffectScore, start: dict | None = None, restarted: bool = False) -> None:
        """Refit the current model plus ``s``'s effect and record the outcome.

        A refit that passes every test but the held-out one may sit in a basin that fits
        the data it saw only (an offset refit at 1.01 times the noise predicted the
        held-out runs at 3 times): it is refitted once more from :attr:`restart`'s start
        (once per effect and round) and the refit with the lower BIC is kept.
        ``restarted`` marks ``start`` as such a start already (see :meth:`screen`).
        """
        cur = self.current
        self.say(f"closing the loop: refit with {s.name} (evidence {s.evidence:.3g})")
        # the held-out error is computed below, only for a refit that passes every other
        # test: a rejected refit's folds (a Spencer refit's: 100 s on the MR damper set)
        # would not change its verdict
        structural = None
        with np.errstate(all="ignore"):
            if s.starts is not None:  # a structural effect, from its own starts
                structural = refit_structural(
                    self.data, cur, s.name, s.starts, self.max_nfev, False
                )
                new = structural.fit
            else:
                more = None if start is not None or self.stage1 is None else self.stage1
                new = refit_with(
                    self.data, cur, s.name, s.estimate, self.max_nfev, False, start,
                    self.good_rms, fallback=None if more is None else (lambda: more(s)),
                )  # fmt: skip
        new, step = self._judge(s, new, structural)
        if restarted:
            step["restarted"] = True
        fits_only = step["_improves"] and step["_significant"] and step["admissible"]
        if fits_only and not step["_predicts"]:
            again = self._restart_start(s.name, dict(new.params), cur.par)
            if again is not None:
                self.say(f"closing the loop: refit with {s.name} from the restarted family")
                par = cur.par.like(again, (*cur.par.effects, s.name))
                with np.errstate(all="ignore"):  # the local starts ran above: this one alone
                    new2 = OutputErrorFitter(self.data, par, max_nfev=self.max_nfev).fit(
                        heldout=False
                    )
                new2, step2 = self._judge(s, new2)
                if step2["_ok"] and new2.bic < new.bic:
                    new, step = new2, step2
                    step["restarted"] = True
        old = self.results.get(s.name)
        if old is None or (step["_ok"] and (old[1]["bic_after"] is None or new.bic < old[0].bic)):
            self.results[s.name] = (new, step)

    def _judge(
        self, s: EffectScore, new: OEFit, structural: StructuralRefit | None = None
    ) -> tuple[OEFit, dict]:
        """The record of the refit ``new`` of the current model plus ``s``'s effect (and
        ``new`` with its held-out error when every other test passes)."""
        cur = self.current
        ok = fit_ok(new, cur)
        wald = wald_chi2(new, s.name) if ok else 0.0
        step = {
            "name": s.name,
            "round": self.round_no,
            "evidence": s.evidence,
            "evidence_eq": s.evidence_eq,
            "start_rms": s.start_rms,
            "rms_before": cur.rms,
            "rms_after": new.rms if ok else None,
            "bic_before": cur.bic,
            "bic_after": new.bic if ok else None,
            "wald_chi2": wald if np.isfinite(wald) else None,
            "heldout_rms_before": cur.heldout_rms,
            "heldout_rms_after": new.heldout_rms if ok else None,
            "converged": bool(new.success),
            "accepted": False,
            "_ok": ok,
            "_improves": ok and new.bic < cur.bic - EFFECT_BIC_MARGIN,
            "_significant": wald > np.log(new.n_obs),
        }
        adm = (
            check_admissible(new.model if new.is_system else new.term_part, self.envelope)
            if ok
            else None
        )
        step["admissible"] = bool(adm is None or adm.ok)
        step["_violation"] = adm.violations[0] if adm is not None and not adm.ok else None
        # the one-step estimate at the current optimum says which sign the data want; the
        # bounded refit only explores the admissible one
        bad = EFFECTS[s.name].inadmissible(s.estimate)
        step["_wants"] = ", ".join(f"{k} = {s.estimate[k]:.3g}" for k in bad) or None
        # share of the excess over the noise that the effect removes
        excess = cur.rss - cur.n_obs * self.noise_std**2
        gain = cur.rss - new.rss if ok else 0.0
        share = gain / excess if excess > 0 else 1.0
        step["excess_share"] = float(share)
        if structural is not None:  # a multi-start refit: how the starts ended
            step["starts"] = [
                {f"{o.parameter}_start": o.start, o.parameter: o.value, "rms": o.rms, "bic": o.bic}
                for o in structural.starts
            ]
            step["starts_spread"] = structural.spread
        step["_improves"] = step["_improves"] and share >= MIN_EXCESS_SHARE
        # acceptance by prediction: the held-out error (pooled over folds) must fall too
        step["_heldout_skipped"] = False
        if self.heldout and ok and new.heldout_rms is None:
            if step["_improves"] and step["_significant"] and step["admissible"]:
                with np.errstate(all="ignore"):
                    fitter = OutputErrorFitter(self.data, new.par, max_nfev=self.max_nfev)
                    new = fitter.heldout_at(new)
                step["heldout_rms_after"] = new.heldout_rms
            else:
                step["_heldout_skipped"] = True
        hb, ha = cur.heldout_rms, step["heldout_rms_after"]
        step["_predicts"] = hb is None or (ha is not None and ha < hb)
        return new, step

    def _restart_start(self, name: str, values: dict, par) -> dict | None:
        """:attr:`restart`'s start for ``name`` from ``values`` of a model ``par``, once
        per effect and round (None when there is no restart, it was used, or it has none)."""
        if self.restart is None or name in self.restarted:
            return None
        again = self.restart(name, values, par)
        if again is not None:
            self.restarted.add(name)
        return again

    def best(self) -> tuple[OEFit, dict] | None:
        """The acceptable refit with the lowest BIC (better in BIC, significant, better on
        held-out data, physically admissible)."""
        ok = [(f, st) for f, st in self.results.values() if _acceptable(st)]
        return min(ok, key=lambda t: t[0].bic) if ok else None

    def done(self) -> bool:
        """An acceptable refit is down to the noise."""
        w = self.best()
        return w is not None and w[0].rms <= self.good_rms

    def screen(self, eq, scores: list[EffectScore], diag: dict, s0) -> None:
        """Stage-1 starts of every augmented structure, then a refit from the best one.

        The local views can be trapped by the current optimum; this global one is not.
        """
        self.say("closing the loop: stage-1 starts of the augmented structures")
        screen_starts(eq, self.data, self.current, scores, s0=s0)
        diag["candidates"] = [s.to_dict() for s in scores]
        for pick in _start_picks(scores, self.current.rms):
            self.attempt(pick, start=pick.start)
            if self.done():
                return
        # an effect the restart knows (the offset: a shift of the angle, which stage 1
        # estimates linearly) is refitted from the family fitted again with its stage-1
        # value, wherever its stage-1 start ranks: a base fit that absorbed it leaves
        # the offset's own start far (8 times the noise at a 3-level set whose stage 1
        # gives theta_off = 0.0300 against the true 0.03)
        for s in scores:
            again = (
                None if s.start is None else self._restart_start(s.name, s.start, self.current.par)
            )
            if again is None:
                continue
            self.attempt(s, start=again, restarted=True)
            if self.done():
                return


def _acceptable(step: dict) -> bool:
    return bool(
        step["_improves"] and step["_significant"] and step["_predicts"] and step["admissible"]
    )


def _rejection(
    step: dict,
    improves: bool,
    step_ok: bool,
    significant: bool,
    violation: str | None,
    heldout_skipped: bool = False,
) -> str:
    """Why a refitted effect was not accepted: every test it failed, in the order applied
    (the held-out error is not computed for a refit that failed another test)."""
    if not step_ok:
        return "its refit did not converge to finite values"
    failed = []
    lowered = step["bic_after"] < step["bic_before"] - EFFECT_BIC_MARGIN
    if not lowered:
        failed.append("did not lower BIC")
    elif not improves:
        failed.append(
            f"removes only {100 * step['excess_share']:.0f} % of the residual's excess over "
            "the noise"
        )
    if not significant:
        wz = np.sqrt(step["wald_chi2"] or 0.0)
        failed.append(f"its parameter is not significant (z = {wz:.2g})")
    hb, ha = step["heldout_rms_before"], step["heldout_rms_after"]
    if heldout_skipped:
        pass  # not predicted: the other tests already rejected it
    elif hb is not None and not (ha is not None and ha < hb):
        after = "diverged" if ha is None else f"{ha:.4g}"
        why = ": it improves the fit only on the data it was fitted to" if lowered else ""
        failed.append(f"does not lower the held-out error ({hb:.4g} -> {after}){why}")
    if not step["admissible"]:
        failed.append(f"not physical: {violation}")
    return "; ".join(failed)


def augment(
    data: FitData,
    fit: OEFit,
    noise_std: float,
    max_nfev: int = 60,
    heldout: bool = True,
    eq=None,
    progress: Callable[[str], None] | None = None,
    s0: np.ndarray | None = None,
    envelope: Envelope | None = None,
    decided: dict[str, str] | None = None,
    noise_samples: list[np.ndarray] | None = None,
    restart: Restart | None = None,
    failures: Failures | None = None,
) -> LoopResult:
    """Diagnose, add the effects that improve BIC, and test the final residual.

    An effect is accepted when its refit converges to finite values, lowers BIC by more
    than :data:`EFFECT_BIC_MARGIN`, its parameter is significant on its own (squared
    z-score above ``log N``), it removes at least :data:`MIN_EXCESS_SHARE` of the
    residual's excess over the noise, it **lowers the held-out error** (leave one test
    condition out, pooled over the folds; leave one run out when the runs share one
    condition), and the model with it is **physically admissible** (it dissipates energy
    and its spring stiffens over twice the training envelope:
    :func:`~hystdisc.simulation.admissibility.check_admissible`). An effect the data want
    with a sign outside its admissible bounds (a negative quadratic damping) is not
    refitted but reported with what it points at (its :attr:`~hystdisc.models.Effect.hint`). A refit that lowers BIC while the effect's parameter is not
    significant has found a better optimum of the model itself: the model is refitted
    without the effect from there and kept, and the effect is rejected.

    Parameters
    ----------
    data : FitData
        The data the fit was made on.
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.FamilyParametrization` (the selected or
        declared family).
    noise_std : float
        Estimated measurement noise (data units); raised to :func:`accuracy_floor` when
        smaller (noise-free data), where the loop does not run.
    max_nfev : int
        Simulation budget of each refit.
    heldout : bool
        Judge every refit on held-out data too (leave one test condition out).
    eq : EqData, optional
        Equation-error data, for the supplementary ``evidence_eq``.
    progress : callable, optional
        Called with short progress messages.
    s0 : ndarray, optional
        The family's stage-1 shape constants (start of the stage-1 screening's search).
    envelope : Envelope, optional
        The training envelope (default: measured on ``data``).
    decided : dict of str to str, optional
        Effects an earlier step decided (name -> why): not candidates.
    noise_samples : list of ndarray, optional
        A sample of the measurement noise (period-to-period differences): the final
        residual's whiteness is judged against its spectrum
        (:func:`~hystdisc.closing.residual.assess_residual`).
    restart : callable, optional
        ``restart(effect, refit)``: a full start of the model plus ``effect`` made
        without the current optimum (see :data:`Restart`), for a refit that fits better
        but does not predict the held-out data; None when there is none.
    failures : Failures, optional
        Where an effect whose refit fails is recorded (``effect <name>``): the effect is
        dropped and the loop goes on (without it, such a failure raises).

    Returns
    -------
    LoopResult
        The final fit, the tried/accepted effects, the diagnosis and the residual verdict.
    """
    say = progress or (lambda msg: None)
    if envelope is None:
        envelope = Envelope.from_runs(data.names, data.t, data.theta, data.theta_dot, data.currents)
    heldout = heldout and data.n_runs >= 2
    if heldout:
        fit = OutputErrorFitter(data, fit.par, max_nfev=max_nfev).heldout_at(fit)
    floor = accuracy_floor(data)
    noise_std = max(float(noise_std), floor)
    good_rms = NOISE_RATIO * noise_std
    out = LoopResult(base=fit, fit=fit)
    current = fit
    candidates, skipped = candidate_effects(fit, data)
    # effects an earlier step already decided (e.g. the staged fit chose the current laws)
    decided = dict(decided or {})
    skipped += [{"name": c, "reason": decided[c]} for c in candidates if c in decided]
    candidates = [c for c in candidates if c not in decided]
    out.skipped = skipped
    rejected: set[str] = set()
    steps: dict[str, dict] = {}
    fits: dict[frozenset, OEFit] = {frozenset(): fit}  # best fit of each effect set
    cells: dict[str, list[dict] | None] = {}  # a structural effect's best screened cells
    for round_no in range(1, 2 * len(EFFECTS) + 1):
        if current.rms <= good_rms and noise_std == floor:
            break  # within the simulator's own accuracy (noise-free data): nothing to explain
        pool = [c for c in candidates if c not in out.effects and c not in rejected]
        if not pool:
            break
        structural = [c for c in pool if EFFECTS[c].structural]
        scores = score_effects(data, current, [c for c in pool if c not in structural], eq=eq)
        if current.rms > good_rms:  # a structure can only explain a misfit
            scores += _structural_scores(data, current, structural, cells, say)
            scores.sort(key=lambda s: -s.evidence)
        diag = {"round": round_no, "candidates": [s.to_dict() for s in scores]}
        out.diagnosis.append(diag)
        stage1 = None
        if eq is not None and not current.is_system:

            def stage1(s: EffectScore, cur: OEFit = current) -> dict | None:
                if s.start is None:
                    say(f"closing the loop: stage-1 start with {s.name}")
                    effects = (*cur.par.effects, s.name)
                    s.start = stage1_start(eq, cur, effects, data, s0=s0)
                return s.start

        rnd = _Round(
            data, current, round_no, max_nfev, heldout, noise_std, say, envelope, stage1, restart,
            failures,
        )  # fmt: skip
        screened = False
        if eq is not None and current.rms > FAR_RATIO * noise_std:
            rnd.screen(eq, scores, diag, s0)  # far from the noise: the global view first
            screened = True
        if not (screened and rnd.done()):
            for s in _refit_queue(scores):
                if s.name not in rnd.results:
                    rnd.attempt(s)
        if not rnd.done() and not screened and eq is not None and current.rms > good_rms:
            rnd.screen(eq, scores, diag, s0)
        results = rnd.results
        rejected |= rnd.failed - set(results)
        w = rnd.best()
        for _, step in results.values():
            acceptable = _acceptable(step)
            step_ok, improves = step.pop("_ok"), step.pop("_improves")
            significant = step.pop("_significant")
            step.pop("_predicts")
            violation, wants = step.pop("_violation"), step.pop("_wants")
            skipped = step.pop("_heldout_skipped")
            out.tried.append(step)
            if w is not None and step is w[1]:
                continue
            if w is not None and acceptable:
                step["note"] = f"{w[1]['name']} lowered BIC more"
                continue
            rejected.add(step["name"])
            step["note"] = _rejection(step, improves, step_ok, significant, violation, skipped)
            if wants:
                hint = EFFECTS[step["name"]].hint or "physics the catalogue lacks"
                step["points_at"] = hint
                step["note"] = (
                    f"the data want {wants}, which is not physical: this points at {hint}; "
                    f"with the admissible sign it {step['note']}"
                )
        if w is not None:
            new, step = w
            step["accepted"] = True
            steps[step["name"]] = step
            out.effects.append(step["name"])
            fits[frozenset(out.effects)] = new
            current = _backward(data, new, out, max_nfev, heldout, say, fits)
            continue
        hops = [
            (f, st)
            for f, st in results.values()
            if st["bic_after"] is not None
            and f.bic < current.bic - EFFECT_BIC_MARGIN
            and (st["wald_chi2"] or 0.0) <= np.log(f.n_obs)
        ]
        if hops:
            # no effect was needed, but a refit left the model's own local optimum
            hop, st = min(hops, key=lambda t: t[0].bic)
            with np.errstate(all="ignore"):
                base = refit_without(data, hop, current, max_nfev, heldout)
            if fit_ok(base, current) and base.bic < current.bic - EFFECT_BIC_MARGIN:
                st["note"] += (
                    f"; its refit found a better optimum of the model without it (RMS "
                    f"{current.rms:.4g} -> {base.rms:.4g}), which is kept"
                )
                current = base
                fits[frozenset(out.effects)] = base
                continue
        break
    out.fit = current
    out.accepted = [
        _effect_entry(
            n,
            current,
            steps[n],
            fits.get(frozenset(out.effects[:j])),
            fits.get(frozenset(out.effects[: j + 1])),
        )
        for j, n in enumerate(out.effects)
    ]
    fs = sampling_rate(data.t)
    out.residual, out.unexplained, out.unexplained_text = assess_residual(
        masked(current.residuals, data.mask),
        fs,
        noise_std,
        natural_frequency(current, data.experiment),
        noise_samples,
    )
    out.residual["noise_used"] = noise_std
    return out


def close_loop(
    fit: OEFit,
    data: FitData,
    noise_std: float,
    eq=None,
    s0: np.ndarray | None = None,
    *,
    max_nfev: int = 60,
    heldout: bool = True,
    progress: Callable[[str], None] | None = None,
    envelope: Envelope | None = None,
    decided: dict[str, str] | None = None,
    noise_samples: list[np.ndarray] | None = None,
    restart: Restart | None = None,
    failures: Failures | None = None,
) -> LoopResult:
    """Close the loop on the fit of the selected (or declared) family.

    Runs :func:`augment`; when it fails (a singular Jacobian, a refit that cannot start),
    warns (or, given ``failures``, records it there as ``closing loop``) and returns the
    fit as it is with the verdict on its residual. An effect whose refit fails is dropped
    alone when ``failures`` is given (see :func:`augment`).

    Parameters
    ----------
    fit : OEFit
        Fit of a :class:`~hystdisc.fitting.FamilyParametrization`.
    data : FitData
        The data it was fitted to.
    noise_std : float
        Estimated measurement noise (data units).
    eq : EqData, optional
        Equation-error data of the discovery (supplementary evidence and the stage-1
        starts of the augmented structures).
    s0 : ndarray, optional
        The family's stage-1 shape constants (start of the stage-1 screening's search).
    max_nfev : int
        Simulation budget of each refit.
    heldout : bool
        Judge every refit on held-out data too (leave one test condition out; the default).
    progress : callable, optional
        Called with short progress messages.
    envelope : Envelope, optional
        The training envelope, for the admissibility of the refits.
    decided : dict of str to str, optional
        Effects an earlier step decided (name -> why): not candidates (e.g. the current
        laws the staged fit chose decide ``current_saturation``).
    noise_samples : list of ndarray, optional
        A sample of the measurement noise (:attr:`hystdisc.data.NoiseEstimate.samples`):
        the final residual is judged against its spectrum, not against white noise.
    restart : callable, optional
        ``restart(effect, refit)``: a full start of the model plus ``effect`` made without
        the current optimum (:data:`Restart`; :class:`~hystdisc.estimator.Discovery` gives
        one for the offset: the family fitted again, with all its starts, on the data
        shifted by the refit's neutral angle).

    Returns
    -------
    LoopResult
        ``fit`` is the final fit with every accepted effect, ``effects`` their names.
    """
    try:
        if not isinstance(fit.par, (FamilyParametrization, FamilySystemParametrization)):
            raise HystdiscError("the fit is not a family's own parametrization")
        return augment(
            data,
            fit,
            noise_std,
            max_nfev=max_nfev,
            heldout=heldout,
            eq=eq,
            progress=progress,
            s0=s0,
            envelope=envelope,
            decided=decided,
            noise_samples=noise_samples,
            restart=restart,
            failures=failures,
        )
    except Exception as exc:  # noqa: BLE001 - with failures given, every failure is isolated
        expected = (HystdiscError, np.linalg.LinAlgError, ValueError, FloatingPointError)
        if failures is None and not isinstance(exc, expected):
            raise
        name = getattr(getattr(fit.par, "family", None), "name", "the fit")
        if failures is not None:
            failures.record("closing loop", f"{reason_of(exc)}; the residual of {name} is "
                            "reported without effects")  # fmt: skip
        else:
            warnings.warn(
                f"closing the loop failed ({exc}); the residual of {name} is reported "
                "without effects",
                HystdiscWarning,
                stacklevel=2,
            )
    loop = LoopResult(base=fit, fit=fit)
    noise = max(float(noise_std), accuracy_floor(data))
    loop.residual, loop.unexplained, loop.unexplained_text = assess_residual(
        masked(fit.residuals, data.mask),
        sampling_rate(data.t),
        noise,
        natural_frequency(fit, data.experiment),
        noise_samples,
    )
    return loop
