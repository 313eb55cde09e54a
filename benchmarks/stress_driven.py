"""Driven stress suite (issue 33 items 4-5): families x random sets x measurement conditions.

The driven counterpart of ``stress.py``. Every case is one synthetic driven dataset
(imposed sine motion, measured motion and torque) written by ``hystdisc simulate`` and
discovered by ``hystdisc discover`` with default settings (plus ``--rig`` where the
condition declares a prefilter), both in a fresh interpreter on the code beside this file
(``PYTHONPATH`` = this repository); the suite judges ``results.json`` against the truth.

Data of a case
    Sines ``0.2 rad @ 0.5 Hz``, ``0.1 @ 2 Hz``, ``0.05 @ 5 Hz`` (:data:`DRIVES`), each at
    the currents 0, 0.5, 1 A: 9 runs of 4 s at 500 Hz (18 000 samples). Force noise: white,
    Gaussian, ``NOISE_FRAC`` = 1 % of the RMS of the case's noise-free torque over all
    runs (so every family and set has the same signal-to-noise ratio).

Random parameters (:data:`BOUNDS`)
    Every coefficient is log-uniform in ``[0.5x, 2x]`` the family's demo default (the
    ``Param`` default) unless said otherwise. Bouc-Wen shapes as in ``stress.py``: ``beta,
    gamma > 0`` (``z`` saturates), ``n`` uniform in ``[0.5, 2.5]`` (seed form) or ``[1, 3]``
    (standard form, Spencer). A driven damper has no rig spring; the torque may hold a
    spring term (an accumulator, Spencer's ``k1``): the term families' ``k_s``, Spencer's
    ``k1`` and tanh's ``k`` are log-uniform in ``[0.5, 2]`` N*m/rad (0.025-0.4 N*m at the
    amplitudes, a few % of the torque; never 0, so every parameter has a relative error).
    Spencer (MR-like loops, checked by plotting force against velocity, ``--plot-loops``,
    ``benchmarks/results/stress_driven_loops_*.png``): internal dashpot ``c1_a`` in ``[2.5,
    10]`` and ``c1_b`` in ``[1, 4]`` against ``c0_a`` in ``[0.25, 1]``, ``c0_b`` in ``[0.3,
    1.2]`` (c1/c0 between 2.5 and 40, Spencer et al.'s 13.5 inside: the roll-off at low
    velocity), ``k0`` in ``[0.25, 1]``, ``A`` in ``[60, 240]`` 1/rad (``A`` times the
    smallest stroke 0.05 rad is 3-12: the Bouc-Wen element yields within every stroke, a
    plateau; with ``A`` in ``[12, 40]`` it did not and the loops were ellipses) and ``beta``
    in ``[10, 40]`` (so ``gamma = A - beta >= 20``: ``z`` saturates at 1). Tanh: ``beta``
    (inverse yield velocity) in ``[5, 20]`` s/rad (yield at 0.05-0.2 rad/s against peak
    velocities 0.63-1.6 rad/s: a sharp MR knee), ``delta`` in ``[0.25, 1]`` (the branch
    shift, the loop's width).
    A set is *rejected* (the next draw of the same generator taken, the reasons counted)
    when its noise-free torque is not finite, or when any run does not dissipate (the work
    ``-integral T dtheta`` over the last full cycle of the motion is not positive).

Seeds and sets (fixed now, before anything is tuned)
    Set ``k`` of family ``F`` comes from ``np.random.default_rng([SEED, crc32(F), k])``: the
    same set whatever ``--sets``, ``--families`` or their order. The simulation seed of a
    case is ``crc32("F/k/condition")``. **Sets 0-1 are for development** (the pilot runs set
    0 of every family under every condition). Sets 2-9 may be drawn while developing.
    **Sets 10-15 are the acceptance sets** (:data:`ACCEPTANCE_SETS`: 6 sets x 7 families =
    42 cases per condition): *never drawn before the final run*; the script refuses to
    draw them without ``--final``.

Conditions (:data:`CONDITIONS`), each with the 1 % white force noise
    ``white``: nothing else. ``motion``: Gaussian noise of 1e-4 rad on the measured motion
    too. ``enc16``: the motion from a 16-bit displacement sensor, 2^16 counts over its full
    scale +-0.2 rad (``--encoder-counts 1029437``: a step of 6.1e-6 rad). ``delay``: the
    torque channel recorded 3 ms (1.5 samples) late (``--delay 0.003``); the expected answer
    is the family plus the ``channel_delay`` effect with ``tau_d = 0.003``. ``prefilter``:
    both channels passed through a causal moving average of 0.1 of each run's period
    (windows 100, 25 and 10 samples; ``--prefilter period_fraction=0.1``), declared to
    ``discover`` by a rig file with the same ``[filter]`` (the UTFSM damper's preprocessing).

How success is read (issue 33 item 5; :func:`evaluate`): success = all five
    ran
        ``hystdisc simulate`` and ``discover`` exit 0 and ``results.json`` is written.
    family
        The final family is the true one and the loop added exactly the condition's
        expected effects (none; ``channel_delay`` under ``delay``); or the true family is
        named in ``equal_fits`` (the loop's effects as expected) and its held-out error
        agrees with the selected one's within their noise band: ``|h_true - h_selected|
        <= 2 floor / sqrt(2 N_eff)``, two standard errors of an RMS of ``N_eff``
        independent noise samples (``N_eff`` = the samples, over each run's filter window
        under ``prefilter``).
    params
        Every parameter of the true family that the fit flags ``identifiable`` with a
        finite interval (``tau_d`` too under ``delay``) is within :data:`TOL` = 5 % of the
        truth, compared in the family's own normalization (term families: the truth
        mapped through ``from_terms(to_terms(p))``, e.g. Bouc-Wen's ``z_sat = 1``;
        Spencer: ``A = beta + gamma`` as sampled, plus the combinations
        ``Spencer.derived`` reports). A parameter whose *simultaneous* 95 % interval is
        wider than 5 % of the truth (the data cannot tell it to 5 %) is judged at that
        half-width instead (``stress.py``'s data-limited reading) and listed.
    rms
        The held-out error (leave one condition out) is at the floor: ``heldout <= (1 +
        RMS_TOL) floor`` and ``heldout >= (1 - RMS_TOL) s_T`` (``RMS_TOL`` = 10 %; no model
        predicts the force noise, so ``s_T`` alone bounds it from below; without motion
        noise this is ``|heldout / floor - 1| <= 10 %``). ``floor = sqrt(s_T^2 + s_m^2)``:
        ``s_T`` the true force noise as recorded, over the samples the fit's RMS counts
        (``results.json``'s ``runs[].fitted``; under ``prefilter`` the moving average's
        output noise ``s / sqrt(W)`` of each run, weighted by its fitted samples: the
        start of a driven run is left out of the fit until its motion has swept its range
        once, half a period, which takes more of the long-window (low-noise) slow runs, so
        the floor over every sample was 4 % below the noise the fit meets: on
        ``bingham/11/prefilter`` the realized filtered noise is 0.00468 over every sample
        and 0.00489 over the fitted ones, where the fit's RMS is 0.00488), ``s_m`` the
        motion noise propagated into the torque where there is some
        (``motion``, ``enc16``): the RMS change of the *true* model's torque when it is
        driven by the best estimate of the motion from its measurement instead of the exact
        motion (of cubic Savitzky-Golay filters of several windows and a fit of 3 harmonics
        of the drive, the one that changes it least, chosen knowing the truth: a lower bound
        of what such estimates leave, so the floor is not padded; a sign function sampled
        exactly at the reversals, Bingham's, makes it large). The in-sample RMS is recorded
        too.
    ci
        The truth inside the simultaneous 95 % intervals (Bonferroni over the case's
        checked parameters: ``|value - truth| / SE <= z_k``, ``SE`` the 95 % interval's
        half-width / 1.96).
    ``params``, ``rms`` and ``ci`` are judged on the true family's fit: the final model
    when the true family is selected, else that family's entry under ``families``.
    Interval calibration is judged over the suite: the per-parameter coverage of the plain
    95 % intervals (target 0.92-0.98), per condition and per family.

The same reading applied to the release suite's stored results (``--release-reading``):
``benchmarks/results/stress*.json`` hold each case's criteria but not the held-out errors,
so there ``rms`` is the in-sample ``|rms / floor - 1| <= 10 %`` and an equal fit counts
when it names the truth (its held-out agreement cannot be checked from the JSON).

Run (the development pilot, set 0 of every family under every condition: 35 cases):
    nice -n 10 python benchmarks/stress_driven.py --sets 1 --jobs 1 \\
        --out benchmarks/results/stress_driven_pilot.md
The acceptance run (sets 10-15, 210 cases; once, on the code to be accepted):
    nice -n 10 python benchmarks/stress_driven.py --first-set 10 --sets 6 --final \\
        --jobs 1 --out benchmarks/results/stress_driven_acceptance.md
(each writes the markdown and a ``.json`` beside it; finished cases are kept in ``--work``
and not run again; ``--no-run`` re-renders from the JSON).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from stress_common import (
    RMS_TOL,
    TOL,
    draw,
    git_commit,
    hystdisc_cli,
    joint_z,
    judge_parameters,
    kept_record,
    report_header,
    run_cases,
)

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from hystdisc.errors import HystdiscError  # noqa: E402
from hystdisc.models import Model  # noqa: E402
from hystdisc.registry import family_names, get_family  # noqa: E402
from hystdisc.simulation.synth import generate  # noqa: E402

#: Base of every sampler seed.
SEED = 33004
#: Sines (amplitude rad, frequency Hz); every one at every current.
DRIVES = ((0.2, 0.5), (0.1, 2.0), (0.05, 5.0))
CURRENTS = (0.0, 0.5, 1.0)
DURATION = 4.0
FS = 500.0
#: Force noise: this fraction of the RMS of the noise-free torque over all runs.
NOISE_FRAC = 0.01
#: Development sets; the acceptance sets are never drawn before the final run.
DEV_SETS = range(0, 2)
ACCEPTANCE_SETS = range(10, 16)
#: 16 bits over the displacement sensor's full scale +-0.2 rad: counts per turn.
ENC16 = round(2.0 * math.pi * 2**16 / 0.4)
DELAY = 0.003

_SPRING = ("log", 0.5, 2.0)
#: Physical bounds of the sampler: name -> ("log", lo, hi) (log-uniform) or ("uni", lo, hi).
BOUNDS: dict[str, dict[str, tuple[str, float, float]]] = {
    "bingham": {
        "c_a": ("log", 0.4, 1.6),
        "c_b": ("log", 0.3, 1.2),
        "f_a": ("log", 0.15, 0.6),
        "f_b": ("log", 0.5, 2.0),
        "k_s": _SPRING,
    },
    "dahl": {
        "k_x": ("log", 0.4, 1.6),
        "k_wa": ("log", 0.25, 1.0),
        "k_wb": ("log", 0.75, 3.0),
        "rho": ("log", 10.0, 40.0),
        "k_s": _SPRING,
    },
    "lugre": {
        "sigma_a": ("log", 5.0, 20.0),
        "sigma_0": ("log", 15.0, 60.0),
        "sigma_1": ("log", 0.25, 1.0),
        "sigma_2": ("log", 0.25, 1.0),
        "sigma_b": ("log", 0.3, 1.2),
        "a_0": ("log", 1.0 / 3.0, 4.0 / 3.0),
        "k_s": _SPRING,
    },
    "bouc-wen": {
        "alpha_1": ("log", 0.25, 1.0),
        "alpha_2": ("log", 0.75, 3.0),
        "c_1": ("log", 0.25, 1.0),
        "c_2": ("log", 0.3, 1.2),
        "beta": ("log", 5.0, 20.0),
        "gamma": ("log", 5.0, 20.0),
        "delta": ("log", 10.0, 40.0),
        "n": ("uni", 0.5, 2.5),
        "k_s": _SPRING,
    },
    "bouc-wen-std": {
        "alpha_1": ("log", 0.25, 1.0),
        "alpha_2": ("log", 0.75, 3.0),
        "c_1": ("log", 0.25, 1.0),
        "c_2": ("log", 0.3, 1.2),
        "beta": ("log", 2.5, 10.0),
        "gamma": ("log", 7.5, 30.0),
        "delta": ("log", 10.0, 40.0),
        "n": ("uni", 1.0, 3.0),
        "k_s": _SPRING,
    },
    "spencer": {
        "alpha_a": ("log", 0.25, 1.0),
        "alpha_b": ("log", 0.75, 3.0),
        "c0_a": ("log", 0.25, 1.0),
        "c0_b": ("log", 0.3, 1.2),
        "c1_a": ("log", 2.5, 10.0),
        "c1_b": ("log", 1.0, 4.0),
        "k0": ("log", 0.25, 1.0),
        "k1": _SPRING,
        "A": ("log", 60.0, 240.0),
        "beta": ("log", 10.0, 40.0),
        "n": ("uni", 1.0, 3.0),
    },
    "tanh": {
        "c_a": ("log", 0.4, 1.6),
        "c_b": ("log", 0.3, 1.2),
        "alpha_a": ("log", 0.25, 1.0),
        "alpha_b": ("log", 0.75, 3.0),
        "beta": ("log", 5.0, 20.0),
        "delta": ("log", 0.25, 1.0),
        "k": _SPRING,
    },
}
FAMILIES = tuple(f for f in family_names() if f in BOUNDS)

#: Measurement conditions (force noise 1 % of the torque RMS in every one).
CONDITIONS: dict[str, dict] = {
    "white": {"theta_noise": 0.0, "encoder": None, "delay": 0.0, "prefilter": None},
    "motion": {"theta_noise": 1e-4, "encoder": None, "delay": 0.0, "prefilter": None},
    "enc16": {"theta_noise": 0.0, "encoder": ENC16, "delay": 0.0, "prefilter": None},
    "delay": {"theta_noise": 0.0, "encoder": None, "delay": DELAY, "prefilter": None},
    "prefilter": {
        "theta_noise": 0.0,
        "encoder": None,
        "delay": 0.0,
        "prefilter": {"period_fraction": 0.1, "channels": ["theta", "torque"]},
    },
}
#: The effects the loop should add under a condition (none elsewhere).
EXPECTED_EFFECTS = {"delay": ["channel_delay"]}
CRITERIA = ("ran", "family", "params", "rms", "ci")
#: The release suite's stored runs read by ``--release-reading`` (sets 0-7, 8-11, 12-13;
#: the 280 cases of ``stress_notes.md``).
RELEASE_RESULTS = ("stress.json", "stress_unseen.json", "stress_unseen_12_13.json")


# ----------------------------------------------------------------------------- sampling


def _drives() -> list[str]:
    return [f"{a:g}@{f:g}" for a, f in DRIVES]


def driven_data(
    family: str,
    params: dict[str, float],
    noise: float = 0.0,
    seed: int = 0,
    duration: float = DURATION,
    **kw: object,
):
    """The suite's driven dataset of a parameter set (in process; ``kw`` to ``generate``)."""
    return generate(
        Model(family, params),
        "driven",
        currents=CURRENTS,
        duration=duration,
        fs=FS,
        drives=_drives(),
        noise=noise,
        seed=seed,
        **kw,
    )


