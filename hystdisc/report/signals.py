"""What the report draws, from the estimator's public fitted attributes: measured and
simulated output of each run, residuals, and the hysteresis loops of data and models."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from hystdisc.data import estimate_noise
from hystdisc.errors import HystdiscError
from hystdisc.registry import get_experiment
from hystdisc.report.markup import color_of
from hystdisc.stats import masked, sampling_rate


def fit_data(disc):
    """The estimator's prepared runs (``fit_data_``), or a one-line HystdiscError."""
    fd = getattr(disc, "fit_data_", None)
    if fd is None:
        raise HystdiscError(
            "this Discovery holds no fitted data (not fitted, or loaded from results.json); "
            "fix: fit it on the dataset before writing a report"
        )
    return fd


def check_fitted(disc) -> None:
    """A one-line HystdiscError unless ``disc`` is fitted."""
    if not hasattr(disc, "results_") or not hasattr(disc, "family_fits_"):
        raise HystdiscError("this Discovery is not fitted yet; fix: call fit(dataset) first")


def final_fit(disc):
    """The selected family's fit with accepted effects (None when no effect was accepted)."""
    fit = getattr(disc, "final_fit_", None)
    if fit is None or not getattr(disc, "effects_", None):
        return None
    return fit


def fits_of(disc) -> dict[str, Any]:
    """Fits to show: every family, the discovered structure when it is no family, the final."""
    fits = dict(disc.family_fits_)
    dfit = getattr(disc, "discovered_fit_", None)
    if dfit is not None and all(dfit is not f for f in fits.values()):
        fits["discovered"] = dfit
    final = final_fit(disc)
    if final is not None:
        fits["final"] = final
    return fits


def fit_label(disc, key: str) -> str:
    """Legend label of a fit key (a family, ``"discovered"`` or ``"final"``)."""
    if key == "discovered":
        return f"discovered ({disc.discovered_name_})"
    if key == "final":
        return f"{disc.family_} + {' + '.join(disc.effects_)}"
    return key


def masked_residuals(fit, fd) -> list[np.ndarray]:
    """A fit's residual of every run on the samples the fit uses."""
    return masked(fit.residuals, fd.mask)


def fit_sampling_rate(fd) -> float:
    """The sampling rate of the prepared runs in Hz."""
    return sampling_rate(fd.t)


# ----------------------------------------------------------------------------- signals


def shown_runs(currents: Sequence[float], max_runs: int = 5) -> list[int]:
    """Indices of the runs to draw: the first run of each current, then the others, in order.

    Examples
    --------
    >>> shown_runs([0, 0, 0.5, 0.5, 1, 1], max_runs=4)
    [0, 2, 4, 1]
    """
    seen: list[float] = []
    first, rest = [], []
    for k, c in enumerate(currents):
        if any(abs(c - s) <= 1e-9 * max(1.0, abs(s)) for s in seen):
            rest.append(k)
        else:
            seen.append(float(c))
            first.append(k)
    return (first + rest)[: max(int(max_runs), 1)]


def fit_signals(disc, runs: Sequence[int] | None = None) -> list[dict[str, Any]]:
    """Measured and simulated output of each run, as fitted.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    runs : sequence of int, optional
        Run indices (default: all).

    Returns
    -------
    list of dict
        Per run: ``name``, ``current``, ``t``, ``measured`` (angle, or torque when driven;
        release runs trimmed as fitted), ``mask`` (samples in the fit) and ``predictions``
        (key -> simulated output; keys are the families, ``"discovered"`` when the
        discovered structure is no family, ``"final"`` with accepted effects).
    """
    check_fitted(disc)
    fd = fit_data(disc)
    fits = fits_of(disc)
    idx = range(fd.n_runs) if runs is None else runs
    return [
        {
            "name": fd.names[k],
            "current": float(fd.currents[k]),
            "t": fd.t[k],
            "measured": fd.y[k],
            "mask": fd.mask[k],
            "predictions": {key: f.predictions[k] for key, f in fits.items()},
        }
        for k in idx
    ]


def fit_residuals(disc, key: str | None = None) -> list[np.ndarray]:
    """Output-error residual (simulated - measured) of every run, on the fitted samples.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    key : str, optional
        A family, ``"discovered"`` or ``"final"``; default: the final model (with the
        accepted effects) when there is one, else the selected family.

    Returns
    -------
    list of ndarray
        One residual per run (for :func:`hystdisc.plotting.plot_residual_spectrum`).
    """
    check_fitted(disc)
    fd = fit_data(disc)
    fits = fits_of(disc)
    if key is None:
        key = "final" if "final" in fits else disc.family_
    if key not in fits:
        raise HystdiscError(f"no fit named {key!r}; fix: use one of {', '.join(fits)}")
    return masked_residuals(fits[key], fd)


