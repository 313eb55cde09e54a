"""The seed's flowchart, automated: fit level by level, then choose each current law.

1. The family is fitted at each current level on its own (:func:`level_fits`), 0 A
   first, each next level started from the last level's optimum, with its
   current-dependent parameters fixed at 0: its passive parameters (``alpha_1``, ``c_1``,
   ...) ARE the values at that level, with 95 % intervals. By default the shape
   parameters (``beta``, ``gamma``, ``n``, the rig spring) are held at the joint fit's
   values (``shape="shared"``): the per-level values are then what the joint model needs
   at each current, which is the question a law answers. With ``shape="free"`` every
   parameter is fitted at every level (the seed's flowchart to the letter); on the real
   UTFSM damper the exponent ``n`` then wanders from 0.4 at 0 A to 4.6 at 1 A and the
   law parameters absorb the shape's changes (``benchmarks/results/current_laws.md``).
2. Each law parameter's law is chosen among linear, quadratic and saturating by leaving
   one level out (:func:`hystdisc.selection.laws.choose_law`): the law fitted to the other
   levels, weighted by their intervals, predicts the left-out level's value. This is
   cheap (no simulation) and it is a held-out judgment of exactly what a law claims: the
   value at a current the law did not see.
3. The joint fit over every run uses the chosen laws: the family's own parametrization
   with them (``FamilyParametrization(..., laws=...)``; a saturating law's ``i0`` or a
   quadratic law's coefficient is a free parameter of the family's model), started from
   the family's joint (linear) fit for the shared parameters and from the laws fitted to
   the levels; it is judged by the held-out output error as every fit is. When every
   chosen law is linear the joint fit is the family's own fit. The joint fit is a family
   fit like any other: :class:`~hystdisc.Discovery` makes it the selected family's fit,
   so the closing loop, ``results.json`` and ``hystdisc predict`` carry the laws.

:func:`staged_fit` runs the three steps and returns a :class:`StagedFit`.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass, field

import numpy as np

from hystdisc.data import distinct_currents
from hystdisc.errors import HystdiscError
from hystdisc.fitting.output_error import OEFit, OutputErrorFitter
from hystdisc.fitting.parametrization import FamilyParametrization, FamilySystemParametrization
from hystdisc.measurement.fitdata import FitData
from hystdisc.models import EFFECTS
from hystdisc.selection.laws import (
    LAWS,
    MIN_LEVELS,
    choose_law,
    fit_law,
    floored_se,
    law_names,
)

#: Current levels the staged fit needs (a law through two points is not judged).
MIN_STAGED_LEVELS = 3


@dataclass
class LevelFit:
    """The family fitted at one current level.

    Attributes
    ----------
    current : float
        The level (A).
    runs : list of int
        Its runs (indices into the fit data).
    fit : OEFit
        The fit (current-dependent parameters fixed at 0).
    """

    current: float
    runs: list[int]
    fit: OEFit


@dataclass
class StagedFit:
    """Outcome of the staged fit (:func:`staged_fit`).

    Attributes
    ----------
    family : str
        The family.
    levels : list of LevelFit
        The fits level by level, lowest current first.
    laws : dict
        Law name -> ``{"parameter", "slope", "values", "ci95", "stderr", "law", "coefs",
        "candidates"}``: the passive parameter and its slope, its per-level values and
        intervals, the chosen law, its coefficients (``a``, ``b``, ``q`` or ``i0``) and
        each candidate's leave-one-level-out error (:func:`~hystdisc.selection.laws.loo_error`).
    joint : OEFit
        The joint fit over every run with the chosen laws (the family's own fit when every
        law is linear).
    linear : OEFit
        The family's joint fit with linear laws (the comparison).
    changed : bool
        A law other than linear was chosen (``joint`` is a new fit).
    notes : list of str
        Plain-word notes (a law left linear for want of levels, ...).
    """

    family: str
    levels: list[LevelFit]
    laws: dict[str, dict]
    joint: OEFit
    linear: OEFit
    changed: bool
    notes: list[str] = field(default_factory=list)

    @property
    def chosen(self) -> dict[str, str]:
        """Law name -> chosen law."""
        return {k: v["law"] for k, v in self.laws.items()}

    def report(self) -> str:
        """The steps as the seed's flowchart shows them: level by level, then the laws."""
        lines = [f"Staged fit of {self.family} (the seed's flowchart: 0 A first, then each step)"]
        for lv in self.levels:
            f = lv.fit
            lines.append(
                f"  level {lv.current:g} A ({len(lv.runs)} runs): RMS {f.rms:.4g}"
                + ("" if f.success else " (not converged)")
            )
            for k in f.par.names:
                lo, hi = f.ci95[k]
                lines.append(f"    {k:<10} {f.params[k]:>12.5g}  [{lo:.4g}, {hi:.4g}]")
        lines.append(
            "  current laws (leave one level out; error in units of the level's interval):"
        )
        head = "    parameter  " + "".join(f"{law:>12}" for law in LAWS) + "  linear p   chosen"
        lines.append(head)
        for d in self.laws.values():
            cells = "".join(
                f"{'-':>12}" if c is None else f"{c['z']:>12.3g}" for c in d["candidates"].values()
            )
            coefs = ", ".join(f"{k}={v:.4g}" for k, v in d["coefs"].items())
            p = d["linear_p"]
            lines.append(f"    {d['parameter']:<10} {cells}  {p:>8.2g}   {d['law']} ({coefs})")
        j, lin = self.joint, self.linear
        lines.append(
            "  joint fit with the chosen laws: RMS "
            f"{j.rms:.4g} (linear {lin.rms:.4g}), held-out RMS {_num(j.heldout_rms)} "
            f"(linear {_num(lin.heldout_rms)})"
        )
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)

    def to_dict(self, run_names: list[str] | None = None) -> dict:
        """The ``current_laws`` table of ``results.json`` (plain JSON values).

        ``levels``: each level's current, runs, RMS and parameters with 95 % intervals;
        ``laws``: per law, the parameter, its per-level values and intervals, the chosen
        law, its coefficients by free-parameter name (``alpha_1``, ``alpha_2``,
        ``alpha_i0``; ``a``, ``b`` and ``q`` or ``i0`` of :mod:`hystdisc.selection.laws`), and
        each candidate's held-out error (leave one level out: ``z`` in units of the level's
        standard error, ``rms`` in the parameter's unit; null without enough levels);
        ``joint`` and ``linear``: RMS, held-out RMS, BIC of the joint fits; ``joint`` also
        its parameters with intervals.
        """

        def pars(fit: OEFit) -> dict:
            return {
                k: {"value": float(v), "ci95": [float(c) for c in fit.ci95.get(k, (v, v))]}
                for k, v in fit.params.items()
            }

        def summary(fit: OEFit) -> dict:
            ho = None if fit.heldout_rms is None else float(fit.heldout_rms)
            return {"rms": float(fit.rms), "heldout_rms": ho, "bic": float(fit.bic)}

        laws = {}
        for key, d in self.laws.items():
            names = law_names(key, d["parameter"], d["slope"], d["law"])
            coefs = [d["coefs"][c] for c in LAWS[d["law"]]]
            laws[key] = {
                "parameter": d["parameter"],
                "currents": [float(c) for c in d["currents"]],
                "values": [float(v) for v in d["values"]],
                "ci95": [[float(c) for c in ci] for ci in d["ci95"]],
                "law": d["law"],
                "proposed": d.get("proposed", d["law"]),
                "linear_p": float(d["linear_p"]),
                "coefficients": dict(zip(names, map(float, coefs), strict=True)),
                "heldout": {
                    law: None if c is None else {"z": float(c["z"]), "rms": float(c["rms"])}
                    for law, c in d["candidates"].items()
                },
            }
        return {
            "family": self.family,
            "heldout_by": "level",
            "levels": [
                {
                    "current": lv.current,
                    "runs": [run_names[r] for r in lv.runs] if run_names else list(lv.runs),
                    "rms": float(lv.fit.rms),
                    "parameters": pars(lv.fit),
                }
                for lv in self.levels
            ],
            "laws": laws,
            "changed": self.changed,
            "joint": {**summary(self.joint), "parameters": pars(self.joint)},
            "linear": summary(self.linear),
            "notes": list(self.notes),
        }