def driven_check(family: str, params: dict[str, float]) -> tuple[str, float]:
    """Why a set is rejected ("" when it is kept) and the RMS of its noise-free torque."""
    try:
        ds = driven_data(family, params)
    except (HystdiscError, FloatingPointError, OverflowError) as exc:
        return f"diverges ({exc})", math.nan
    torques = [np.asarray(r.torque, dtype=float) for r in ds.runs]
    if not all(np.all(np.isfinite(tq)) for tq in torques):
        return "non-finite torque", math.nan
    for run, (_, f) in zip(ds.runs, [(a, f) for a, f in DRIVES for _ in CURRENTS], strict=True):
        m = int(round(FS / f))  # the last full cycle
        th, tq = run.theta[-m - 1 :], run.torque[-m - 1 :]
        work = float(np.sum(0.5 * (tq[1:] + tq[:-1]) * np.diff(th)))  # dissipated
        if not work > 0:
            return f"does not dissipate (cycle work {work:.3g} at {run.current} A)", math.nan
    return "", float(np.sqrt(np.mean(np.concatenate(torques) ** 2)))


def sample_set(
    family: str, index: int, final: bool = False
) -> tuple[dict[str, float], list[str], float]:
    """Parameter set ``index`` of ``family`` (deterministic), the reasons of the rejected
    draws and the RMS of its noise-free torque. The acceptance sets are refused unless
    ``final`` (module docstring)."""
    if index in ACCEPTANCE_SETS and not final:
        raise ValueError(
            f"set {index} is an acceptance set (never drawn before the final run); pass "
            "final=True (--final) only for that run"
        )
    rng = np.random.default_rng([SEED, zlib.crc32(family.encode()), index])
    rejected: list[str] = []
    for _ in range(100):
        p = {k: draw(rng, s) for k, s in BOUNDS[family].items()}
        why_not, scale = driven_check(family, p)
        if not why_not:
            return p, rejected, scale
        rejected.append(why_not)
    raise RuntimeError(f"{family} set {index}: 100 draws rejected ({rejected[-1]})")


