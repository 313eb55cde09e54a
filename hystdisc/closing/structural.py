"""Structural effects in the loop: diagnosis, starts that find the basin, multi-start refits.

A structural effect (``series_compliance``: the SAS beam on a compliant wheel) adds
states, not torque terms: the model plus the effect is a state-space system
(:class:`~hystdisc.fitting.StructuralParametrization`). Its signature does not exist at
the current optimum in the score test's sense (the rig without the wheel is the limit
``k_w -> infinity`` of the model with it, where the output does not depend on ``m_w`` and
``c_w`` at all), so it is diagnosed globally:

1. **Starts** (:func:`structural_starts`): the current optimum (family, rig and term
   effects) with the wheel at a grid of natural frequencies ``sqrt(k_w / m_w) / 2 pi``
   above the beam's own (:data:`FREQUENCY_RATIOS` times it, plus the residual's spectral
   peak when it lies above the beam's frequency: the resonance the unexplained-residual
   diagnosis names), inertia ratios :data:`INERTIA_RATIOS` and damping ratios
   :data:`DAMPING_RATIOS`. A driven damper has no rig frequency: its mount starts at
   stiffnesses :data:`MOUNT_STIFFNESS_RATIOS` times the damper's own (RMS force over RMS
   motion), with the mount's frequency :data:`MOUNT_FREQUENCY_RATIOS` times the highest
   drive frequency (far above it: the mount's mass is a regularizer, not a resonance the
   data show) and the same damping ratios.
2. **Diagnosis** (:func:`score_structural`): on release data the least damped start of
   every (frequency, inertia) cell is screened by :data:`WHEEL_SCREEN_NFEV` iterations
   on the lowest- and the highest-current run, then simulated on every run
   (:func:`screen_cells`; simulated once, a stiff wheel changes nothing and ranks first,
   and a LuGre beam on an 8 Hz wheel scored evidence 0 where its screened start reached
   the noise); a later round of the loop screens only the previous screen's best cells
   (:data:`N_STARTS` distinct frequencies: ``EffectScore.cells``), a driven mount's
   starts are simulated once. The best one's RSS reduction
   is the effect's evidence (an achieved share of the RSS, a lower bound of what the
   refit will give) and predicts its BIC change. The loop refits the effect when
   that change is a drop or the residual shows its signature; a driven fit above the
   noise always counts as one (the fit without the mount has bent the damper's
   parameters towards it, so its starts predict little: on a bouc-wen-std damper behind
   a mount of 9 times its stiffness the best start was worse than the fit without it, and
   every refit reached the noise).
3. **Refit** (:func:`refit_structural`): release data continue from the screened starts
   (:func:`screened_starts`; screened here when the diagnosis did not), a driven mount
   takes the best-ranked starts; the output-error fit runs from the :data:`N_STARTS` best of them,
   the one with the lowest BIC is kept, and the spread of the starts (their RMS and wheel
   stiffness) is reported with it (:class:`StructuralRefit`).

The refit is then judged like any effect (BIC, significance of the compliance
``1/k_w``, excess share, held-out error, admissibility).
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass

import numpy as np

from hystdisc.closing.diagnostics import (
    WHITE_P,
    ljung_box_pooled,
    residual_spectrum,
    spectral_peak,
)
from hystdisc.closing.refit import EFFECT_BIC_MARGIN
from hystdisc.closing.residual import natural_frequency
from hystdisc.closing.scores import EffectScore
from hystdisc.fitting import OEFit, OutputErrorFitter
from hystdisc.fitting.multistart import screen_start
from hystdisc.measurement import FitData
from hystdisc.models import EFFECTS
from hystdisc.models.effects import Structure
from hystdisc.stats import bic_change, masked, sampling_rate

#: Runs a wheel's grid is screened on (:func:`screen_runs`).
SCREEN_RUNS = 2
#: Wheel natural frequencies of the start grid, in multiples of the beam's own.
FREQUENCY_RATIOS = (1.5, 2.5, 4.0, 6.0, 10.0)
#: Wheel inertias of the start grid, per unit beam inertia.
INERTIA_RATIOS = (0.1, 0.3, 1.0)
#: Damping ratios ``c_w / (2 sqrt(k_w m_w))`` of the start grid.
DAMPING_RATIOS = (0.05, 0.3)
#: A residual peak counts as above the beam's frequency beyond this multiple of it.
PEAK_ABOVE = 1.3
#: Output-error fits per structural refit (from the best screened starts).
N_STARTS = 3
#: The same for a driven mount (each fit integrates a stiff state-space model on every
#: sample; on the synthetic mount the three best starts reached one optimum, k_w within
#: 0.1 % of each other).
N_STARTS_MOUNT = 1
#: Iterations of a driven mount's refit before it must lower BIC to be continued.
MOUNT_SCREEN_NFEV = 4
#: Release: iterations of the screen of each (frequency, inertia) start of the grid before
#: the best :data:`N_STARTS` are continued. One simulation per start ranks them poorly: a
#: stiff wheel changes nothing and ranks first, a start near the true wheel at the wrong
#: inertia makes things worse at first (on a Dahl beam with a 7.1 Hz wheel of inertia 0.1
#: the three best-ranked starts all had inertia 1 and two ended at k_w 276, m_w 0.59, RMS
#: 2 % above the noise; the 7.8 Hz start of inertia 0.1 reaches the wheel in 1 s).
WHEEL_SCREEN_NFEV = 4
#: Driven: mount stiffnesses of the start grid, in multiples of the damper's own.
MOUNT_STIFFNESS_RATIOS = (2.0, 5.0, 15.0, 50.0)
#: Driven: mount natural frequencies of the start grid, in multiples of the top drive
#: frequency.
MOUNT_FREQUENCY_RATIOS = (8.0, 25.0)


@dataclass
class StartOutcome:
    """How the fit from one start of a structural refit ended.

    Attributes
    ----------
    parameter : str
        The parameter that tells the starts apart (the effect's first significance
        parameter, e.g. the wheel's ``k_w``).
    start : float
        Its value at the start (for a screened start, the value of its grid cell).
    value : float
        Its fitted value (NaN when the fit does not report it).
    rms, bic : float
        The RMS and BIC the fit reached.
    """

    parameter: str
    start: float
    value: float
    rms: float
    bic: float


@dataclass
class StructuralRefit:
    """The outcome of :func:`refit_structural`.

    Attributes
    ----------
    fit : OEFit
        The fit with the lowest BIC.
    starts : list of StartOutcome
        How the fit from every start ended, in the order fitted.
    spread : float or None
        The relative spread of :attr:`StartOutcome.value` among the starts within the
        BIC margin of the best (None when the best fit's value is 0 or missing).
    """

    fit: OEFit
    starts: list[StartOutcome]
    spread: float | None


def _wheel(structure: Structure, f_hz: float, m: float, zeta: float) -> dict[str, float]:
    """The structure's values at natural frequency ``f_hz``, inertia ``m``, damping ratio
    ``zeta``."""
    return structure.values(m * (2.0 * np.pi * f_hz) ** 2, m, zeta)


def _structure(name: str) -> Structure:
    """The structure of the structural effect ``name``."""
    structure = EFFECTS[name].structure
    if structure is None:
        raise ValueError(f"{name} is not a structural effect")
    return structure


def _start_key(structure: Structure) -> str:
    """The key under which a screened start keeps its grid cell's stiffness."""
    return f"{structure.stiffness}_start"


def residual_peak(fit: OEFit, data: FitData) -> float | None:
    """Frequency (Hz) of the residual's resonance above the beam's own frequency: the
    largest peak of its run-averaged spectrum when the residual is not white, the peak
    is a resonance (quality factor 2 or more) and it lies between :data:`PEAK_ABOVE`
    and twice the top of :data:`FREQUENCY_RATIOS` times the beam's frequency; else None."""
    f_beam = natural_frequency(fit, data.experiment)
    res = [r for r in masked(fit.residuals, data.mask) if len(r) > 10]
    if not res or f_beam is None or ljung_box_pooled(res) >= WHITE_P:
        return None
    f, psd, resolution = residual_spectrum(res, sampling_rate(data.t))
    fk, q = spectral_peak(f, psd, f_min=resolution)
    inside = PEAK_ABOVE * f_beam < fk < 2 * max(FREQUENCY_RATIOS) * f_beam
    return float(fk) if np.isfinite(fk) and inside and q >= 2.0 else None


def structural_starts(fit: OEFit, data: FitData, name: str) -> list[dict[str, float]]:
    """Starts of ``fit``'s model plus the structural effect ``name`` (see the module docstring).

    Parameters
    ----------
    fit : OEFit
        The current fit (a family parametrization with term effects).
    data : FitData
        Its data (for the residual's spectral peak).
    name : str
        The structural effect (``series_compliance``).

    Returns
    -------
    list of dict
        Full parameter starts (the current optimum with the effect's parameters set).
    """
    structure = _structure(name)
    if data.exp.motion_imposed:
        return mount_starts(fit, data, structure)
    f_beam = natural_frequency(fit, data.experiment)
    if f_beam is None:
        return []
    freqs = [r * f_beam for r in FREQUENCY_RATIOS]
    peak = residual_peak(fit, data)
    if peak is not None:
        freqs.append(peak)
    out = []
    for f, m, zeta in itertools.product(freqs, INERTIA_RATIOS, DAMPING_RATIOS):
        start = dict(fit.params)
        start.update(_wheel(structure, f, m, zeta))
        out.append(start)
    return out


def drive_frequency(data: FitData) -> float | None:
    """The highest of the runs' dominant motion frequencies (Hz; None without motion)."""
    fs = sampling_rate(data.t)
    tops = []
    for th in data.theta:
        x = np.asarray(th, dtype=float) - np.mean(th)
        if x.size < 8 or not np.any(x):
            continue
        spec = np.abs(np.fft.rfft(x))
        k = int(np.argmax(spec[1:])) + 1
        tops.append(k * fs / x.size)
    return max(tops) if tops else None


def mount_starts(fit: OEFit, data: FitData, structure: Structure) -> list[dict[str, float]]:
    """Starts of a driven damper behind a compliant mount (see the module docstring).

    Examples
    --------
    >>> from types import SimpleNamespace
    >>> from hystdisc.models import get_effect
    >>> t = np.arange(2000) / 1000.0
    >>> data = SimpleNamespace(t=[t], theta=[0.2 * np.sin(2 * np.pi * 2 * t)],
    ...                        y=[10.0 * np.sin(2 * np.pi * 2 * t)], mask=[t >= 0])
    >>> mount = get_effect("series_compliance").structure
    >>> starts = mount_starts(SimpleNamespace(params={"c_1": 1.0}), data, mount)
    >>> len(starts), round(starts[0]["k_w"], 6), round(starts[0]["m_w"], 6)
    (16, 100.0, 0.009895)
    """
    f_top = drive_frequency(data)
    ys = np.concatenate([np.asarray(y)[m] for y, m in zip(data.y, data.mask, strict=True)])
    xs = np.concatenate([np.asarray(x)[m] for x, m in zip(data.theta, data.mask, strict=True)])
    xs = xs - np.mean(xs)
    if f_top is None or not np.any(xs):
        return []
    k_damper = float(np.sqrt(np.mean((ys - np.mean(ys)) ** 2) / np.mean(xs**2)))
    out = []
    grid = itertools.product(MOUNT_STIFFNESS_RATIOS, MOUNT_FREQUENCY_RATIOS, DAMPING_RATIOS)
    for kr, fr, zeta in grid:
        k = kr * k_damper
        m = k / (2.0 * np.pi * fr * f_top) ** 2
        start = dict(fit.params)
        start.update(structure.values(k, m, zeta))
        out.append(start)
    return out


def _rss_at(data: FitData, fit: OEFit, name: str, start: dict) -> tuple[float, np.ndarray]:
    """RSS and per-run RSS of ``fit``'s structure plus ``name`` at ``start``."""
    par = fit.par.like(start, (*fit.par.effects, name))
    v = np.concatenate([par.x0, np.asarray(fit.nuisance, dtype=float).ravel()])
    fitter = OutputErrorFitter(data, par)
    with np.errstate(all="ignore"):
        r = fitter.residuals(v)
    if not np.all(np.isfinite(r)):
        return float("inf"), np.full(data.n_runs, np.inf)
    rows = fitter.row_offsets
    per = np.array(
        [float(r[rows[k] : rows[k + 1]] @ r[rows[k] : rows[k + 1]]) for k in range(data.n_runs)]
    )
    return float(r @ r), per


def score_structural(
    data: FitData, fit: OEFit, name: str, cells: list[dict] | None = None
) -> EffectScore | None:
    """Diagnose the structural effect ``name`` by its screened starts (module docstring).

    Parameters
    ----------
    data : FitData
        The data.
    fit : OEFit
        The current fit.
    name : str
        The structural effect.
    cells : list of dict, optional
        Release: the wheel values (``m_w``, ``k_w``, ``c_w``) to screen instead of the
        whole grid (a later round of the loop screens the best cells of the first:
        :data:`N_STARTS` distinct frequencies, ``EffectScore.cells``).

    Returns
    -------
    EffectScore or None
        ``evidence`` is the share of the RSS the best start removes, ``starts`` the starts
        ranked by their RSS (None when the rig has no frequency to start from).
    """
    if cells and not data.exp.motion_imposed:
        # a later round: the kept cells only (the grid and its residual spectrum unbuilt)
        has_beam = natural_frequency(fit, data.experiment) is not None
        starts = [{**fit.params, **w} for w in cells] if has_beam else []
    else:
        starts = structural_starts(fit, data, name)
    if not starts:
        return None
    ranked, screened = [], []
    if not data.exp.motion_imposed:
        # release: one simulation per start ranks them poorly (a stiff wheel changes
        # nothing and ranks first; a LuGre beam on an 8 Hz wheel scored evidence 0, while
        # its screened start reached the noise), so the cells are screened here and the
        # refit continues from these screened starts
        screened = screen_cells(data, fit, name, starts)
        structure = _structure(name)
        for rss, per, params, cell in screened:
            ranked.append((rss, per, {**params, _start_key(structure): cell[structure.stiffness]}))
    else:
        for st in starts:
            rss, per = _rss_at(data, fit, name, st)
            if np.isfinite(rss):
                ranked.append((rss, per, st))
    if not ranked:
        return None
    ranked.sort(key=lambda t: t[0])
    rss, per, best = ranked[0]
    if data.exp.motion_imposed:
        # a fit without the mount has already bent the damper's parameters towards it, so
        # a start there predicts little: the mount is judged after its refit
        signature = "a driven fit above the noise (a compliant mount is judged by its refit)"
    else:
        peak = residual_peak(fit, data)
        signature = (
            None if peak is None else f"a residual resonance near {peak:.3g} Hz, above the beam's"
        )
    rows = np.cumsum([0] + [int(m.sum()) for m in data.mask])
    base_per = [float(np.sum(r[m] ** 2)) for r, m in zip(fit.residuals, data.mask, strict=True)]
    N = int(rows[-1])
    gain = max(fit.rss - rss, 0.0)
    eff = EFFECTS[name]
    q = len(eff.params)
    s2 = fit.rss / max(N - fit.n_params, 1)
    return EffectScore(
        name=name,
        terms=eff.terms,
        evidence=float(gain / fit.rss) if fit.rss > 0 else 0.0,
        per_run=[
            float(max(b - a, 0.0) / b) if b > 0 else 0.0 for a, b in zip(per, base_per, strict=True)
        ],
        lm=float(gain / s2) if s2 > 0 else 0.0,
        predicted_rms=float(np.sqrt(min(rss, fit.rss) / N)),
        predicted_dbic=bic_change(min(rss, fit.rss), fit.rss, N, q),
        estimate={p.name: float(best[p.name]) for p in eff.params},
        start_rms=float(np.sqrt(rss / N)),
        start_dbic=bic_change(rss, fit.rss, N, q),
        start=best,
        starts=[st for _, _, st in ranked],
        signature=signature,
        cells=distinct_starts([c for *_, c in screened], _structure(name), N_STARTS) or None,
    )


def distinct_starts(
    starts: list[dict], structure: Structure, n: int, rel: float = 0.2, by: str = "frequency"
) -> list[dict]:
    """The first ``n`` of ``starts`` whose natural frequencies (``by="frequency"``, a
    release's wheel) or stiffnesses (``by="stiffness"``, a driven mount) of the
    ``structure`` differ by more than ``rel`` from each other (the ranking's best of each).

    Examples
    --------
    >>> from hystdisc.models.effects import Structure
    >>> wheel = Structure(lambda terms, exp: None, "m", "k", "c")
    >>> s = [{"k": 100.0, "m": 1.0}, {"k": 110.0, "m": 1.0}, {"k": 400.0, "m": 1.0}]
    >>> [d["k"] for d in distinct_starts(s, wheel, 2)]
    [100.0, 400.0]
    """

    def key(st: dict) -> float:
        return st[structure.stiffness] if by == "stiffness" else structure.frequency(st)

    out: list[dict] = []
    for st in starts:
        w = key(st)
        if all(abs(w / key(o) - 1.0) > rel for o in out):
            out.append(st)
        if len(out) == n:
            break
    return out


def screened_starts(
    data: FitData, fit: OEFit, name: str, starts: list[dict], n: int = N_STARTS
) -> list[dict]:
    """The ``n`` release starts to continue: the ``n`` lowest BIC after
    :func:`screen_cells` (their screened parameters, with the grid start's stiffness kept
    under :func:`_start_key`), distinct in frequency as :func:`distinct_starts` keeps
    them. Starts that are already screened (they carry that key, from
    :func:`score_structural`) are not screened again."""
    structure = _structure(name)
    key = _start_key(structure)
    if starts and all(key in st for st in starts):
        return distinct_starts(starts, structure, n)
    screened = [
        {**params, key: cell[structure.stiffness]}
        for _, _, params, cell in screen_cells(data, fit, name, starts)
    ]
    return distinct_starts(screened, structure, n) or distinct_starts(starts, structure, n)


def screen_runs(data: FitData) -> list[int]:
    """The runs a wheel's grid is screened on: the lowest and the highest current (the
    wheel is the rig's, in every run; the damper's share of the beam differs most between
    them), or every run when there are two or fewer.

    Examples
    --------
    >>> from types import SimpleNamespace as NS
    >>> screen_runs(NS(n_runs=5, currents=np.array([0.5, 0.0, 1.0, 0.25, 0.75])))
    [1, 2]
    """
    if data.n_runs <= SCREEN_RUNS:
        return list(range(data.n_runs))
    order = np.argsort(np.asarray(data.currents, dtype=float), kind="stable")
    return sorted({int(order[0]), int(order[-1])})


def screen_cells(
    data: FitData, fit: OEFit, name: str, starts: list[dict]
) -> list[tuple[float, np.ndarray, dict, dict]]:
    """The least damped start of every (wheel frequency, inertia) cell of the grid, each
    fitted by :data:`WHEEL_SCREEN_NFEV` Levenberg-Marquardt iterations on the runs of
    :func:`screen_runs`, then simulated on every run: ``(RSS, each run's RSS, the screened
    parameters, the cell's wheel values)``, lowest RSS first (failed screens left out)."""
    cells: dict[tuple, dict] = {}
    sc = _structure(name)
    for st in starts:  # the least damped start of each cell (a damped one drifts to m -> 0)
        m = st[sc.inertia]
        cell = (round(float(np.log(st[sc.stiffness] / m)), 3), round(float(m), 6))
        if cell not in cells or st[sc.damping] < cells[cell][sc.damping]:
            cells[cell] = st
    runs = screen_runs(data)
    sub = data if len(runs) == data.n_runs else data.subset(runs)
    screened = []
    for st in cells.values():
        par = fit.par.like(st, (*fit.par.effects, name))
        # a screen, not a fit: no intervals (their Jacobian was a fifth of the cost)
        x, sub_rss = screen_start(sub, par, WHEEL_SCREEN_NFEV)
        if not np.isfinite(sub_rss):
            continue
        params = par.params(x)
        rss, per = _rss_at(data, fit, name, params)
        if np.isfinite(rss):
            wheel = {p.name: float(st[p.name]) for p in EFFECTS[name].params}
            screened.append((rss, per, params, wheel))
    screened.sort(key=lambda b: b[0])
    return screened


def refit_structural(
    data: FitData,
    fit: OEFit,
    name: str,
    starts: list[dict],
    max_nfev: int = 60,
    heldout: bool = False,
    n_starts: int = N_STARTS,
) -> StructuralRefit:
    """Fit ``fit``'s model plus the structural effect ``name`` from the best ``starts``.

    Parameters
    ----------
    data : FitData
        The data.
    fit : OEFit
        The current fit.
    name : str
        The structural effect.
    starts : list of dict
        Full starts, best first (:attr:`EffectScore.starts` of :func:`score_structural`).
    max_nfev : int
        Simulation budget of each fit.
    heldout : bool
        Compute the held-out error of the kept fit.
    n_starts : int
        Fits to run (the first ``n_starts`` starts).

    Returns
    -------
    StructuralRefit
        The fit with the lowest BIC, every start's outcome (start and final ``k_w``, RMS,
        BIC) and the relative spread of ``k_w`` among the starts within the BIC margin of
        the best.
    """
    eff = EFFECTS[name]
    key = (eff.significance or tuple(p.name for p in eff.params))[0]
    fits, rows = [], []  # the fits and how each ended
    by = "stiffness" if data.exp.motion_imposed else "frequency"
    if data.exp.motion_imposed:
        n_starts = min(n_starts, N_STARTS_MOUNT)
    chosen = (
        distinct_starts(starts, _structure(name), n_starts, by=by)
        if data.exp.motion_imposed
        else screened_starts(data, fit, name, starts, n_starts)
    )
    for st in chosen:
        par = fit.par.like(st, (*fit.par.effects, name))
        with np.errstate(all="ignore"):
            if data.exp.motion_imposed:
                # a few iterations first: the mount is continued only when they already
                # lower BIC (a mount the data do not have costs a full stiff fit otherwise)
                new = OutputErrorFitter(data, par, max_nfev=MOUNT_SCREEN_NFEV).fit(heldout=False)
                if np.isfinite(new.bic) and new.bic < fit.bic - EFFECT_BIC_MARGIN:
                    par = fit.par.like(new.params, (*fit.par.effects, name))
                    new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=False)
            else:
                new = OutputErrorFitter(data, par, max_nfev=max_nfev).fit(heldout=False)
        fits.append(new)
        rows.append(
            StartOutcome(
                key,
                float(st.get(f"{key}_start", st[key])),
                float(new.params.get(key, np.nan)),
                float(new.rms),
                float(new.bic),
            )
        )
    ok = [f for f in fits if np.isfinite(f.bic)]
    best = min(ok, key=lambda f: f.bic) if ok else fits[0]
    if heldout and ok:
        best = OutputErrorFitter(data, best.par, max_nfev=max_nfev).heldout_at(best)
    near = [r.value for r in rows if np.isfinite(r.bic) and r.bic < best.bic + EFFECT_BIC_MARGIN]
    spread = (
        float((max(near) - min(near)) / abs(best.params[key]))
        if near and best.params.get(key)
        else None
    )
    return StructuralRefit(best, rows, spread)
