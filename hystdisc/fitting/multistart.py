"""Global output-error fits: several starts per family, the best kept, nesting kept consistent.

An output-error fit is a local search: from one start it can stop in a wrong basin (a
seed-form Bouc-Wen at 150 times the quantization floor, a Dahl whose LuGre fit is worse
than Dahl's own). Three tools make the fits global enough to trust:

1. :func:`best_of_starts` runs every start a few iterations (:data:`SCREEN_NFEV`), keeps
   the best and continues it to convergence (given the noise floor, the first start is
   fitted first, and the others only run when it ends above the floor); the fit's note says how many starts reached
   the optimum (RMS within :data:`REACHED_RTOL`) and the spread when they disagree, and
   ``fit.starts`` holds every start's RMS.
   The discovery adds, for a family above the floor, the optima of its related
   families (``Family.start_from``, read through :func:`mapped_starts`) to its starts:
   on a coarse encoder stage 1 can miss every basin (a LuGre set whose stage-1 start was
   679 times the floor reached it in 8 iterations from Dahl's optimum).
2. :func:`random_starts` perturbs a start inside the admissible box (log-uniform factors
   up to :data:`RANDOM_FACTOR` on every free parameter, the exponents additively).
3. :func:`nesting_pass`: the optimum of every other family, mapped through the term form
   (:func:`mapped_starts`, the family's ``term_starts``: Dahl into LuGre; Dahl and
   LuGre into Bouc-Wen, whose gamma term is theirs at n -> 0 (seed form) or n = 1
   (standard form); the two Bouc-Wen forms into each other, exponent shifted by one or
   kept), is simulated once in each family; when it fits better than the family's own
   optimum the family is refitted from it. The pass repeats while it changes a fit (at
   most :data:`NESTING_PASSES`). A family then never ends with a worse fit than a
   family it contains. Where the correspondence is approximate (the two Bouc-Wen forms,
   Dahl or LuGre into Bouc-Wen) a mapped optimum can start worse than the family's own
   and still lead to a better basin: a family left above the noise floor
   (``screen_above``) screens the mapped optima of the families at the floor that have no
   more parameters than it, :data:`SCREEN_NFEV` iterations each, and is refitted from the
   best when its screen fits better (a seed-form Bouc-Wen stuck at 1.4 times a 2048-count
   encoder's floor reached the floor and its truth from the standard form's optimum in 8
   iterations).

Examples
--------
>>> from hystdisc.models import Model
>>> p = random_starts("dahl", Model("dahl").params, 2, seed=0)
>>> [label for label, _ in p]
['random 1', 'random 2']
>>> all(0.2 < s["rho"] / 20.0 < 5 for _, s in p)
True
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping, Sequence

import numpy as np

from hystdisc.discovery import family_starts
from hystdisc.errors import HystdiscError
from hystdisc.faults import Failures
from hystdisc.fitting.output_error import OEFit, OutputErrorFitter
from hystdisc.fitting.parametrization import FamilySystemParametrization, Parametrization
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import EFFECTS, FAMILIES, RIG_PARAMS, get_family
from hystdisc.stats import sampling_rate

#: Levenberg-Marquardt iterations of each start before the best is continued.
SCREEN_NFEV = 8
#: A start "reached the optimum" when its RMS is within this relative distance of it.
REACHED_RTOL = 0.01
#: Random starts scale each free parameter by a log-uniform factor up to this.
RANDOM_FACTOR = 3.0
#: Random starts move the exponents (``n``, shape exponents) by up to this.
EXPONENT_STEP = 1.0
#: A mapped optimum refits a family when it fits better than the family's optimum by
#: more than this relative RSS.
NESTING_RTOL = 1e-3
#: Levenberg-Marquardt iterations of each start of a state-space family before the best
#: start is continued to convergence.
SYSTEM_START_NFEV = 8
#: Other basins of a term family's stage-1 grid among its output-error starts.
GRID_BASINS = 2
#: At most this many nesting passes (a pass that changes nothing ends them).
NESTING_PASSES = 3

Say = Callable[[str], None]


def _quiet(msg: str) -> None:
    return None


def screen_start(
    data: FitData, par: Parametrization, nfev: int, nuisance: np.ndarray | None = None
) -> tuple[np.ndarray, float]:
    """The one start screener: a start's free parameters and RSS after ``nfev``
    Levenberg-Marquardt iterations (:meth:`OutputErrorFitter.screen`; inf when its
    simulation diverges), or at the start itself for ``nfev = 0`` with the run nuisances
    ``nuisance`` (a refit's starts, judged by one simulation each). The multi-start fits,
    the closing loop's effect refits and its structural grids all screen with it.
    """
    if nfev > 0:
        return OutputErrorFitter(data, par, max_nfev=nfev).screen(nfev)
    nu = np.zeros(0) if nuisance is None else np.asarray(nuisance, dtype=float).ravel()
    v = np.concatenate([par.x0, nu])
    with np.errstate(all="ignore"):
        r = OutputErrorFitter(data, par).residuals(v)
    return par.x0, (float(r @ r) if np.all(np.isfinite(r)) else float("inf"))


def best_of_starts(
    data: FitData,
    starts: Sequence[tuple[str, Parametrization]],
    max_nfev: int,
    screen_nfev: int = SCREEN_NFEV,
    mapper: Callable | None = None,
    say: Say = _quiet,
    name: str = "",
    good_rms: float | None = None,
    first: OEFit | None = None,
    failures: Failures | None = None,
) -> OEFit:
    """The best fit of several starts (see the module docstring).

    With ``good_rms`` the first start is fitted to convergence first; when it ends at or
    below ``good_rms`` (the noise floor: no start can fit better than the noise) the
    other starts are not run, and the note says so. Otherwise the other starts are
    screened; the best of them is continued when its screen already fits better than the
    first start's optimum, and the better of the two fits is kept.

    Parameters
    ----------
    data : FitData
        The runs.
    starts : sequence of (label, Parametrization)
        Each start's label and parametrization (its ``x0`` is the start).
    max_nfev : int
        Iterations of the continued fit.
    screen_nfev : int
        Iterations of each start (a single start is fitted to ``max_nfev`` directly).
    mapper : callable, optional
        ``mapper(fn, items)`` -> list, to run the starts in parallel (default: in turn).
    say : callable
        Progress messages.
    name : str
        The family, for the messages.
    good_rms : float, optional
        The RMS at which a fit is at the noise floor (see above).
    first : OEFit, optional
        The first start's fit to convergence, when it is already made (it is then not
        refitted, and is the lead whatever ``good_rms``).
    failures : Failures, optional
        Where a start whose fit fails is recorded (``"<name> start '<label>'"``); the
        other starts go on. Without it a start's failure raises.

    Returns
    -------
    OEFit
        The best fit (no held-out error: ask :meth:`OutputErrorFitter.heldout_at`), with
        the note on the starts and :attr:`~OEFit.starts` (label -> RMS).

    Raises
    ------
    HystdiscError
        When every start failed (the reasons are in ``failures``).
    """
    if not starts:
        raise ValueError("best_of_starts needs at least one start")
    guard = Failures() if failures is None else failures
    strict = failures is None

    def fitted(k: int, par: Parametrization) -> OEFit | None:
        """Start ``k`` (or its continuation ``par``) fitted to convergence, or None."""
        task = f"{name} start '{starts[k][0]}'"
        with np.errstate(all="ignore"):
            if strict:
                return OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=False)
            return guard.guard(
                task, lambda: OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=False)
            )

    if len(starts) == 1:
        only = fitted(0, starts[0][1])
        if only is None:
            raise HystdiscError(f"{name}: its only start failed (listed under failed)")
        return only
    labels = [label for label, _ in starts]
    lead = first
    if lead is None and good_rms is not None:
        lead = fitted(0, starts[0][1])
    if lead is not None and good_rms is not None:
        if lead.rms <= good_rms:
            _starts_note(
                lead,
                f"the first of {len(starts)} starts ({labels[0]}) reached the noise floor "
                f"(RMS {lead.rms:.4g}): the others were not needed",
            )
            lead.starts = {labels[0]: float(lead.rms)}
            return lead

    def one(k: int) -> tuple[np.ndarray, float]:
        label, par = starts[k]
        say(f"stage 2: output-error fit of {name}, start {k + 1}/{len(starts)} ({label})")
        if strict:
            return screen_start(data, par, screen_nfev)
        out = guard.guard(f"{name} start '{label}'", lambda: screen_start(data, par, screen_nfev))
        return (par.x0, float("inf")) if out is None else out

    run = list(range(1 if lead is not None else 0, len(starts)))
    screened = list((mapper or (lambda f, it: [f(i) for i in it]))(one, run))
    n_obs = max(sum(int(m.sum()) for m in data.mask), 1)
    rms = {
        labels[k]: float(np.sqrt(rss / n_obs)) for k, (_, rss) in zip(run, screened, strict=True)
    }
    pick = int(np.argmin([rss for _, rss in screened]))
    k_pick = run[pick]
    x_pick = screened[pick][0]
    best = lead
    if lead is None or screened[pick][1] < lead.rss:
        # the best screened start is continued (given a converged first start, only when
        # its screen already fits better: a basin the first start did not reach)
        say(f"stage 2: output-error fit of {name} from its best start ({labels[k_pick]})")
        par0 = starts[k_pick][1]
        par = par0.like(par0.params(x_pick), par0.effects)
        cont = fitted(k_pick, par)
        if cont is not None:
            best = cont
            rms[labels[k_pick]] = float(best.rms)
    if best is None:
        raise HystdiscError(
            f"{name}: every start failed or diverged ({len(starts)} starts); the reasons "
            "are listed under failed"
        )
    if lead is not None:
        rms[labels[0]] = float(lead.rms)
        if lead.rss < best.rss:
            best = lead
    top = min(rms.values())
    reached = [lb for lb in labels if rms[lb] <= (1 + REACHED_RTOL) * top]
    others = sorted((lb for lb in labels if lb not in reached), key=lambda lb: rms[lb])
    how = (
        f"the first fitted to convergence, the others screened {screen_nfev} iterations"
        if lead is not None
        else f"each screened {screen_nfev} iterations"
    )
    _starts_note(
        best,
        f"{len(reached)} of {len(labels)} starts reached the optimum ({how}, the best "
        f"continued; RMS within {REACHED_RTOL:.0%}: {', '.join(reached)})"
        + (
            "; the others ended at RMS " + ", ".join(f"{rms[lb]:.4g} ({lb})" for lb in others)
            if others
            else ""
        ),
    )
    best.starts = rms
    return best


def term_starts(
    eq, name: str, n: int, seed: int, s0, one_level: bool, first: dict[str, float] | None = None
) -> list[tuple[str, dict[str, float]]]:
    """The ``n`` starts of a term family: stage 1's (``first`` when already made), other
    basins of its shape's grid (up to :data:`GRID_BASINS`, from the shape constants
    ``s0``), random perturbations of stage 1's (:func:`random_starts`, ``seed``)."""
    starts = family_starts(
        eq, name, min(GRID_BASINS, n - 1), s0=s0, one_level=one_level, first=first
    )
    if n > len(starts):
        starts += random_starts(name, starts[0][1], n - len(starts), seed=seed)
    return starts