def _num(x: float | None) -> str:
    return "-" if x is None else f"{x:.4g}"


def level_runs(currents: np.ndarray) -> tuple[np.ndarray, list[list[int]]]:
    """The distinct current levels and the runs at each (nearest level)."""
    levels = distinct_currents(currents)
    idx = [int(np.argmin(np.abs(levels - c))) for c in currents]
    return levels, [[r for r, k in enumerate(idx) if k == j] for j in range(levels.size)]


def level_parametrization(
    par: FamilyParametrization, start: Mapping[str, float], shared: bool = False
):
    """``par``'s family at one current: the current-dependent parameters fixed at 0 (and,
    with ``shared``, every parameter but the laws' passive ones held at ``start``)."""
    fixed = dict(par.fixed)
    fixed.update({p: 0.0 for p in par.family.current_params})
    if shared:
        passive = {a for a, _ in par.family.current_laws.values()}
        base = _family_par(par, start, fixed)
        fixed.update({n: float(start[n]) for n in base.names if n not in passive})
    return _family_par(par, start, fixed)


def _family_par(
    par, start: Mapping[str, float], fixed: dict, laws: Mapping[str, str] | None = None
):
    """``par``'s family (term form or state-space) started at ``start`` with ``fixed`` and
    the current ``laws`` (law name -> law)."""
    laws = dict(laws or {})
    chain = measurement_effects(par.effects)  # the record's, not the damper's: kept
    if isinstance(par, FamilySystemParametrization):
        return FamilySystemParametrization(
            par.family, par.experiment, dict(start), chain, fixed, laws
        )
    return FamilyParametrization(
        par.family, par.experiment, dict(start), chain, fixed, par.norm, laws
    )


