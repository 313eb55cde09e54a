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
   :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN` are refitted by output error (from the current optimum with
   the Gauss-Newton estimate of the effect); when that does not reach the noise, the
   candidate with the best stage-1 start is refitted from it (first, when the residual is
   far above the noise). A refit is accepted when it lowers BIC by more than the margin,
   its effect parameter is significant on its own (squared z-score above ``log N``) and it
   removes at least :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the residual's excess over the noise; the
   best accepted refit of the round wins, earlier effects that it makes redundant are
   dropped again, the residual is re-diagnosed, and the loop repeats until nothing is
   accepted. Only candidates with evidence are refitted: on data the model explains, the
   loop costs one Jacobian.
4. **Whiteness** (:func:`~hystdisc.closing.residual.assess_residual`): the final residual is tested by a Ljung-Box
   test pooled over runs and its spectrum is averaged over runs; with a sample of the
   noise (a periodic excitation), against the noise's own spectrum instead. When it is not white and
   its RMS is clearly above the noise (:data:`~hystdisc.closing.residual.NOISE_RATIO`), ``unexplained`` is set with
   the dominant frequency and a sentence such as "a resonance near 6.0 Hz that no
   catalogued effect explains".

:func:`close_loop` runs all of it on the selected family's fit and returns the
:class:`~hystdisc.closing.records.LoopResult`; :class:`~hystdisc.estimator.Discovery`
stores it (``loop_``, ``final_fit_``, ``effects_``) and the pipeline's results builder
writes it into ``results.json``. The parts live in :mod:`~hystdisc.closing.scores`
(diagnosis), :mod:`~hystdisc.closing.refit` (candidates, starts, refits),
:mod:`~hystdisc.closing.rounds` (a round's refits and their verdicts),
:mod:`~hystdisc.closing.records` (what the loop records) and
:mod:`~hystdisc.closing.residual` (whiteness).
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping

import numpy as np

from hystdisc.closing.records import (
    AcceptedEffect,
    Diagnosis,
    EffectVerdict,
    LoopResult,
    effect_parameters,
)
from hystdisc.closing.refit import (
    EFFECT_BIC_MARGIN,
    EffectSkipped,
    candidate_effects,
    fit_ok,
    refit_without,
    stage1_start,
)
from hystdisc.closing.residual import (
    NOISE_RATIO,
    accuracy_floor,
    assess_residual,
    natural_frequency,
)
from hystdisc.closing.rounds import (
    MIN_EXCESS_SHARE,
    Restart,
    Round,
    excess_over,
    refit_queue,
    snapshot,
)
from hystdisc.closing.scores import EffectScore, score_effects, wald_chi2, with_effects
from hystdisc.closing.structural import score_structural
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
from hystdisc.stats import masked, sampling_rate

#: ``library(fit)``: the catalogued effects an open regression of ``fit``'s residual points
#: at, each with start values of its parameters (:func:`augment`).
Library = Callable[[OEFit], Mapping[str, Mapping[str, float]]]

#: Above this many times the noise the current optimum may be a trap for the local views:
#: the stage-1 starts of the augmented structures are screened first.
FAR_RATIO = 5.0


def _accepted(
    name: str, final: OEFit, verdict: EffectVerdict, before: OEFit | None, after: OEFit | None
) -> AcceptedEffect:
    """The accepted effect ``name`` with its parameters from the ``final`` fit.

    ``before``/``after`` are the fits without and with the effect along the final chain of
    accepted effects (when an effect was removed again, the chain is recomputed from the
    fits at hand); without them the values at the time of acceptance (``verdict``) are used.
    """
    v = verdict
    if before is not None and after is not None:
        return AcceptedEffect.between(name, final, before, after, v.evidence, v.evidence_eq)
    return AcceptedEffect(
        name,
        tuple(EFFECTS[name].terms),
        effect_parameters(name, final),
        v.rms_before,
        v.rms_after,
        v.bic_before,
        v.bic_after,
        v.heldout_rms_before,
        v.heldout_rms_after,
        v.evidence,
        v.evidence_eq,
    )


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


def _backward(data, fit, out: LoopResult, max_nfev, heldout, say, fits: dict) -> OEFit:
    """Drop earlier effects that a later one made redundant (parameter not significant):
    the loop's own, and a measurement effect the model carried into the loop (a channel
    delay stage 1 saw in a misfit the loop's effect explains: ``out.dropped``)."""
    while out.effects:
        carried = [
            e
            for e in fit.par.effects
            if e not in out.effects and EFFECTS[e].has_role("measurement")
        ]
        weak = [
            (wald_chi2(fit, e), e)
            for e in [*carried, *out.effects[:-1]]
            if wald_chi2(fit, e) <= np.log(fit.n_obs)
        ]
        if not weak:
            break
        _, name = min(weak)
        say(f"closing the loop: {name} became redundant, refit without it")
        par0 = fit.par
        start = {k: v for k, v in fit.params.items()}
        par = par0.like(start, tuple(e for e in par0.effects if e != name))
        with np.errstate(all="ignore"):
            new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=heldout)
        if not (fit_ok(new, fit) and new.bic < fit.bic):
            break
        why = f"{out.effects[-1]} made it redundant: its parameter was no longer significant"
        if name in carried:
            out.dropped[name] = why
        else:
            out.effects.remove(name)
        fits[frozenset(out.effects)] = new
        for verdict in out.tried:
            if verdict.name == name and verdict.accepted:
                verdict.accepted = False
                verdict.removed = True
                verdict.note = why
        fit = new
    return fit


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
    first: tuple[str, ...] = (),
    library: Library | None = None,
) -> LoopResult:
    """Diagnose, add the effects that improve BIC, and test the final residual.

    An effect is accepted when its refit converges to finite values, lowers BIC by more
    than :data:`~hystdisc.closing.refit.EFFECT_BIC_MARGIN`, its parameter is significant on
    its own (squared z-score above ``log N``), it removes at least
    :data:`~hystdisc.closing.rounds.MIN_EXCESS_SHARE` of the residual's excess over the
    noise, it **lowers the held-out error** (leave one test condition out, pooled over the
    folds; leave one run out when the runs share one condition), and the model with it is
    **physically admissible** (it dissipates energy and its spring stiffens over twice the
    training envelope: :func:`~hystdisc.simulation.admissibility.check_admissible`). An
    effect the data want with a sign outside its admissible bounds (a negative quadratic
    damping, by the one-step estimate) is refitted within its bounds, and when rejected
    is reported with what that sign points at (its :attr:`~hystdisc.models.Effect.hint`). A refit that lowers BIC while the effect's
    parameter is not significant has found a better optimum of the model itself: the model
    is refitted without the effect from there and kept, and the effect is rejected.

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
    first : tuple of str
        Effects an earlier step saw signs of: refitted in the first round whatever their
        rank (a channel delay the stage-1 scan saw but could not tell from the structure's
        misfit).
    library : callable, optional
        ``library(fit)``: the catalogued effects an open regression of ``fit``'s residual
        points at, each with start values (:data:`Library`). Called once, when a round
        accepts nothing while the residual is above the noise; the effects it names that
        no round refitted, or that it gives values for (a play's width), are refitted in
        one more round, first and from those values (``LoopResult.pointed``).
    noise_samples : list of ndarray, optional
        A sample of the measurement noise (period-to-period differences): the final
        residual's whiteness is judged against its spectrum
        (:func:`~hystdisc.closing.residual.assess_residual`).
    restart : callable, optional
        ``restart(effect, refit)``: a full start of the model plus ``effect`` made
        without the current optimum (see :data:`~hystdisc.closing.rounds.Restart`), for a refit that fits better
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
    skipped += [EffectSkipped(c, decided[c]) for c in candidates if c in decided]
    candidates = [c for c in candidates if c not in decided]
    out.skipped = skipped
    rejected: set[str] = set()
    # effects rejected for their share of the excess alone: the RSS each removed
    share_gain: dict[str, float] = {}
    steps: dict[str, EffectVerdict] = {}  # each accepted effect's verdict
    fits: dict[frozenset, OEFit] = {frozenset(): fit}  # best fit of each effect set
    cells: dict[str, list[dict] | None] = {}  # a structural effect's best screened cells
    forced, forced_values = tuple(first), {}  # refitted first this round
    asked = library is None
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
        diag = Diagnosis(round_no, snapshot(scores))
        out.diagnosis.append(diag)
        stage1 = None
        if eq is not None and not current.is_system:

            def stage1(s: EffectScore, cur: OEFit = current) -> dict | None:
                if s.start is None:
                    say(f"closing the loop: stage-1 start with {s.name}")
                    effects = (*cur.par.effects, s.name)
                    s.start = stage1_start(eq, cur, effects, data, s0=s0)
                return s.start

        rnd = Round(
            data, current, round_no, max_nfev, heldout, noise_std, say, envelope, stage1, restart,
            failures,
        )  # fmt: skip
        # the library's round refits what the library named, nothing the rounds before
        # already weighed (on the UTFSM CSV the usual queue refitted coulomb and bias again)
        screened = bool(forced_values)
        if not screened and eq is not None and current.rms > FAR_RATIO * noise_std:
            rnd.screen(eq, scores, diag, s0)  # far from the noise: the global view first
            screened = True
        if not (screened and rnd.done()):
            queue = refit_queue(scores, forced)
            for s in [q for q in queue if q.name in forced_values] if forced_values else queue:
                if s.name in rnd.results:
                    continue
                if s.name in forced_values and s.starts is None:
                    rnd.attempt(s, start=_start_at(current, s.name, forced_values[s.name]))
                    if forced_values[s.name]:  # a value the library read off the residual
                        rnd.restart_from(s, forced_values[s.name])
                    continue
                done = rnd.best() if rnd.done() else None
                if (
                    s.starts is not None
                    and done is not None
                    and not s.signature
                    and s.start_rms >= done[0].rms
                ):
                    # a structural refit is the loop's dearest (several full fits); once a
                    # refit of the round is down to the noise, a structure whose signature
                    # the residual does not show and none of whose screened starts fits
                    # better is skipped (a mild wheel's best start does fit better than the
                    # cubic stiffness that also reaches the noise; a driven mount, whose
                    # screen says nothing, is judged by its refit: channel_delay reaches
                    # 1.07x the noise behind a mount, the mount the noise)
                    why = (
                        f"{done[1].name} reached the noise; no signature of it, and its best "
                        "start did not fit better"
                    )
                    _not_refitted(diag, s.name, why)
                    continue
                rnd.attempt(s)
        if not rnd.done() and not screened and eq is not None and current.rms > good_rms:
            rnd.screen(eq, scores, diag, s0)
        results = rnd.results
        forced, forced_values = (), {}
        rejected |= rnd.failed - set(results)
        w = rnd.best()
        for _, verdict in results.values():
            out.tried.append(verdict)
            if w is not None and verdict is w[1]:
                continue
            if w is not None and verdict.acceptable:
                verdict.note = f"{w[1].name} lowered BIC more"
                continue
            rejected.add(verdict.name)
            verdict.reject()
            if verdict.share_only:
                excess = excess_over(current, noise_std)
                share_gain[verdict.name] = verdict.excess_share * max(excess, 0.0)
        if w is not None:
            new, verdict = w
            verdict.accepted = True
            steps[verdict.name] = verdict
            out.effects.append(verdict.name)
            fits[frozenset(out.effects)] = new
            current = _backward(data, new, out, max_nfev, heldout, say, fits)
            # the excess shrank: a gain too small a share of the old one may count now
            excess = excess_over(current, noise_std)
            again = [n for n, g in share_gain.items() if g >= MIN_EXCESS_SHARE * excess > 0]
            if again:
                say(f"closing the loop: {', '.join(again)} tried again (the excess shrank)")
                rejected -= set(again)
                for n in again:
                    del share_gain[n]
            continue
        hops = [
            (f, v)
            for f, v in results.values()
            if v.bic_after is not None
            and f.bic < current.bic - EFFECT_BIC_MARGIN
            and (v.wald_chi2 or 0.0) <= np.log(f.n_obs)
        ]
        if hops:
            # no effect was needed, but a refit left the model's own local optimum
            hop, v = min(hops, key=lambda t: t[0].bic)
            with np.errstate(all="ignore"):
                base = refit_without(data, hop, current, max_nfev, heldout)
            if fit_ok(base, current) and base.bic < current.bic - EFFECT_BIC_MARGIN:
                v.note = (
                    f"{v.note}; its refit found a better optimum of the model without it (RMS "
                    f"{current.rms:.4g} -> {base.rms:.4g}), which is kept"
                )
                current = base
                fits[frozenset(out.effects)] = base
                continue
        if not asked and current.rms > good_rms:
            asked = True
            tried = {v.name for v in out.tried}
            # an effect a round refitted is refitted again only from the values the library
            # read off the residual (a play's width): its catalogued start may be out of
            # reach (the other-lab stand-in's 0.5 mm play collapsed to none from it)
            extra = {
                n: dict(v)
                for n, v in library(current).items()
                if n in candidates and n not in out.effects and (n not in tried or v)
            }
            if extra:
                say(f"closing the loop: the open library points at {', '.join(extra)}")
                forced, forced_values = tuple(extra), extra
                rejected -= set(extra)
                out.pointed = dict(extra)
                continue
        break
    out.fit = current
    out.accepted = [
        _accepted(
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
    out.residual.noise_used = noise_std
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
    first: tuple[str, ...] = (),
    library: Library | None = None,
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
        the current optimum (:data:`~hystdisc.closing.rounds.Restart`;
        :class:`~hystdisc.estimator.Discovery` gives one for the offset: the family fitted
        again, with all its starts, on the data shifted by the refit's neutral angle).
    first : tuple of str
        Effects refitted in the first round whatever their rank (see :func:`augment`).
    library : callable, optional
        The open library on a residual the rounds leave (see :func:`augment`).

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
            first=first,
            library=library,
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


def _not_refitted(diag: Diagnosis, name: str, why: str) -> None:
    """Record in the round's diagnosis why candidate ``name`` was not refitted."""
    for c in diag.candidates:
        if c.name == name:
            c.not_refitted = why


def _start_at(fit: OEFit, name: str, values: Mapping[str, float]) -> dict[str, float]:
    """A full start of ``fit`` plus effect ``name`` at ``values`` (the rest of its
    parameters where it is absent)."""
    par, x = with_effects(fit, [name], dict(values))
    return dict(zip(par.names, map(float, x), strict=True))
