"""One round of the closing loop: which candidates are refitted, the refits, their verdicts.

Each round of :func:`~hystdisc.closing.loop.augment` refits the candidates worth it
(:func:`refit_queue`: the two output-error leaders and the equation-error leader whose
predicted BIC drop beats the margin, and every structural effect whose starts predict a
drop or whose signature the residual shows) and, when the residual is far from the noise
or the local refits fall short, the candidates with the best stage-1 starts
(:func:`start_picks`). A :class:`Round` makes those refits and judges each
(:class:`~hystdisc.closing.records.EffectVerdict`): BIC, significance, the share of the
residual's excess it removes, held-out error, admissibility.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

import numpy as np

from hystdisc.closing.records import Diagnosis, EffectVerdict
from hystdisc.closing.refit import EFFECT_BIC_MARGIN, fit_ok, refit_with, screen_starts
from hystdisc.closing.residual import NOISE_RATIO
from hystdisc.closing.scores import EffectScore, wald_chi2
from hystdisc.closing.structural import StructuralRefit, refit_structural
from hystdisc.data.envelope import Envelope
from hystdisc.faults import Failures
from hystdisc.fitting import FamilyParametrization, OEFit, OutputErrorFitter
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS
from hystdisc.simulation.admissibility import check_admissible

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
#: ... unless it lowers the held-out error of every held-out fold (test condition), with
#: at least this many folds: far above its floor (a real damper whose structure the
#: catalogue lacks, 9x its repeatability) a real effect removes a small share of a large
#: excess and still predicts every condition it was not fitted on better, while one fitted
#: to the noise lowers each fold's error by chance (all of four: about 1 in 16) and must
#: also have passed BIC and significance.
MIN_FOLDS_ALL = 4
#: ``restart(effect, values, par) -> start or None``: a full start of the model ``par``
#: (the current one) plus ``effect`` that does not rely on the current optimum, given
#: ``values`` of a start or refit of that structure (the effect's own among them): the
#: offset's and the backlash's (:func:`~hystdisc.closing.motion_restart.motion_restart`)
#: fit the family again on the angle shifted by ``values["theta_off"]``, or on the motion
#: seen through the play ``values["r_b"]``; None for the other effects.
Restart = Callable[[str, dict, "FamilyParametrization"], "dict | None"]


def excess_over(fit: OEFit, floor: float) -> float:
    """The residual's excess over the measurement's ``floor`` (noise or repeatability):
    ``RSS - N floor^2``, what an effect's share (:data:`MIN_EXCESS_SHARE`) is a share of.

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> excess_over(SimpleNamespace(rss=5.0, n_obs=100), 0.2)
    1.0
    """
    return float(fit.rss - fit.n_obs * floor**2)


def fold_rms(data: FitData, fit: OEFit) -> list[float] | None:
    """The held-out RMS of each fold of ``data`` (:meth:`FitData.folds`) from ``fit``'s
    held-out predictions (None without them)."""
    preds = fit.heldout_predictions
    if preds is None:
        return None
    out = []
    for fold in data.folds():
        if any(preds[r] is None for r in fold):
            return None
        e = np.concatenate([(preds[r] - data.y[r])[data.mask[r]] for r in fold])
        out.append(float(np.sqrt(np.mean(e**2))) if e.size else 0.0)
    return out


def snapshot(scores: list[EffectScore]) -> list[EffectScore]:
    """Copies of ``scores`` as they are now (what a round's diagnosis records)."""
    return [dataclasses.replace(s) for s in scores]


def refit_queue(scores: list[EffectScore], first: tuple[str, ...] = ()) -> list[EffectScore]:
    """Candidates worth a local output-error refit this round (at most three, after the
    ones an earlier step saw), then the structural effects worth a refit from their starts.

    The top two candidates by output-error evidence and the top by equation-error
    evidence (a second view that catches an effect the model's own terms mimic locally),
    each only when its predicted BIC drop beats the margin. Both output-error leaders are
    refitted because a hysteretic state mimics several effects to first order (a fast
    ``z`` looks like Coulomb friction), so the local ranking of close candidates is not
    trusted; the refits decide.

    Parameters
    ----------
    scores : list of EffectScore
        The round's diagnosis, ranked by evidence.
    first : tuple of str
        Effects refitted first whatever their rank (an earlier step saw signs of them).

    Returns
    -------
    list of EffectScore
        The candidates to refit, in turn.
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
    forced = [s for s in scores if s.name in first and s.starts is None]
    queue = forced + [s for s in queue if s not in forced][:MAX_REFITS_PER_ROUND]
    return queue + [s for s in structural if s not in forced]


def start_pick(scores: list[EffectScore]) -> EffectScore | None:
    """The candidate whose stage-1 start predicts the largest BIC drop (if beyond the
    margin), or None."""
    good = [s for s in scores if s.start_dbic is not None and s.start_dbic < -EFFECT_BIC_MARGIN]
    return min(good, key=lambda s: s.start_dbic) if good else None


def start_picks(scores: list[EffectScore], rms: float) -> list[EffectScore]:
    """The stage-1 starts worth a refit: :func:`start_pick`'s, then the lowest start RMS
    within :data:`START_NEAR` of the current ``rms`` (an unconverged start of the right
    structure can begin above the current optimum: an offset's start at 1.26 times a
    distorted fit's RMS converged to the noise), :data:`SCREEN_REFITS` at most."""
    # a structural effect's starts were screened in its diagnosis, and its evidence
    # already decided whether it is refitted (:func:`refit_queue`)
    scores = [s for s in scores if s.starts is None]
    out = [s for s in [start_pick(scores)] if s is not None]
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


class Round:
    """The refits of one round of :func:`~hystdisc.closing.loop.augment`: by effect, the
    best refit and its verdict (:attr:`results`).

    Parameters
    ----------
    data : FitData
        The data of the fits.
    current : OEFit
        The model at the start of the round.
    round_no : int
        The round's number (1 first).
    max_nfev : int
        Simulation budget of each refit.
    heldout : bool
        Judge the refits on held-out data too.
    noise_std : float
        The noise level the refits are judged against.
    say : callable
        Called with short progress messages.
    envelope : Envelope
        The training envelope (admissibility of the refits).
    stage1 : callable, optional
        ``stage1(score)``: the stage-1 start of the current model plus the score's effect
        (made on first use), the fallback of a local refit; None without stage-1 data.
    restart : callable, optional
        A restart of the model with an effect (:data:`Restart`), or None.
    failures : Failures, optional
        Where a refit that fails is recorded (``"effect <name>"``); None: it raises.
    """

    def __init__(
        self,
        data: FitData,
        current: OEFit,
        round_no: int,
        max_nfev: int,
        heldout: bool,
        noise_std: float,
        say: Callable[[str], None],
        envelope: Envelope,
        stage1: Callable[[EffectScore], dict | None] | None = None,
        restart: Restart | None = None,
        failures: Failures | None = None,
    ) -> None:
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
        self.current = current
        self.round_no = round_no
        self.max_nfev = max_nfev
        self.heldout = heldout
        #: an RMS that needs no further start (a little above the noise)
        self.good_rms = NOISE_RATIO * noise_std
        self.say = say
        #: by effect: its best refit this round and the verdict on it
        self.results: dict[str, tuple[OEFit, EffectVerdict]] = {}

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
        held-out runs at 3 times), and one the data want (better in BIC, significant)
        that is not physical may sit in a basin the missing effect bent the model into (a
        Spencer damper fitted without its play, then refitted with it, diverges in a slow
        cycle): either is refitted once more from :attr:`restart`'s start (once per
        effect and round). The restarted refit is kept when its BIC is lower, or when it
        passes every test and the first was not physical.
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
        new, verdict = self.judge(s, new, structural)
        if restarted:
            verdict.restarted = True
        wanted = verdict.improves and verdict.significant
        # a share a state-space family's force carries (the family has no stage-1 start):
        # a refit rejected or left above the noise may sit where the missing share bent
        # the family (share_restart)
        share = cur.is_system and bool(EFFECTS[s.name].scaled)
        share = share and not restarted and (new.rms > self.good_rms or not verdict.acceptable)
        if share or (wanted and not (verdict.admissible and verdict.predicts)):
            again = self._restart_start(s.name, dict(new.params), cur.par)
            if again is not None:
                self.say(f"closing the loop: refit with {s.name} from the restarted family")
                par = cur.par.like(again, (*cur.par.effects, s.name))
                with np.errstate(all="ignore"):  # the local starts ran above: this one alone
                    new2 = OutputErrorFitter(self.data, par, max_nfev=self.max_nfev).fit(
                        heldout=False
                    )
                new2, verdict2 = self.judge(s, new2)
                physical = verdict2.acceptable and not verdict.admissible
                if verdict2.ok and (new2.bic < new.bic or physical):
                    new, verdict = new2, verdict2
                    verdict.restarted = True
        old = self.results.get(s.name)
        if old is None:
            self.results[s.name] = (new, verdict)
        elif verdict.ok:
            lower = old[1].bic_after is None or new.bic < old[0].bic
            if lower or (verdict.acceptable and not old[1].acceptable):
                self.results[s.name] = (new, verdict)

    def restart_from(self, s: EffectScore, values: dict) -> None:
        """Refit ``s``'s effect once more from :attr:`restart`'s start at ``values`` (the
        effect's own, read off the residual: the open library's play width), unless its
        refit this round is acceptable or was restarted already.

        A base fit bent by a missing play can leave the local refit from the library's
        width no way to it (a Spencer damper with a 0.4 mm play: the base fit ended at
        ``n = 10``, and the refit from there took the width to 0); the family fitted again
        on the motion seen through that width does not depend on that fit.
        """
        done = self.results.get(s.name)
        if done is not None and done[1].acceptable:
            return
        again = self._restart_start(s.name, {**dict(self.current.params), **values},
                                    self.current.par)  # fmt: skip
        if again is not None:
            self.say(f"closing the loop: refit with {s.name} from the restarted family")
            self.attempt(s, start=again, restarted=True)

    def judge(
        self, s: EffectScore, new: OEFit, structural: StructuralRefit | None = None
    ) -> tuple[OEFit, EffectVerdict]:
        """The verdict on the refit ``new`` of the current model plus ``s``'s effect.

        Parameters
        ----------
        s : EffectScore
            The effect's diagnosis.
        new : OEFit
            The refit.
        structural : StructuralRefit, optional
            The structural refit ``new`` is the best of (its starts are reported).

        Returns
        -------
        OEFit
            ``new``, with its held-out error when every other test passes.
        EffectVerdict
            The verdict.
        """
        cur = self.current
        ok = fit_ok(new, cur)
        wald = wald_chi2(new, s.name) if ok else 0.0
        verdict = EffectVerdict(
            name=s.name,
            round=self.round_no,
            evidence=s.evidence,
            evidence_eq=s.evidence_eq,
            start_rms=s.start_rms,
            rms_before=cur.rms,
            rms_after=new.rms if ok else None,
            bic_before=cur.bic,
            bic_after=new.bic if ok else None,
            wald_chi2=wald if np.isfinite(wald) else None,
            heldout_rms_before=cur.heldout_rms,
            heldout_rms_after=new.heldout_rms if ok else None,
            converged=bool(new.success),
            ok=ok,
            improves=ok and new.bic < cur.bic - EFFECT_BIC_MARGIN,
            significant=wald > np.log(new.n_obs),
        )
        adm = (
            check_admissible(new.model if new.is_system else new.term_part, self.envelope)
            if ok
            else None
        )
        verdict.admissible = bool(adm is None or adm.ok)
        verdict.violation = adm.violations[0] if adm is not None and not adm.ok else None
        # the one-step estimate at the current optimum says which sign the data want; the
        # bounded refit only explores the admissible one
        bad = EFFECTS[s.name].inadmissible(s.estimate)
        verdict.wants = ", ".join(f"{k} = {s.estimate[k]:.3g}" for k in bad) or None
        # share of the excess over the noise that the effect removes
        excess = excess_over(cur, self.noise_std)
        gain = cur.rss - new.rss if ok else 0.0
        share = gain / excess if excess > 0 else 1.0
        verdict.excess_share = float(share)
        if structural is not None:  # a multi-start refit: how the starts ended
            verdict.starts, verdict.starts_spread = structural.starts, structural.spread
        lowered = verdict.improves  # lower BIC by the margin
        verdict.improves = lowered and share >= MIN_EXCESS_SHARE
        # acceptance by prediction: the held-out error (pooled over folds) must fall too
        if self.heldout and ok and new.heldout_rms is None:
            if lowered and verdict.significant and verdict.admissible:
                with np.errstate(all="ignore"):
                    fitter = OutputErrorFitter(self.data, new.par, max_nfev=self.max_nfev)
                    new = fitter.heldout_at(new)
                verdict.heldout_rms_after = new.heldout_rms
            else:
                verdict.heldout_skipped = True
        hb, ha = cur.heldout_rms, verdict.heldout_rms_after
        if (
            self.heldout
            and hb is not None
            and (ha is None or ha >= hb)
            and verdict.improves
            and verdict.significant
            and verdict.admissible
        ):
            # everything but the held-out error says yes: before rejecting, the folds are
            # refitted completely (the quick estimate is a few steps from a linear one, and
            # one that leaves the basin judges the fitting, not the model)
            with np.errstate(all="ignore"):
                fitter = OutputErrorFitter(self.data, new.par, max_nfev=self.max_nfev)
                new = fitter.heldout_at(new, full=True)
            verdict.heldout_rms_after = ha = new.heldout_rms
            verdict.heldout_refit = True
        verdict.predicts = hb is None or (ha is not None and ha < hb)
        if lowered and not verdict.improves and verdict.significant and verdict.admissible:
            before, after = fold_rms(self.data, cur), fold_rms(self.data, new)
            if before is not None and after is not None:
                verdict.heldout_folds = len(before)
                verdict.heldout_folds_lower = sum(a < b for a, b in zip(after, before, strict=True))
                every = verdict.heldout_folds_lower == verdict.heldout_folds
                verdict.improves = every and verdict.heldout_folds >= MIN_FOLDS_ALL
        return new, verdict

    def _restart_start(self, name: str, values: dict, par) -> dict | None:
        """:attr:`restart`'s start for ``name`` from ``values`` of a model ``par``, once
        per effect and round (None when there is no restart, it was used, or it has none)."""
        if self.restart is None or name in self.restarted:
            return None
        again = self.restart(name, values, par)
        if again is not None:
            self.restarted.add(name)
        return again

    def best(self) -> tuple[OEFit, EffectVerdict] | None:
        """The acceptable refit with the lowest BIC (better in BIC, significant, better on
        held-out data, physically admissible), or None."""
        ok = [(f, v) for f, v in self.results.values() if v.acceptable]
        return min(ok, key=lambda t: t[0].bic) if ok else None

    def done(self) -> bool:
        """An acceptable refit is down to the noise."""
        w = self.best()
        return w is not None and w[0].rms <= self.good_rms

    def screen(self, eq, scores: list[EffectScore], diag: Diagnosis, s0) -> None:
        """Stage-1 starts of every augmented structure, then a refit from the best one.

        The local views can be trapped by the current optimum; this global one is not.
        ``diag`` (the round's diagnosis) records the scores with their starts.
        """
        self.say("closing the loop: stage-1 starts of the augmented structures")
        screen_starts(eq, self.data, self.current, scores, s0=s0)
        diag.candidates = snapshot(scores)
        for pick in start_picks(scores, self.current.rms):
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