def measurement_effects(effects) -> tuple[str, ...]:
    """The effects of the measurement chain among ``effects`` (no torque terms, no states:
    a channel delay), which every per-level fit of the staged fit carries too."""
    return tuple(e for e in effects if not EFFECTS[e].terms and not EFFECTS[e].structural)


def level_fits(
    fd: FitData,
    par: FamilyParametrization,
    start: Mapping[str, float],
    max_nfev: int = 40,
    progress: Callable[[str], None] | None = None,
    shape: str = "shared",
) -> list[LevelFit]:
    """The family fitted at each current level, lowest first, each started from the last.

    ``start`` starts the lowest level (e.g. the joint fit's parameters: its passive ones
    are the values at 0 A). ``shape="shared"`` holds every parameter but the laws' passive
    ones at ``start`` (the joint fit's shape); ``"free"`` fits them at every level too.
    """
    if shape not in ("shared", "free"):
        raise HystdiscError(f"unknown shape option '{shape}'; fix: use shared or free")
    say = progress or (lambda msg: None)
    levels, groups = level_runs(fd.currents)
    out: list[LevelFit] = []
    s = dict(start)
    for cur, runs in zip(levels, groups, strict=True):
        say(f"staged fit: level {cur:g} A ({len(runs)} runs)")
        lp = level_parametrization(par, s, shared=shape == "shared")
        fit = OutputErrorFitter(fd.subset(runs), lp, max_nfev=max_nfev).fit(heldout=False)
        out.append(LevelFit(float(cur), runs, fit))
        s = dict(fit.params)
    return out


def choose_laws(family, levels: list[LevelFit]) -> tuple[dict[str, dict], list[str]]:
    """Each declared law's per-level values and the law chosen for them."""
    i = [lv.current for lv in levels]
    out: dict[str, dict] = {}
    notes: list[str] = []
    for key, (passive, slope) in family.current_laws.items():
        if passive not in levels[0].fit.par.names:
            notes.append(f"{passive} is fixed by the normalization: no law is fitted for it")
            continue
        v = [lv.fit.params[passive] for lv in levels]
        se = [lv.fit.stderr[passive] for lv in levels]
        d = choose_law(i, v, se)
        out[key] = {
            "parameter": passive,
            "slope": slope,
            "currents": i,
            "values": v,
            "ci95": [list(lv.fit.ci95[passive]) for lv in levels],
            "stderr": se,
            **d,
        }
    if len(levels) < min(n for law, n in MIN_LEVELS.items() if law != "linear"):
        notes.append(
            f"{len(levels)} current levels: quadratic and saturating laws need "
            f"{MIN_LEVELS['quadratic']} (each law stays linear)"
        )
    return out, notes