def normalized_truth(family: str, params: dict[str, float]) -> dict[str, float]:
    """The truth in the family's own normalization, as ``results.json`` reports it."""
    fam = get_family(family)
    if fam.is_system:  # sampled in its normalization; plus the combinations it reports
        out = {k: float(v) for k, v in params.items()}
        derived = getattr(fam, "derived", None)
        if derived is not None:
            out.update({k: float(v) for k, v in derived(params).items()})
        return out
    own = {k: v for k, v in params.items() if k != "k_s"}
    out = {k: float(v) for k, v in fam.from_terms(fam.to_terms(own)).items()}
    out["k_s"] = float(params["k_s"])
    return out


# ----------------------------------------------------------------------------- floors


def filtered_noise_factor(windows: list[int], n: int) -> float:
    """RMS of unit white noise through causal moving averages of ``windows`` (one per run
    of ``n`` samples, zero initial state), over all samples: ``sqrt(mean min(k+1, W)/W^2)``."""
    k = np.arange(1, n + 1)
    var = [np.minimum(k, w) / float(w) ** 2 for w in windows]
    return float(np.sqrt(np.mean(np.concatenate(var))))


def prefilter_windows(condition: str) -> list[int]:
    """Each run's moving-average window under ``condition`` (1: none)."""
    filt = CONDITIONS[condition]["prefilter"]
    if filt is None:
        return [1] * (len(DRIVES) * len(CURRENTS))
    if filt.get("window"):
        return [int(filt["window"])] * (len(DRIVES) * len(CURRENTS))
    return [
        max(1, int(round(filt["period_fraction"] * FS / f))) for _, f in DRIVES for _ in CURRENTS
    ]