def _simulated_damper(fit, fd, runs: Sequence[int]) -> list[Any]:
    """Simulated theta, theta_dot and damper torque of release/forced runs (SimResults);
    None for a run that diverged, and for every run of a model with no term form (a
    state-space family, or a structural effect's beam on a wheel: its damper acts on the
    motion relative to the wheel, which these loops do not draw)."""
    from hystdisc.fitting import SystemParametrization
    from hystdisc.simulation import simulate_mech

    if isinstance(fit.par, SystemParametrization):
        return [None] * len(runs)
    nu = np.asarray(fit.nuisance)
    kw: dict[str, Any] = {}
    if get_experiment(fd.experiment).has_input:
        kw = {"inputs": [fd.u[r] for r in runs], "theta_dot0": [nu[r, 1] for r in runs]}
        if nu.shape[1] > 2:
            kw["z0"] = [nu[r, 2] for r in runs]
    out, status = simulate_mech(
        fit.term_model,
        [fd.t[r] for r in runs],
        [float(fd.currents[r]) for r in runs],
        [float(nu[r, 0]) for r in runs],
        raise_on_divergence=False,
        **kw,
    )
    return [None if s else o for o, s in zip(out, status, strict=True)]


def model_loops(
    disc,
    runs: Sequence[int] | None = None,
    fits: Sequence[str] | None = None,
) -> list[dict[str, Any]]:
    """Hysteresis loops of the data and of the fitted models, ready for ``loops_figure``.

    For a driven test the data loop is the measured torque against the smoothed imposed
    motion, and each model's loop its simulated torque on the same motion. For a release
    (or forced) test the damper torque is not measured: the data loop is the torque the
    rig equation implies, ``-theta'' - k_s theta`` (``+ u`` and ``J theta''`` when forced),
    from the smoothed angle and the selected family's ``k_s``; each model's loop is the
    damper torque of its own simulation (fitted initial angle) against its simulated
    velocity and angle.

    Parameters
    ----------
    disc, runs
        As in :func:`fit_signals`.
    fits : sequence of str, optional
        Which fits (default: every family, ``"discovered"`` when it is no family and
        ``"final"`` when effects were accepted).

    Returns
    -------
    list of dict
        Loop dicts (``t, theta, theta_dot, torque, current, label, style``) plus ``run``
        (index) and ``kind`` (``"data"`` or the fit key), data first for every run.
    """
    from hystdisc.discovery.differentiation import differentiate

    check_fitted(disc)
    fd = fit_data(disc)
    all_fits = fits_of(disc)
    keys = list(all_fits) if fits is None else [k for k in fits if k in all_fits]
    idx = list(range(fd.n_runs)) if runs is None else list(runs)
    loops: list[dict[str, Any]] = []
    sims: dict[str, list[Any]] = {}
    exp = get_experiment(fd.experiment)
    if not exp.motion_imposed and idx:
        for key in keys:
            sims[key] = _simulated_damper(all_fits[key], fd, idx)
    ref = final_fit(disc) or disc.family_fits_[disc.family_]
    k_s = float(ref.params.get("k_s", 0.0))
    J = float(ref.params.get("J", 1.0)) if exp.has_input else 1.0
    for j, r in enumerate(idx):
        cur = float(fd.currents[r])
        base = {"current": cur, "run": r}
        if exp.motion_imposed:
            th, w, tq, data_t = fd.theta[r], fd.theta_dot[r], fd.y[r], fd.t[r]
            data_label = f"measured ({cur:g} A)"
        else:
            y = np.asarray(fd.y[r], dtype=float)
            d = differentiate(fd.t[r], y, estimate_noise(y, 1.0 / np.median(np.diff(fd.t[r]))))
            # the smoothed derivatives are unreliable within half a window of the ends
            h = min(d.window // 2 + 1, max(y.size // 4, 0))
            keep = slice(h, y.size - h)
            th, w = d.theta[keep], d.theta_dot[keep]
            tq = -J * d.theta_ddot[keep] - k_s * th
            if exp.has_input:
                tq = tq + fd.u[r][keep]
            data_t = fd.t[r][keep]
            data_label = f"data: rig equation ({cur:g} A)"
        loops.append(
            {
                **base,
                "t": data_t,
                "theta": th,
                "theta_dot": w,
                "torque": tq,
                "label": data_label,
                "kind": "data",
                "style": {"color": "0.55", "lw": 0.8},
            }
        )
        for key in keys:
            style = {"color": color_of(key), "lw": 1.1, "ls": "--"}
            label = fit_label(disc, key)
            if exp.motion_imposed:
                item = {
                    "t": fd.t[r],
                    "theta": th,
                    "theta_dot": w,
                    "torque": all_fits[key].predictions[r],
                }
            else:
                sim = sims[key][j]
                if sim is None:
                    continue
                item = {
                    "t": sim.t,
                    "theta": sim.theta,
                    "theta_dot": sim.theta_dot,
                    "torque": sim.torque,
                }
            loops.append({**base, **item, "label": label, "kind": key, "style": style})
    return loops


# ----------------------------------------------------------------------------- sections