def joint_fit(
    fd: FitData,
    par: FamilyParametrization,
    shared: Mapping[str, float],
    laws: Mapping[str, dict],
    chosen: Mapping[str, str],
    max_nfev: int = 40,
    heldout: bool = True,
) -> OEFit:
    """The joint fit of every run of ``fd`` with the laws ``chosen`` (law name -> law): the
    family of ``par`` with those laws (its parametrization's ``laws``), the shared
    parameters started at ``shared``, each law's coefficients at the law fitted to the
    levels (``laws``)."""
    start = dict(shared)
    for key, law in chosen.items():
        d = laws[key]
        coefs = fit_law(law, d["currents"], d["values"], floored_se(d["values"], d["stderr"]))
        for name, c in zip(law_names(key, d["parameter"], d["slope"], law), LAWS[law], strict=True):
            start[name] = coefs[c]
    lp = _family_par(par, start, dict(par.fixed), chosen)
    return OutputErrorFitter(fd, lp, max_nfev=max_nfev).fit(heldout=heldout)


def staged_fit(
    fd: FitData,
    family_fit: OEFit,
    max_nfev: int = 40,
    heldout: bool = True,
    progress: Callable[[str], None] | None = None,
    shape: str = "shared",
) -> StagedFit:
    """Fit level by level, choose each law by held-out error, refit jointly with them.

    Parameters
    ----------
    fd : FitData
        Every run (at :data:`MIN_STAGED_LEVELS` current levels or more).
    family_fit : OEFit
        The family's joint fit with linear laws (a :class:`FamilyParametrization` fit;
        its optimum starts the 0 A level and the shared parameters of the joint fit).
    max_nfev : int
        Iterations of each fit.
    heldout : bool
        Compute the held-out error (leave one condition out) of the joint fit.
    progress : callable, optional
        Receives progress messages.
    shape : {"shared", "free"}
        The per-level fits hold the shape parameters at the joint fit's values
        (``"shared"``: the values per level are what the joint fit would need at that
        current, the question a law answers) or fit them at every level (``"free"``: the
        seed's flowchart; the shape may then absorb what the current does, see
        :func:`level_fits`).
    """
    par = family_fit.par
    if not isinstance(par, (FamilyParametrization, FamilySystemParametrization)):
        raise HystdiscError(
            "the staged fit starts from a family's own fit; fix: pass a FamilyParametrization fit"
        )
    if set(par.effects) - set(measurement_effects(par.effects)):
        raise HystdiscError(
            "the staged fit works on the family alone (a measurement chain's effect aside); "
            "fix: pass the fit without effects"
        )
    levels, _ = level_runs(fd.currents)
    if levels.size < MIN_STAGED_LEVELS:
        raise HystdiscError(
            f"{levels.size} current level(s): the staged fit needs {MIN_STAGED_LEVELS}; fix: "
            "record runs at more currents"
        )
    fits = level_fits(fd, par, family_fit.params, max_nfev, progress, shape)
    laws, notes = choose_laws(par.family, fits)
    chosen = {k: d["law"] for k, d in laws.items()}
    changed = any(v != "linear" for v in chosen.values())
    linear = family_fit
    if heldout and linear.heldout_rms is None:
        linear = OutputErrorFitter(fd, par, max_nfev=max_nfev).heldout_at(linear)
    if changed:
        if progress:
            progress(
                "staged fit: joint fit with "
                + ", ".join(f"{d['parameter']} {d['law']}" for d in laws.values())
            )
        joint = joint_fit(fd, par, family_fit.params, laws, chosen, max_nfev, heldout)
        h_law, h_lin = joint.heldout_rms, linear.heldout_rms
        if h_law is None or h_lin is None:
            notes.append(
                "the joint fit with the chosen laws was not checked on held-out conditions "
                "(held-out errors off or not available): the laws rest on the levels alone"
            )
        if h_law is not None and h_lin is not None and not h_law < h_lin:
            # the held-out conditions are the judge: a law that does not predict them
            # better than the linear one is not claimed
            proposed = ", ".join(
                f"{d['parameter']} {d['law']}" for d in laws.values() if d["law"] != "linear"
            )
            notes.append(
                f"the joint fit with {proposed} does not predict the held-out conditions "
                f"better than the linear laws (held-out RMS {h_law:.4g} vs {h_lin:.4g}): "
                "the linear laws are kept"
            )
            for d in laws.values():
                d["proposed"] = d["law"]
                d["law"] = "linear"
                d["coefs"] = fit_law(
                    "linear", d["currents"], d["values"], floored_se(d["values"], d["stderr"])
                )
            joint, changed = linear, False
    else:
        joint = linear
    return StagedFit(par.family.name, fits, laws, joint, linear, changed, notes)