def poor_predictions(
    fits: dict[str, OEFit], good_rms: float, with_heldout: Callable[[str], OEFit], mapper
) -> dict[str, str]:
    """The term families whose fit is at the floor (``good_rms``) but may sit in a wrong
    basin: name -> why, in words. Such a fit's held-out error is above the floor, or
    its held-out folds had to be refitted fully (:attr:`OEFit.heldout_refitted`: the data
    leave a curved, flat valley there, which a degenerate basin makes, such as Bouc-Wen's
    ``n -> 0`` with ``beta`` growing without bound). Their held-out errors are computed
    here (``with_heldout`` on the threads of ``mapper``) and kept in ``fits`` (updated)."""
    names = [n for n, f in fits.items() if n in FAMILIES and not f.is_system and f.rms <= good_rms]
    fits.update(zip(names, mapper(with_heldout, names), strict=True))
    out = {}
    for n in names:
        h, flat = fits[n].heldout_rms, fits[n].heldout_refitted
        if h is not None and not h <= good_rms:  # a diverged fold (inf) counts too
            out[n] = f"predicted the held-out runs at RMS {h:.4g}, above the floor {good_rms:.4g}"
        elif flat:
            out[n] = (
                f"its fits without a run moved along a curved, flat valley ({len(flat)} "
                "held-out runs refitted fully), as a degenerate basin makes them"
            )
    return out