def _true_torques(family: str, params: dict[str, float], thetas, theta_dots) -> list[np.ndarray]:
    """The true model's torque of each run driven by the given motion."""
    from hystdisc.simulation import simulate_driven_runs, simulate_system

    mdl = Model(family, params)
    t = np.arange(thetas[0].size) / FS
    cur = [c for _ in DRIVES for c in CURRENTS]
    if mdl.family.is_system:
        sys_, values = mdl.system("driven")
        return [
            simulate_system(
                sys_, t, sys_.initial_state(), values, c, {"theta": x, "theta_dot": v}
            ).y
            for c, x, v in zip(cur, thetas, theta_dots, strict=True)
        ]
    sims, _ = simulate_driven_runs(mdl, [t] * len(cur), cur, list(thetas), list(theta_dots))
    return [s.torque for s in sims]


#: Savitzky-Golay windows (samples) tried for the propagated motion noise.
SG_WINDOWS = (5, 9, 15, 21, 31, 45, 61, 91, 121)
#: Harmonics of the drive fitted to each run's motion (the other motion estimate tried).
HARMONICS = 3


def harmonic_motion(t: np.ndarray, theta: np.ndarray, freq: float, k: int = HARMONICS):
    """Least-squares fit of a mean and ``k`` harmonics of ``freq`` to a periodic motion:
    the motion and its (analytic) velocity."""
    om = 2.0 * np.pi * freq * np.arange(1, k + 1)
    arg = np.outer(t, om)
    basis = np.hstack([np.ones((t.size, 1)), np.sin(arg), np.cos(arg)])
    coef, *_ = np.linalg.lstsq(basis, theta, rcond=None)
    a, b = coef[1 : k + 1], coef[k + 1 :]
    return basis @ coef, np.cos(arg) @ (a * om) - np.sin(arg) @ (b * om)


def propagated_motion_noise(
    family: str, params: dict[str, float], case_seed: int, cond: dict, duration: float = DURATION
) -> tuple[float, str]:
    """RMS change of the true torque when the model is driven by the best estimate of the
    motion from its measurement instead of the exact motion, and which estimate that was
    (0 and "" without motion noise). Tried: cubic Savitzky-Golay filters of
    :data:`SG_WINDOWS` samples, and a fit of :data:`HARMONICS` harmonics of the drive's
    frequency (a periodic test's own estimate); the one closest to the truth is kept (a
    lower bound of what such estimates leave)."""
    if not cond["theta_noise"] and not cond["encoder"]:
        return 0.0, ""
    from scipy.signal import savgol_filter

    exact = driven_data(family, params, duration=duration)
    meas = driven_data(
        family,
        params,
        noise=0.0,
        seed=case_seed,
        duration=duration,
        theta_noise=cond["theta_noise"],
        encoder_counts=cond["encoder"],
    )
    ref = np.concatenate([r.torque for r in exact.runs])
    freqs = [f for _, f in DRIVES for _ in CURRENTS]
    estimates = {
        f"savgol {w}": (
            [savgol_filter(r.theta, w, 3, mode="interp") for r in meas.runs],
            [savgol_filter(r.theta, w, 3, deriv=1, delta=1 / FS, mode="interp") for r in meas.runs],
        )
        for w in SG_WINDOWS
    }
    fits = [harmonic_motion(r.t, r.theta, f) for r, f in zip(meas.runs, freqs, strict=True)]
    estimates[f"{HARMONICS} harmonics"] = ([a for a, _ in fits], [b for _, b in fits])
    best = (math.inf, "")
    for label, (ths, ws) in estimates.items():
        tq = np.concatenate(_true_torques(family, params, ths, ws))
        best = min(best, (float(np.sqrt(np.mean((tq - ref) ** 2))), label))
    return best


# ----------------------------------------------------------------------------- one case


@dataclass
class Case:
    """One dataset: a family, a parameter set, a condition."""

    family: str
    index: int
    condition: str
    params: dict[str, float]
    torque_rms: float
    rejected: list[str] = field(default_factory=list)
    #: Record length in s (the suite's; shorter in the tests).
    duration: float = DURATION
    #: ``discover --families`` (None: the default, every family; a subset in the tests).
    families: tuple[str, ...] | None = None

    @property
    def name(self) -> str:
        return f"{self.family}/{self.index}/{self.condition}"

    @property
    def seed(self) -> int:
        return zlib.crc32(self.name.encode()) % 2**31

    @property
    def noise(self) -> float:
        """Force noise std (3 significant digits, as passed to ``--noise``)."""
        return float(f"{NOISE_FRAC * self.torque_rms:.3g}")

    @property
    def force_floor(self) -> float:
        """The force noise as recorded (through the prefilter's windows)."""
        n = int(round(self.duration * FS))
        return self.noise * filtered_noise_factor(prefilter_windows(self.condition), n)

    @property
    def n_eff(self) -> float:
        """Independent noise samples: every sample, over its run's filter window."""
        n = int(round(self.duration * FS))
        return float(sum(n / w for w in prefilter_windows(self.condition)))

    def force_floor_on(self, fitted: list[int] | None) -> float:
        """The force noise as recorded over the samples the fit counts (``fitted``: each
        run's, past the filter's start-up: ``noise / sqrt(W)`` there); every sample
        (:attr:`force_floor`) when not known."""
        if not fitted or len(fitted) != len(prefilter_windows(self.condition)) or not sum(fitted):
            return self.force_floor  # not known, or nothing fitted to weight
        return self.noise * math.sqrt(self.n_eff_on(fitted) / sum(fitted))

    def n_eff_on(self, fitted: list[int] | None) -> float:
        """Independent noise samples among the fitted ones (:attr:`n_eff` when not known)."""
        windows = prefilter_windows(self.condition)
        if fitted is None or len(fitted) != len(windows):
            return self.n_eff
        return float(sum(f / w for f, w in zip(fitted, windows, strict=True)))

    def rig_text(self) -> str | None:
        """The rig file that declares the condition's prefilter (None without one)."""
        filt = CONDITIONS[self.condition]["prefilter"]
        if filt is None:
            return None
        lines = ['experiment = "driven"', "[filter]"]
        for k, v in filt.items():
            lines.append(f"{k} = {json.dumps(v)}")
        return "\n".join(lines) + "\n"

    def simulate_args(self, csv: Path) -> list[str]:
        """The ``hystdisc simulate`` arguments of this case."""
        cond = CONDITIONS[self.condition]
        args = ["simulate", "--model", self.family, "--experiment", "driven"]
        args += ["--set", ",".join(f"{k}={v!r}" for k, v in self.params.items())]
        args += ["--currents", ",".join(f"{c:g}" for c in CURRENTS)]
        for d in _drives():
            args += ["--drive", d]
        args += ["--duration", f"{self.duration:g}", "--fs", f"{FS:g}"]
        args += ["--noise", repr(self.noise), "--seed", str(self.seed)]
        if cond["theta_noise"]:
            args += ["--theta-noise", repr(cond["theta_noise"])]
        if cond["encoder"]:
            args += ["--encoder-counts", str(cond["encoder"])]
        if cond["delay"]:
            args += ["--delay", repr(cond["delay"])]
        if cond["prefilter"]:
            f = cond["prefilter"]
            spec = ",".join(f"{k}={v}" for k, v in f.items() if k != "channels")
            args += ["--prefilter", f"{spec},channels={'+'.join(f['channels'])}"]
        return args + ["-o", str(csv), "--force", "--quiet"]

    def discover_args(self, csv: Path, out: Path, rig: Path | None) -> list[str]:
        """The ``hystdisc discover`` arguments (default settings; the rig when declared)."""
        extra = ["--rig", str(rig)] if rig is not None else []
        if self.families is not None:
            extra += ["--families", ",".join(self.families)]
        return ["discover", str(csv), *extra, "--json", str(out), "--force", "--quiet"]


