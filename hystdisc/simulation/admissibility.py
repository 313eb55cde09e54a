"""Physical admissibility: a damper dissipates, a spring stiffens the rig, everywhere it may be used.

A fit can reach a lower in-sample error with parameters that make the damper *generate*
energy outside the training data (a negative velocity-squared term makes the force fall
and reverse beyond the velocities it was fitted on). :func:`check_admissible` drives
the damper model through closed sine cycles over a grid that covers twice the training
envelope in displacement and velocity, at currents across the training range, and
reports every cycle in which the damper does net work on the rig (``∮ T dθ < 0``) or
its simulation diverges, and every angle where the rig's spring (``k_s θ`` plus a cubic
term) would soften below zero stiffness.

Examples
--------
>>> from hystdisc.models import Model
>>> from hystdisc.data.envelope import Envelope, RunEnvelope
>>> env = Envelope([RunEnvelope("0", 0.0, 0.3, 2.0, 6.0), RunEnvelope("1", 1.0, 0.3, 2.0, 6.0)])
>>> check_admissible(Model("dahl").to_terms(), env).ok
True
>>> bad = Model("dahl").to_terms()
>>> bad.torque["theta_dot*|theta_dot|"] = -0.5  # a negative quadratic damping
>>> rep = check_admissible(bad, env)
>>> rep.ok, rep.violations[0]
(False, 'the damper generates energy in a cycle of amplitude 0.6 at peak velocity 4 (2x the training velocity), current 0 A')
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from hystdisc.data.envelope import Envelope
from hystdisc.errors import HystdiscError
from hystdisc.models import EFFECTS, TermModel
from hystdisc.simulation.ode import simulate_system
from hystdisc.simulation.runs import simulate_driven_runs

#: The envelope is checked up to this multiple of the training displacement and velocity.
FACTOR = 2.0
#: Cycles simulated per check (the last one is measured, after z has forgotten its start).
CYCLES = 3
#: Samples per cycle.
SAMPLES_PER_CYCLE = 400
#: A cycle's net work counts as generation below ``-REL_TOL`` times its dissipated work.
REL_TOL = 1e-6
#: Torque terms of the rig, not of the damper (conservative: they do no net work).
RIG_TERMS = ("theta", "theta^3", "1")
#: Parameters of the rig, not of the damper, in a system model's values.
RIG_VALUES = ("k_s", "J", "k_3", "theta_off")


@dataclass
class Admissibility:
    """The outcome of :func:`check_admissible`.

    Attributes
    ----------
    ok : bool
        No violation anywhere in the checked envelope.
    violations : list of str
        One sentence per kind of violation, worst first.
    worst_work : float
        Most negative net work per cycle found (0 when none), torque times angle units.
    """

    ok: bool = True
    violations: list[str] = field(default_factory=list)
    worst_work: float = 0.0


def _damper(tm: TermModel) -> TermModel:
    return TermModel(
        {k: v for k, v in tm.torque.items() if k not in RIG_TERMS},
        dict(tm.hysteresis),
        tm.n,
        tm.J,
        tm.m,
        saturation=dict(tm.saturation),
    )


def _spring(model) -> tuple[float, float]:
    """The rig spring's ``k_s`` and cubic ``k_3`` of a term model or a system model."""
    if isinstance(model, TermModel):
        return model.torque.get("theta", 0.0), model.torque.get("theta^3", 0.0)
    _, values = model
    return float(values.get("k_s", 0.0)), float(values.get("k_3", 0.0))