def drop_diverged(fits: Mapping[str, OEFit], failures: Failures) -> dict[str, OEFit]:
    """``fits`` without the fits whose simulation diverged at their optimum (on any run):
    each is recorded in ``failures`` with the runs, and is no result."""
    out = {}
    for name, fit in fits.items():
        if fit.diverged:
            runs = ", ".join(fit.diverged[:3]) + (" ..." if len(fit.diverged) > 3 else "")
            failures.record(name, f"its simulation diverged at its optimum (run {runs})")
        else:
            out[name] = fit
    return out


def helper_families(
    fits: dict[str, OEFit], good_rms: float, poor: Collection[str] = ()
) -> dict[str, list[str]]:
    """For each term family in ``fits`` above ``good_rms`` (or named in ``poor``: at the
    floor but not predicting held-out runs), its related families (``Family.start_from``,
    and theirs) that ``fits`` lacks: fitted as its starts only.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> helper_families({"bouc-wen": NS(rms=2.0, is_system=False)}, 1.1)
    {'bouc-wen': ['bouc-wen-std', 'dahl', 'lugre']}
    >>> helper_families({"bouc-wen": NS(rms=1.0, is_system=False)}, 1.1)
    {}
    >>> helper_families({"dahl": NS(rms=1.0, is_system=False)}, 1.1, poor={"dahl"})
    {'dahl': ['lugre']}
    """
    out: dict[str, list[str]] = {}
    for name, fit in fits.items():
        if name not in FAMILIES or fit.is_system or not (fit.rms > good_rms or name in poor):
            continue
        found: list[str] = []
        todo = [name]
        while todo:
            for other in FAMILIES[todo.pop(0)].start_from:
                if other not in fits and other not in found:
                    found.append(other)
                    todo.append(other)
        if found:
            out[name] = found
    return out