def _base_record(case: Case) -> dict:
    return {
        "case": case.name,
        "family": case.family,
        "index": case.index,
        "condition": case.condition,
        "seed": case.seed,
        "params_sampled": case.params,
        "rejected_draws": case.rejected,
        "noise": case.noise,
    }


def crash_record(case: Case, error: str) -> dict:
    """The record of a case whose command failed (or wrote no results)."""
    return {
        **_base_record(case),
        "success": False,
        "error": error,
        "criteria": {k: False for k in CRITERIA},
    }


def evaluate(res: dict, case: Case, motion_floor: float = 0.0) -> dict:
    """The five criteria of one case from its ``results.json`` (module docstring);
    ``motion_floor`` is the propagated motion noise ``s_m`` of the floor."""
    truth = normalized_truth(case.family, case.params)
    expected = sorted(EXPECTED_EFFECTS.get(case.condition, []))
    fitted = [r.get("fitted") for r in res.get("runs") or []]
    fitted = fitted if fitted and all(isinstance(f, int) for f in fitted) else None
    s_t = case.force_floor_on(fitted)
    floor = math.hypot(s_t, motion_floor)
    band = 2.0 * floor / math.sqrt(2.0 * case.n_eff_on(fitted))
    final = res.get("final") or {}
    chosen = final.get("family", res.get("family"))
    effects = sorted(
        e if isinstance(e, str) else e.get("name", str(e)) for e in final.get("effects", [])
    )
    equal = list(res.get("equal_fits") or [])
    families = res.get("families") or {}
    failed = res.get("failed") or {}
    effects_ok = effects == expected
    notes: list[str] = []
    if chosen == case.family:
        fit, source = final, "final"
    elif case.family in families:
        fit, source = families[case.family], f"families[{case.family}]"
    else:
        why_gone = failed.get(case.family) if isinstance(failed, dict) else None
        rec = crash_record(
            case,
            f"the true family {case.family} has no fit in results.json"
            + (f" (failed: {why_gone})" if why_gone else ""),
        )
        rec["criteria"]["ran"] = True
        rec.update(selected=chosen, effects=effects, equal_fits=equal, failed=failed)
        return rec
    if "tau_d" in (fit.get("parameters") or {}) and case.condition == "delay":
        truth["tau_d"] = DELAY
    h_true = fit.get("heldout_rms")
    h_sel = final.get("heldout_rms")
    equal_ok = False
    if chosen != case.family and case.family in equal:
        if h_true is not None and h_sel is not None:
            equal_ok = abs(float(h_true) - float(h_sel)) <= band
            notes.append(
                f"equal fit: held-out {float(h_true):.5g} (true) vs {float(h_sel):.5g} "
                f"(selected), band {band:.3g}"
            )
        else:
            notes.append("equal fit without held-out errors to compare")
    family_ok = effects_ok and (chosen == case.family or equal_ok)
    judged = judge_parameters(fit.get("parameters") or {}, truth, TOL)
    zs, zj = judged["z"], judged["zj"]
    heldout_ratio = float(h_true) / floor if h_true is not None else math.nan
    crit = {
        "ran": True,
        "family": family_ok,
        "params": not judged["outside_data"],
        # at most 10 % above the floor; at least 10 % below the force noise alone (no
        # model predicts the force noise; the motion's share is an estimate's, see above)
        "rms": (1.0 - RMS_TOL) * s_t <= heldout_ratio * floor and heldout_ratio <= 1.0 + RMS_TOL,
        "ci": all(z <= zj for z in zs.values()),
    }
    noise = res.get("noise") or {}
    return {
        **_base_record(case),
        "truth": truth,
        "success": all(crit.values()),
        "criteria": crit,
        "selected": chosen,
        "effects": effects,
        "expected_effects": expected,
        "equal_fits": equal,
        "failed": failed,
        "judged_on": source,
        "floor": floor,
        "force_floor": s_t,
        "motion_floor": motion_floor,
        "equal_band": band,
        "rms": float(fit["rms"]) if fit.get("rms") is not None else None,
        "rms_ratio": float(fit["rms"]) / floor if fit.get("rms") is not None else None,
        "heldout_rms": None if h_true is None else float(h_true),
        "heldout_ratio": heldout_ratio,
        "selected_heldout_ratio": None if h_sel is None else float(h_sel) / floor,
        "family_heldout_ratios": {
            k: (None if v.get("heldout_rms") is None else float(v["heldout_rms"]) / floor)
            for k, v in families.items()
        },
        "checked": judged["checked"],
        "skipped_unidentifiable": judged["skipped"],
        "outside_tolerance": judged["outside_tolerance"],
        "outside_data": judged["outside_data"],
        "outside_ci": judged["outside_ci"],
        "data_limited": judged["limited"],
        "z": zs,
        "z_bound": zj,
        "notes": notes,
        "noise_estimate": noise.get("std", res.get("noise_std")),
        "noise_method": noise.get("method"),
        "unexplained": res.get("unexplained"),
    }