def heldout_level(
    fd: FitData,
    family_fit: OEFit,
    laws: Mapping[str, dict],
    chosen: Mapping[str, str],
    level: float,
    max_nfev: int = 40,
) -> float:
    """RMS error on the runs at current ``level`` of the joint fit with the laws ``chosen``
    fitted without them (a current level the laws did not see)."""
    levels, groups = level_runs(fd.currents)
    k = int(np.argmin(np.abs(levels - level)))
    test = groups[k]
    train = [r for r in range(fd.n_runs) if r not in test]
    sub_laws = {}
    for key, d in laws.items():
        keep = [j for j in range(len(d["currents"])) if j != k]
        sub_laws[key] = {
            **d,
            "currents": [d["currents"][j] for j in keep],
            "values": [d["values"][j] for j in keep],
            "stderr": [d["stderr"][j] for j in keep],
        }
    fit = joint_fit(
        fd.subset(train), family_fit.par, family_fit.params, sub_laws, chosen, max_nfev, False
    )
    ref = fd.subset(test)
    e = np.concatenate([(p - ref.y[r])[ref.mask[r]] for r, p in enumerate(predict_runs(fit, ref))])
    return float(np.sqrt(np.mean(e * e)))


def predict_runs(fit: OEFit, fd: FitData) -> list[np.ndarray]:
    """The outputs of ``fit``'s model (any parametrization) simulated on the runs of ``fd``
    (new runs: their initial states start from their first samples)."""
    nu = fd.nuisance_start(fit.par.has_state()).reshape(fd.n_runs, -1)
    runs = list(range(fd.n_runs))
    return fit.par.simulate(fd, [fit.par.model(fit.x)] * fd.n_runs, runs, list(nu))


def levels_start(
    fd: FitData, par: FamilyParametrization, start: Mapping[str, float], max_nfev: int = 20
) -> dict[str, float] | None:
    """A start for the joint fit from the current levels fitted one by one.

    A joint fit can trade one current-dependent parameter against another (a viscous
    slope against a friction slope) and stop in that basin; at one level there is no
    slope to trade. The family is fitted at each level (:func:`level_fits`, the shape held
    at ``start``), a straight line through each law's per-level values (weighted by their
    intervals) gives its passive value and slope. None with fewer than two levels.

    Parameters
    ----------
    fd : FitData
        The runs (at two current levels or more).
    par : FamilyParametrization
        The family's parametrization (its fixed parameters are kept).
    start : mapping
        Where the lowest level starts, and the shape held at every level.
    max_nfev : int
        Iterations of each level's fit.

    Returns
    -------
    dict or None
        ``start`` with each law's passive parameter and slope replaced.
    """
    if level_runs(fd.currents)[0].size < 2:
        return None
    levels = level_fits(fd, par, start, max_nfev)
    out = dict(start)
    i = [lv.current for lv in levels]
    for passive, slope in par.family.current_laws.values():
        if passive not in levels[0].fit.par.names or slope in par.fixed:
            continue
        v = [lv.fit.params[passive] for lv in levels]
        line = fit_law("linear", i, v, floored_se(v, [lv.fit.stderr[passive] for lv in levels]))
        out[passive], out[slope] = line["a"], line["b"]
    return out