def _driven_torques(model, ts, currents, ths, ws) -> tuple[list[np.ndarray], list[int]]:
    """The damper's torque on imposed sine cycles (status 0: simulated, 1: diverged)."""
    if isinstance(model, TermModel):
        sims, status = simulate_driven_runs(
            _damper(model), ts, currents, ths, ws, raise_on_divergence=False
        )
        return [s.torque for s in sims], list(status)
    system, values = model
    # the damper alone, as a term model's: a structural effect's mount (a spring, dashpot
    # and mass within their bounds) is passive, and its fast mode would only spend the
    # integrator's step budget on the slow cycles
    damper = system.family.system("driven", tuple(e for e in system.effects
                                                  if not EFFECTS[e].structural))  # fmt: skip
    names = {p.name for p in damper.params}
    # the rig's spring and offset are not the damper's (conservative: no net work)
    vals = {k: v for k, v in values.items() if k in names and k not in RIG_VALUES}
    out, status = [], []
    for t, c, th, w in zip(ts, currents, ths, ws, strict=True):
        try:
            y = simulate_system(
                damper,
                t,
                damper.initial_state(),
                vals,
                current=c,
                inputs={"theta": th, "theta_dot": w},
            ).y
            out.append(y)
            status.append(0 if np.all(np.isfinite(y)) else 1)
        except HystdiscError:
            out.append(np.full(t.size, np.nan))
            status.append(1)
    return out, status


def check_admissible(
    terms,
    envelope: Envelope,
    factor: float = FACTOR,
    n_levels: int = 4,
    n_currents: int = 5,
) -> Admissibility:
    """Check a model for energy generation and negative stiffness over ``factor`` times
    the training envelope.

    Parameters
    ----------
    terms : TermModel or (StateSpaceModel, dict)
        The model (damper, rig spring and effects) in term form, or a system family's
        model (:class:`~hystdisc.models.system.FamilySystem`) with its parameter values.
    envelope : Envelope
        The training envelope (:class:`~hystdisc.data.envelope.Envelope`).
    factor : float
        How far beyond the training displacement and velocity to check.
    n_levels : int
        Amplitudes and peak velocities per axis, geometrically spaced from
        ``factor / 2**(n_levels - 1)`` to ``factor`` times the training maximum.
    n_currents : int
        Currents across the training range.

    Returns
    -------
    Admissibility
    """
    out = Admissibility()
    a_max, v_max = envelope.theta_max, envelope.theta_dot_max
    lo, hi = envelope.current_range
    currents = np.unique(np.linspace(lo, hi, n_currents)) if hi > lo else np.array([lo])
    # the spring: k_s + 3 k_3 theta^2 >= 0 for |theta| <= factor * a_max
    ks, k3 = _spring(terms)
    stiff = ks + 3.0 * k3 * (factor * a_max) ** 2
    if ks < 0 or stiff < 0:
        out.violations.append(
            f"the rig spring has negative stiffness ({min(ks, stiff):.3g}) within "
            f"{factor:g}x the training displacement"
        )
    if a_max <= 0 or v_max <= 0:
        out.ok = not out.violations
        return out
    scales = factor / 2.0 ** np.arange(n_levels - 1, -1, -1)
    cases = [(a, v, c) for a in scales for v in scales for c in currents]
    ts, ths, ws = [], [], []
    for a, v, _ in cases:
        amp, vel = a * a_max, v * v_max
        f = vel / (2 * np.pi * amp)
        t = np.linspace(0.0, CYCLES / f, CYCLES * SAMPLES_PER_CYCLE + 1)
        ts.append(t)
        ths.append(amp * np.sin(2 * np.pi * f * t))
        ws.append(vel * np.cos(2 * np.pi * f * t))
    torques, status = _driven_torques(terms, ts, [c for *_, c in cases], ths, ws)
    worst = None
    for (a, v, c), torque, st, t, w in zip(cases, torques, status, ts, ws, strict=True):
        last = slice(-SAMPLES_PER_CYCLE - 1, None)
        p = torque[last] * w[last]
        work = float(np.trapezoid(p, t[last])) if st == 0 else -np.inf
        scale = float(np.trapezoid(np.abs(p), t[last])) if st == 0 else 1.0
        if not work >= -REL_TOL * scale and (worst is None or work < worst[0]):
            worst = (work, a, v, c)
    if worst is not None:
        work, a, v, c = worst
        out.worst_work = work
        where = (
            f"a cycle of amplitude {a * a_max:.3g} at peak velocity {v * v_max:.3g} "
            f"({v:g}x the training velocity), current {c:.3g} A"
        )
        # a cycle whose simulation failed did no measurable work: it is said as such
        what = "the damper generates energy in" if np.isfinite(work) else "the damper diverges in"
        out.violations.insert(0, f"{what} {where}")
    out.ok = not out.violations
    return out