def with_fitted(res: dict, case: Case, work: Path) -> dict:
    """``res`` with each run's fitted samples (``runs[].fitted``), which a
    ``results.json`` written before they were recorded lacks: counted from the case's
    data in ``work`` as the fit counts them (:func:`hystdisc.measurement.prepare_data`;
    they depend on the data alone)."""
    runs = res.get("runs") or []
    if not runs or all(isinstance(r.get("fitted"), int) for r in runs):
        return res
    import hystdisc
    from hystdisc.measurement.prepare import prepare_data

    stem = case.name.replace("/", "_")
    rig = work / f"{stem}.rig.toml"
    ds = hystdisc.load(work / f"{stem}.csv", rig=rig if rig.exists() else None)
    _, fd, _, _ = prepare_data(ds)
    counts = {n: int(np.sum(m)) for n, m in zip(fd.names, fd.mask, strict=True)}
    return {**res, "runs": [{**r, "fitted": counts.get(r.get("name"))} for r in runs]}


def run_case(case: Case, work: Path) -> dict:
    """Simulate, discover and evaluate one case (``work`` holds its files)."""
    work.mkdir(parents=True, exist_ok=True)
    stem = case.name.replace("/", "_")
    csv, out = work / f"{stem}.csv", work / f"{stem}.json"
    rig = None
    if case.rig_text() is not None:
        rig = work / f"{stem}.rig.toml"
        rig.write_text(case.rig_text())
    t0 = time.perf_counter()
    if out.exists():
        out.unlink()
    for args in (case.simulate_args(csv), case.discover_args(csv, out, rig)):
        code, err = hystdisc_cli(args, ROOT)
        if code:
            rec = crash_record(case, f"hystdisc {args[0]} exited with {code}: {err}")
            rec["seconds"] = time.perf_counter() - t0
            return rec
    if not out.exists():
        return crash_record(case, "hystdisc discover exited 0 but wrote no results.json")
    s_m, w = propagated_motion_noise(
        case.family, case.params, case.seed, CONDITIONS[case.condition], case.duration
    )
    rec = evaluate(json.loads(out.read_text()), case, s_m)
    rec["motion_estimate"] = w
    rec["seconds"] = time.perf_counter() - t0
    return rec


# ----------------------------------------------------------------------------- report


def _fmt(x: float) -> str:
    return f"{x:.4g}"


def why(rec: dict) -> str:
    """One line: why a case failed."""
    if rec.get("error"):
        return rec["error"]
    c = rec["criteria"]
    parts = []
    if not c["family"]:
        if rec["selected"] != rec["family"]:
            h = rec.get("selected_heldout_ratio")
            parts.append(
                f"family: selected **{rec['selected']}** (held-out "
                f"{'-' if h is None else f'{h:.3g}'}x floor; true family "
                f"{rec['heldout_ratio']:.3g}x)"
            )
        if rec["effects"] != rec["expected_effects"]:
            parts.append(
                f"family: effects {rec['effects'] or 'none'} (expected "
                f"{rec['expected_effects'] or 'none'})"
            )
    if not c["rms"]:
        parts.append(f"rms: held-out {rec['heldout_ratio']:.3g}x floor ({rec['judged_on']})")
    for o in rec["outside_data"]:
        parts.append(
            f"params: {o['name']} {_fmt(o['value'])} vs {_fmt(o['truth'])} ({100 * o['rel']:.1f} %)"
        )
    if not c["ci"]:
        bad = {n: z for n, z in rec["z"].items() if z > rec["z_bound"]}
        parts.append(
            "ci: "
            + ", ".join(f"{n} z={z:.2f}" for n, z in bad.items())
            + f" > {rec['z_bound']:.2f}"
        )
    if rec.get("failed"):
        parts.append(f"(dropped families: {rec['failed']})")
    return "; ".join(parts)


def failed_criteria(rec: dict) -> str:
    """The criteria a case failed, in order (the first that failed decides nothing)."""
    return ", ".join(k for k in CRITERIA if not rec["criteria"].get(k)) or "-"


def _rate(recs: list[dict], key: str | None = None) -> str:
    if not recs:
        return "-"
    ok = sum(r["success"] if key is None else bool(r["criteria"].get(key)) for r in recs)
    return f"{ok}/{len(recs)}"


def coverage(recs: list[dict]) -> tuple[int, int]:
    """(inside, checked) over the plain 95 % intervals of the checked parameters."""
    n = sum(len(r.get("checked", [])) for r in recs)
    out = sum(len(r.get("outside_ci", [])) for r in recs)
    return n - out, n


def _cov(recs: list[dict]) -> str:
    ok, n = coverage(recs)
    return f"{ok}/{n} ({ok / n:.3f})" if n else "-"