def _starts_note(fit: OEFit, note: str) -> None:
    """Add the note on how the starts ended (also kept in :attr:`~OEFit.starts_note`, which
    a refit from another family's optimum carries over)."""
    fit.notes.append(note)
    fit.starts_note = note


def random_starts(
    family: str, start: Mapping[str, float], n: int, seed: int = 0
) -> list[tuple[str, dict[str, float]]]:
    """``n`` random perturbations of ``start`` inside the family's admissible box.

    Every parameter with a nonzero value is scaled by a log-uniform factor in
    ``[1/RANDOM_FACTOR, RANDOM_FACTOR]`` (its sign kept), the exponents (parameters named
    ``n``) moved by up to :data:`EXPONENT_STEP`; each value is clipped inside its bounds.
    """
    fam = get_family(family)
    specs = {p.name: p for p in (*fam.params, *RIG_PARAMS)}
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n):
        p = dict(start)
        for name, v in start.items():
            spec = specs.get(name)
            if spec is None or not np.isfinite(v):
                continue
            if name == "n":
                new = v + rng.uniform(-EXPONENT_STEP, EXPONENT_STEP)
            elif v != 0.0:
                new = v * float(np.exp(rng.uniform(-1.0, 1.0) * np.log(RANDOM_FACTOR)))
            else:
                continue
            p[name] = float(np.clip(new, spec.lower, spec.upper))
        out.append((f"random {k + 1}", p))
    return out