def render(records: list[dict], meta: dict) -> str:
    """The markdown report."""
    lines = [
        *report_header(
            "Driven stress suite (issue 33 items 4-5)",
            meta,
            f"{len(records)} cases" + (f" ({meta['note']})" if meta.get("note") else ""),
        ),
        "Each case: `hystdisc simulate --experiment driven` of a random parameter set (sines "
        + ", ".join(f"{a:g} rad @ {f:g} Hz" for a, f in DRIVES)
        + f" at {', '.join(f'{c:g}' for c in CURRENTS)} A; {DURATION:g} s at {FS:g} Hz; "
        f"force noise {100 * NOISE_FRAC:g} % of the torque RMS), then `hystdisc discover` "
        "with default settings (plus `--rig` declaring the prefilter). Definitions in "
        "`benchmarks/stress_driven.py`.",
        "",
        "**Success** = all of: **ran** (both commands exit 0, results.json written); "
        "**family** (the true family selected with exactly the condition's expected effects "
        "— `channel_delay` under `delay`, none elsewhere — or named in `equal_fits` with a "
        "held-out error within 2 standard errors of an RMS of the selected one's); "
        f"**params** (every identifiable parameter within {100 * TOL:.0f} % in the "
        "family's own normalization, or within its simultaneous 95 % half-width where that "
        f"is wider); **rms** (held-out error at most {100 * RMS_TOL:.0f} % above the floor "
        "sqrt(s_T^2 + s_m^2) — s_T the true recorded force noise, s_m the motion noise "
        "propagated through the true model by the best motion estimate where there is some "
        f"— and at least {100 * RMS_TOL:.0f} % below s_T alone); **ci** (the truth inside "
        "the simultaneous — Bonferroni — 95 % intervals). Coverage = the plain 95 % "
        "intervals holding the truth, over every checked parameter (target 0.92-0.98).",
        "",
        "| condition | family | n | success | ran | family | params | rms | ci | coverage |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    conds = [c for c in CONDITIONS if any(r["condition"] == c for r in records)]
    fams = [f for f in FAMILIES if any(r["family"] == f for r in records)]
    for c in conds:
        for f in [*fams, None]:
            rs = [r for r in records if r["condition"] == c and (f is None or r["family"] == f)]
            if not rs:
                continue
            lines.append(
                f"| {c} | {f or '**all**'} | {len(rs)} | {_rate(rs)} | {_rate(rs, 'ran')} | "
                f"{_rate(rs, 'family')} | {_rate(rs, 'params')} | {_rate(rs, 'rms')} | "
                f"{_rate(rs, 'ci')} | {_cov(rs)} |"
            )
    lines += ["", "## Coverage of the plain 95 % intervals", ""]
    lines += ["| over | cases with a fit | coverage |", "|---|---|---|"]
    for label, rs in [
        *[(f"condition {c}", [r for r in records if r["condition"] == c]) for c in conds],
        *[(f"family {f}", [r for r in records if r["family"] == f]) for f in fams],
        ("**suite**", records),
    ]:
        fitted = [r for r in rs if "checked" in r]
        lines.append(f"| {label} | {len(fitted)} | {_cov(fitted)} |")
    lines += ["", "## Every case", ""]
    lines += [
        "| case | outcome | failed criteria | held-out / floor | why |",
        "|---|---|---|---|---|",
    ]
    for r in records:
        hr = r.get("heldout_ratio")
        hr_s = "-" if hr is None or not math.isfinite(hr) else f"{hr:.3f}"
        outcome = "ok" if r["success"] else ("CRASH" if r.get("error") else "fail")
        reason = why(r) if not r["success"] else ""
        lines.append(
            f"| `{r['case']}` | {outcome} | {failed_criteria(r)} | {hr_s} | "
            f"{reason.replace('|', '/')} |"
        )
    lines += ["", "## Parameter sets and rejected draws", ""]
    for f in fams:
        seen = {r["index"]: r for r in records if r["family"] == f}
        for k, r in sorted(seen.items()):
            p = ", ".join(f"{a}={_fmt(b)}" for a, b in r["params_sampled"].items())
            rej = r.get("rejected_draws") or []
            extra = f" — {len(rej)} draw(s) rejected before it: {'; '.join(rej)}" if rej else ""
            lines.append(f"- {f} set {k} (force noise {r.get('noise')}): {p}{extra}")
    secs = [r["seconds"] for r in records if r.get("seconds")]
    if secs:
        lines += [
            "",
            f"Seconds per case: median {np.median(secs):.0f}, max {max(secs):.0f}, "
            f"total {sum(secs):.0f} over {len(secs)} cases run here.",
        ]
    lines.append("")
    return "\n".join(lines)


# ----------------------------------------------------------------------------- release suite


def release_reading(paths: list[Path]) -> str:
    """The issue-33 reading applied to the release suite's stored results (markdown)."""
    recs: list[dict] = []
    for p in paths:
        recs += json.loads(p.read_text())["cases"]
    seen: dict[str, dict] = {}
    for r in recs:  # a case stored twice (a rerun of the same sets) counts once: the last
        seen[r["case"]] = r
    recs = list(seen.values())

    def ok(r: dict) -> dict[str, bool]:
        if r.get("error"):
            return dict.fromkeys(CRITERIA, False)
        c = r["criteria"]
        fam = c["family"] or (r["family"] in (r.get("equal_fits") or []) and not r["effects"])
        return {
            "ran": True,
            "family": bool(fam),
            "params": bool(c["params_data"]),
            "rms": bool(c["rms"]),
            "ci": bool(c["ci_joint"]),
        }

    lines = [
        "| condition | n | success | family (equal fits counted) | params (data limit) "
        "| rms (in-sample) | ci (simultaneous) | coverage (plain 95 %) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    conds = sorted({r["condition"] for r in recs}, key=lambda c: (c != "white", c))
    for c in conds:
        rs = [r for r in recs if r["condition"] == c]
        oks = [ok(r) for r in rs]
        cnt = {k: sum(o[k] for o in oks) for k in CRITERIA}
        succ = sum(all(o.values()) for o in oks)
        lines.append(
            f"| {c} | {len(rs)} | {succ}/{len(rs)} | {cnt['family']} | {cnt['params']} | "
            f"{cnt['rms']} | {cnt['ci']} | {_cov(rs)} |"
        )
    lines += ["", "Misses:", ""]
    for r in recs:
        o = ok(r)
        if all(o.values()):
            continue
        bad = [k for k in CRITERIA if not o[k]]
        zs = {n: z for n, z in r.get("z", {}).items() if z > 2.0}
        bound = joint_z(len(r.get("z", {})))
        lines.append(
            f"- `{r['case']}`: fails {', '.join(bad)}; selected {r.get('selected')}, "
            f"equal fits {r.get('equal_fits')}, effects {r.get('effects')}, RMS "
            f"{r.get('rms_ratio', math.nan):.3f}x floor, outliers found "
            f"{r.get('outliers_found')}; z > 2: "
            + ", ".join(f"{n} {z:.2f}" for n, z in zs.items())
            + f" (simultaneous bound {bound:.2f} for {len(r.get('z', {}))})"
        )
    return "\n".join(lines) + "\n"


# ----------------------------------------------------------------------------- loops


def plot_loops(family: str, indices: list[int], path: Path) -> None:
    """Torque against velocity of the noise-free sets ``indices`` (every drive at 1 A)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(indices), figsize=(4 * len(indices), 3.4), squeeze=False)
    for ax, k in zip(axes[0], indices, strict=True):
        p, _, _ = sample_set(family, k)
        ds = driven_data(family, p)
        for run in ds.runs:
            if run.current == 1.0 or run.current == 0.0:
                half = run.t.size // 2  # the periodic part
                ax.plot(run.theta_dot[half:], run.torque[half:], lw=0.8)
        ax.set_title(f"{family} set {k} (0 and 1 A)", fontsize=9)
        ax.set_xlabel("velocity [rad/s]")
        ax.set_ylabel("torque [N*m]")
    fig.tight_layout()
    fig.savefig(path, dpi=90)
    plt.close(fig)


# ----------------------------------------------------------------------------- command


def build_cases(fams: list[str], conds: list[str], sets: range, final: bool) -> list[Case]:
    """Every case, set by set (a partial run covers every family and condition)."""
    cases = []
    for k in sets:
        for f in fams:
            p, rej, scale = sample_set(f, k, final=final)
            cases += [Case(f, k, c, p, scale, rej) for c in conds]
    return cases


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", type=int, default=1, help="parameter sets per family")
    ap.add_argument("--first-set", type=int, default=0)
    ap.add_argument("--final", action="store_true", help="allow the acceptance sets (10-15)")
    ap.add_argument("--conditions", default=",".join(CONDITIONS))
    ap.add_argument("--families", default=",".join(FAMILIES))
    ap.add_argument("--jobs", type=int, default=1, help="cases run in parallel")
    ap.add_argument("--work", default=None, help="folder of the CSVs and results (kept)")
    ap.add_argument(
        "--out", default=str(ROOT / "benchmarks" / "results" / "stress_driven_pilot.md")
    )
    ap.add_argument("--no-run", action="store_true", help="re-render the markdown from the JSON")
    ap.add_argument(
        "--re-evaluate",
        action="store_true",
        help="judge the cases kept in --work again from their results.json (no new run; "
        "each run's fitted samples counted from its data when the results lack them)",
    )
    ap.add_argument(
        "--release-reading",
        nargs="*",
        metavar="JSON",
        help="print the issue-33 reading of the release suite's stored results and exit",
    )
    ap.add_argument("--plot-loops", metavar="PNG", help="plot sets 0-2 of spencer and tanh")
    args = ap.parse_args(argv)
    if args.release_reading is not None:
        paths = [Path(p) for p in args.release_reading] or [
            ROOT / "benchmarks" / "results" / f for f in RELEASE_RESULTS
        ]
        print(release_reading(paths))
        return 0
    if args.plot_loops:
        import matplotlib.image as mpimg  # noqa: F401 (matplotlib present)

        out = Path(args.plot_loops)
        for f in ("spencer", "tanh"):
            plot_loops(f, [0, 1, 2], out.with_name(f"{out.stem}_{f}{out.suffix}"))
        return 0
    out = Path(args.out)
    if out.suffix != ".md":  # the JSON is written beside it, under the same stem
        ap.error(f"--out {out}: name the markdown file (.md); its .json is written beside it")
    jpath = out.with_suffix(".json")
    t0 = time.time()
    if args.no_run:
        data = json.loads(jpath.read_text())
        out.write_text(render(data["cases"], data["meta"]))
        return 0
    conds = [c.strip() for c in args.conditions.split(",") if c.strip()]
    fams = [f.strip() for f in args.families.split(",") if f.strip()]
    for c in conds:
        if c not in CONDITIONS:
            ap.error(f"unknown condition {c}; use {', '.join(CONDITIONS)}")
    for f in fams:
        if f not in BOUNDS:
            ap.error(f"unknown family {f}; use {', '.join(BOUNDS)}")
    sets = range(args.first_set, args.first_set + args.sets)
    if any(k in ACCEPTANCE_SETS for k in sets) and not args.final:
        ap.error(
            f"sets {ACCEPTANCE_SETS.start}-{ACCEPTANCE_SETS.stop - 1} are the acceptance sets, "
            "never drawn before the final run; pass --final for that run only"
        )
    work = Path(args.work or tempfile.mkdtemp(prefix="hystdisc_stress_driven_"))
    cases = build_cases(fams, conds, sets, args.final)
    print(f"{len(cases)} cases; work folder {work}", flush=True)
    meta = {
        "command": "python benchmarks/stress_driven.py "
        + " ".join(argv if argv is not None else sys.argv[1:]),
        "commit": git_commit(ROOT),
        "when": time.strftime("%Y-%m-%d %H:%M"),
        "drives": DRIVES,
        "currents": CURRENTS,
        "duration": DURATION,
        "fs": FS,
        "noise_frac": NOISE_FRAC,
        "tolerance": TOL,
        "rms_tolerance": RMS_TOL,
        "conditions": {c: CONDITIONS[c] for c in conds},
        "bounds": BOUNDS,
    }
    if args.re_evaluate:
        meta["note"] = "judged again from the results kept in --work: the wall time is the "
        meta["note"] += "judging's; each case's own time is in its record"
    records: list[dict] = []

    def save() -> None:
        meta["wall_s"] = time.time() - t0
        order = {c.name: i for i, c in enumerate(cases)}
        records.sort(key=lambda r: order[r["case"]])
        out.parent.mkdir(parents=True, exist_ok=True)
        jpath.write_text(json.dumps({"meta": meta, "cases": records}, indent=1, default=str))
        out.write_text(render(records, meta))

    def one(case: Case) -> dict:
        done = work / f"{case.name.replace('/', '_')}.record.json"
        rec = kept_record(done)
        res = work / f"{case.name.replace('/', '_')}.json"
        if rec is not None and args.re_evaluate and res.exists():
            s_m, est = propagated_motion_noise(
                case.family, case.params, case.seed, CONDITIONS[case.condition], case.duration
            )
            seconds = rec.get("seconds")
            rec = evaluate(with_fitted(json.loads(res.read_text()), case, work), case, s_m)
            rec.update(motion_estimate=est, seconds=seconds)
            done.write_text(json.dumps(rec, default=str))
        if rec is None:
            rec = run_case(case, work)
            done.write_text(json.dumps(rec, default=str))
        return rec

    def finished(rec: dict, count: int) -> None:
        records.append(rec)
        status = "ok" if rec["success"] else "FAIL " + why(rec)
        print(f"[{count}/{len(cases)}] {rec['case']}: {status}", flush=True)
        save()

    run_cases(cases, one, args.jobs, finished)
    save()
    print(f"wrote {out} and {jpath}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