def mapped_starts(family: str, fit: OEFit) -> list[dict[str, float]]:
    """Another family's optimum in ``family``'s parameters, through the term form
    (:meth:`Family.term_starts`: one start, or several when the family contains the
    other model only approximately); empty when either is a state-space model or the
    mapping fails. Values are clipped to the bounds; non-finite readings are dropped."""
    fam = get_family(family)
    if fam.is_system or fit.is_system:
        return []
    try:
        with np.errstate(all="ignore"):
            readings = fam.term_starts(fit.term_part)
    except (KeyError, ValueError, ZeroDivisionError, NotImplementedError):
        return []
    specs = {s.name: s for s in (*fam.params, *RIG_PARAMS)}
    out = []
    for reading in readings:
        p = {k: float(v) for k, v in reading.items()}
        # the rig's parameters and those of the effects the fit carries (a measured
        # channel delay) keep their values
        carried = ("k_s", "J", *(q.name for e in fit.par.effects for q in EFFECTS[e].params))
        for extra in carried:
            if extra in fit.params:
                p.setdefault(extra, float(fit.params[extra]))
        if not all(np.isfinite(v) for v in p.values()):
            continue
        for k, v in p.items():
            if k in specs:
                p[k] = float(np.clip(v, specs[k].lower, specs[k].upper))
        out.append(p)
    return out


def start_rss(data: FitData, par: Parametrization, nuisance: np.ndarray | None = None) -> float:
    """RSS of ``par`` at its start, with the initial states ``nuisance`` (e.g. those of the
    fit the start was mapped from, when they are laid out alike) or the runs' first
    samples."""
    fitter = OutputErrorFitter(data, par)
    nu = data.nuisance_start(par.has_state())
    if nuisance is not None and np.size(nuisance) == nu.size:
        nu = np.asarray(nuisance, dtype=float).ravel()
    v = np.concatenate([par.x0, nu])
    with np.errstate(all="ignore"):
        r = fitter.residuals(v)
    return float(r @ r) if np.all(np.isfinite(r)) else float("inf")


def nesting_pass(
    data: FitData,
    fits: dict[str, OEFit],
    max_nfev: int,
    say: Say = _quiet,
    passes: int = NESTING_PASSES,
    screen_above: float | None = None,
    failures: Failures | None = None,
) -> dict[str, OEFit]:
    """Refit each family from another family's optimum when that optimum, mapped into it,
    fits better than its own (see the module docstring); repeated while a pass changes a
    fit (at most ``passes`` times: a refitted family can lift one that contains it).
    With ``screen_above`` (an RMS: the noise floor), a family whose RMS is above it also
    screens the mapped optima of the families at or below it with no more parameters,
    when they start worse than its own.
    Returns the updated fits (the same objects where nothing changed); each refit carries
    a note. With ``failures``, a refit that fails is recorded there
    (``"<name> nesting refit"``) and the family keeps its fit."""
    out = dict(fits)
    screened: set[tuple] = set()  # (family, other, their RSS): the pairs already screened
    for _ in range(passes):
        changed = False
        for name in list(out):
            args = (data, out, name, max_nfev, say, screen_above, screened)
            if failures is None:
                new = _nested_refit(*args)
            else:
                new = failures.guard(f"{name} nesting refit", _nested_refit, *args)
            if new is not None:
                out[name], changed = new, True
        if not changed:
            break
    return out


def _nested_refit(
    data: FitData,
    fits: dict[str, OEFit],
    name: str,
    max_nfev: int,
    say: Say,
    screen_above: float | None = None,
    screened: set[tuple] | None = None,
) -> OEFit | None:
    """``name`` refitted from the best mapped optimum of the others, or None."""
    fit = fits[name]
    if fit.is_system:
        return None
    best_rss, source = fit.rss, None
    worse: list[tuple[float, str, Parametrization]] = []  # mapped starts that start worse
    done = screened if screened is not None else set()
    for other, ofit in fits.items():
        if other == name or not ofit.rss < fit.rss * (1 - NESTING_RTOL):
            continue
        for p in mapped_starts(name, ofit):
            par = fit.par.like(p, fit.par.effects)
            rss = start_rss(data, par, ofit.nuisance)
            if rss < best_rss * (1 - NESTING_RTOL):
                best_rss, source = rss, (other, par)
            elif (
                screen_above is not None
                and ofit.rms <= screen_above < fit.rms
                and len(ofit.par.names) <= len(fit.par.names)
                and np.isfinite(rss)
                and (name, other, fit.rss, ofit.rss) not in done
            ):
                # a model at the floor with no more parameters: this family should get
                # there too; its mapped optimum is screened below
                worse.append((rss, other, par))
    after = ""  # the mapped start fitted better as it was
    if source is None and worse:
        # an approximate correspondence: a few iterations from each decide
        for _, other, par in sorted(worse, key=lambda w: w[0]):
            say(f"stage 2: {name} screened from the optimum of {other}")
            x, rss = OutputErrorFitter(data, par, max_nfev=SCREEN_NFEV).screen(SCREEN_NFEV)
            if rss < best_rss * (1 - NESTING_RTOL):
                best_rss, source = rss, (other, par.like(par.params(x), par.effects))
                after = f" after {SCREEN_NFEV} iterations"
        done.update((name, o, fit.rss, fits[o].rss) for _, o, _ in worse)
    if source is None:
        return None
    other, par = source
    say(f"stage 2: {name} refitted from the optimum of {other} (it fits better there{after})")
    with np.errstate(all="ignore"):
        new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=False)
    if not new.rss < fit.rss * (1 - NESTING_RTOL):
        return None
    # the new optimum's own notes (identifiability) stand; of the old fit's, the starts'
    if fit.starts_note is not None:
        new.notes.append(fit.starts_note)
    new.notes.append(
        f"refitted from the optimum of {other}, mapped into it, which fitted "
        f"better{after} (RMS {fit.rms:.4g} -> {new.rms:.4g}): a family never ends worse "
        "than a model it contains"
    )
    # the old fit's starts stay the record of how this family was fitted
    new.starts, new.starts_note, new.nested_from = fit.starts, fit.starts_note, other
    return new


def system_fit(
    name: str,
    base: OEFit,
    data: FitData,
    max_nfev: int,
    fixed: Mapping[str, float] | None = None,
    mapper: Callable | None = None,
    say: Say = _quiet,
    failures: Failures | None = None,
) -> OEFit:
    """A state-space family by output error from each of its starts, mapped from a term
    family's fit ``base`` (the standard Bouc-Wen one: ``Family.starts``); the best is
    kept, and how many starts reached it is noted.

    Parameters
    ----------
    name : str
        The state-space family.
    base : OEFit
        The fit its starts are mapped from (its rig parameters are kept, and so are its
        measurement effects and the shares of the scaled effects the family carries,
        :attr:`~hystdisc.models.families.base.SystemFamily.scaled_effects`, with their
        values).
    data : FitData
        The runs.
    max_nfev : int
        Iterations of the best start's fit.
    fixed : mapping, optional
        Parameters held at a value (e.g. the current slopes at one current).
    mapper : callable, optional
        ``map``-like runner of the starts (threads).
    say : callable
        Progress messages.
    failures : Failures, optional
        Where a failed start is recorded (see :func:`best_of_starts`).

    Returns
    -------
    OEFit
        The best start's fit (without its held-out error).
    """
    fam = get_family(name)
    bp = dict(base.params)
    vel = float(np.median([np.max(np.abs(w)) for w in data.theta_dot]))
    starts = fam.starts(bp, velocity=vel, dt=1.0 / sampling_rate(data.t))
    # the base's measurement effects (a channel delay every family carries) and the shares
    # the family's own force carries (an asymmetric yield: Family.scaled_effects), with
    # their values
    effects = tuple(
        e
        for e in base.par.effects
        if (not EFFECTS[e].terms and not EFFECTS[e].structural) or e in fam.scaled_effects
    )
    carried = ("k_s", "J", *(q.name for e in effects for q in EFFECTS[e].params))
    for _, st in starts:
        for k in carried:
            if k in bp:
                st.setdefault(k, bp[k])
    pars = [
        (label, FamilySystemParametrization(name, data.experiment, st, effects, dict(fixed or {})))
        for label, st in starts
    ]
    return best_of_starts(
        data, pars, max_nfev, SYSTEM_START_NFEV, mapper=mapper, say=say, name=name,
        failures=failures,
    )  # fmt: skip
