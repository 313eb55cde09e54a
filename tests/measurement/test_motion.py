"""Errors in the imposed motion (issue 33 item 3): a driven test measures its motion too.

The motion's noise is estimated per run, a periodic run's motion is a least-squares
harmonic series (a motion that does not repeat: local seventh-order fits), and the motion
estimate's errors enter the intervals (``hystdisc/fitting/motion_error.py``). Every dataset
is made by the package's simulator with a fixed seed; the truth is the simulated one.
"""

from __future__ import annotations

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from hystdisc.data import Dataset, Run
from hystdisc.data.motion import fit_harmonics, motion_noise
from hystdisc.data.rigs import normalize_rig
from hystdisc.estimator import Discovery
from hystdisc.fitting import FamilyParametrization, OutputErrorFitter
from hystdisc.measurement.chain import causal_average
from hystdisc.measurement.prepare import prepare_data
from hystdisc.models import Model
from hystdisc.simulation.runs import simulate_driven_runs
from hystdisc.simulation.synth import generate

#: Issue 33's command: ``hystdisc simulate --model bouc-wen-std --experiment driven --set
#: ... --currents 0,0.5,1 --drive 0.2@0.5 --drive 0.1@2 --drive 0.05@5 --duration 4 --fs
#: 500 --noise 0.03 --theta-noise 1e-4 --seed 11``.
ISSUE = dict(alpha_1=0.8, alpha_2=2.0, c_1=0.3, c_2=0.9, beta=6, gamma=14, delta=20, n=1.5, k_s=0)
DRIVES = ("0.2@0.5", "0.1@2", "0.05@5")
DAHL = dict(k_x=0.8, k_wa=0.5, k_wb=1.5, rho=20.0, k_s=0.2)


def issue_data(theta_noise: float = 1e-4, seed: int = 11, model=None) -> Dataset:
    """Issue 33's driven set (or another model's on the same drives)."""
    return generate(
        Model("bouc-wen-std", ISSUE) if model is None else model,
        "driven",
        currents=(0.0, 0.5, 1.0),
        duration=4.0,
        fs=500.0,
        noise=0.03,
        seed=seed,
        drives=DRIVES,
        theta_noise=theta_noise,
    )


def ramped(model: Model, theta_noise: float, force_noise: float, seed: int) -> Dataset:
    """The same drives with each amplitude ramped in over the first second: not periodic."""
    rng = np.random.default_rng(seed)
    t = np.arange(2000) / 500.0
    g = np.where(t < 1.0, 0.5 * (1 - np.cos(np.pi * t)), 1.0)
    dg = np.where(t < 1.0, 0.5 * np.pi * np.sin(np.pi * t), 0.0)
    cases = [
        (a, 2 * np.pi * f, c) for a, f in ((0.2, 0.5), (0.1, 2), (0.05, 5)) for c in (0, 0.5, 1)
    ]
    ths = [a * g * np.sin(om * t) for a, om, _ in cases]
    ws = [a * (dg * np.sin(om * t) + g * om * np.cos(om * t)) for a, om, _ in cases]
    sims, _ = simulate_driven_runs(model, [t] * 9, [c for *_, c in cases], ths, ws)
    runs = [
        Run(
            str(k),
            t,
            th + theta_noise * rng.standard_normal(t.size),
            c,
            torque=s.torque + force_noise * rng.standard_normal(t.size),
            theta_dot=w,
        )
        for k, ((*_, c), s, th, w) in enumerate(zip(cases, sims, ths, ws, strict=True))
    ]
    return Dataset(runs, "driven", "ramped")


def gain(estimate: np.ndarray, truth: np.ndarray, skip: int = 100) -> float:
    """Least-squares gain of an estimated velocity against the true one."""
    e, w = estimate[skip:-skip], truth[skip:-skip]
    return float(e @ w / (w @ w))


@pytest.fixture(scope="module")
def issue_fit() -> Discovery:
    """The declared standard Bouc-Wen fitted to issue 33's set."""
    with threadpool_limits(limits=1):
        return Discovery(model="bouc-wen-std", close_loop=False, heldout=False).fit(issue_data())


def test_issue_command_intervals_cover_the_truth(issue_fit):
    """Before: c_1, c_2, delta and k_s had the truth outside their 95 % intervals (the
    smoothed velocity was attenuated by 0.33 % at 5 Hz)."""
    fit = issue_fit.final_fit_
    for name, value in ISSUE.items():
        lo, hi = fit.ci95[name]
        assert lo <= value <= hi, (name, value, lo, hi)


def test_motion_noise_is_reported(issue_fit):
    rec = issue_fit.results_.to_dict()["motion_noise"]
    assert abs(rec["std"] / 1e-4 - 1) < 0.1
    assert rec["method"] == "cycle-to-cycle"
    assert set(rec["runs"]) == {r.name for r in issue_data().runs}
    assert all(abs(v / 1e-4 - 1) < 0.1 for v in rec["runs"].values())
    assert {e["estimate"] for e in rec["estimates"].values()} == {"harmonic"}
    assert "Motion noise: " in issue_fit.results_.report()


def test_a_harmonic_run_keeps_its_start_up_out_of_the_residual():
    """The unknown initial z: a driven run's residual starts once the motion has swept its
    range (the series has no one-sided ends to trim, the start-up still goes)."""
    _, fd, _, _ = prepare_data(issue_data())
    for k in range(fd.n_runs):
        th = fd.theta[k]
        travel = np.concatenate([[0.0], np.cumsum(np.abs(np.diff(th)))])
        assert np.array_equal(fd.mask[k], travel >= np.ptp(th))


def test_release_data_have_no_motion_noise():
    _, fd, _, _ = prepare_data(generate("dahl", currents=(0, 1), duration=2.0, seed=1))
    assert fd.motion_noise is None and fd.motion_errors is None


def test_harmonic_velocity_is_unbiased():
    """The 5 Hz runs' velocity as the fit sees it: the smoother passed 0.9967 of it."""
    ds = issue_data()
    _, fd, _, _ = prepare_data(ds)
    for k in (6, 7, 8):  # 0.05 rad at 5 Hz
        assert abs(gain(fd.theta_dot[k], ds.runs[k].theta_dot) - 1) < 1e-4
    _, old, _, _ = prepare_data(ds, motion="legacy")
    assert {e["estimate"] for e in old.motion_noise.estimates.values()} == {"smoother"}
    assert abs(gain(old.theta_dot[6], ds.runs[6].theta_dot) - 1) > 2e-3


def test_motion_noise_of_a_quantized_motion():
    """A 16-bit displacement: a lattice too fine to be recognized, whose error reads as
    white noise (and, at a whole-sample period, repeats every cycle, so the cycles do not
    show it: the differences do). The harmonic series still fits every run. A coarse
    lattice (10 bits) is recognized on the large runs: its floor is their noise."""
    clean = issue_data(theta_noise=0.0)
    span = float(np.ptp(np.concatenate([r.theta for r in clean.runs])))
    q = span / 2**16
    runs = [
        Run(r.name, r.t, q * np.round(r.theta / q), r.current, torque=r.torque) for r in clean.runs
    ]
    _, fd, _, _ = prepare_data(Dataset(runs, "driven", "16-bit"))
    actual = np.sqrt(
        np.mean(
            np.concatenate([r.theta - c.theta for r, c in zip(runs, clean.runs, strict=True)]) ** 2
        )
    )
    assert abs(fd.motion_noise.std / actual - 1) < 0.1
    assert {e["estimate"] for e in fd.motion_noise.estimates.values()} == {"harmonic"}
    q = span / 2**10
    for r in clean.runs[:3]:  # 0.2 rad: 1024 levels
        est = motion_noise(r.t, q * np.round(r.theta / q))
        assert est.method == "quantization" and est.std == pytest.approx(q / np.sqrt(12))


def test_a_ramped_motion_falls_back_to_local_fits():
    model = Model("dahl", DAHL)
    ds = ramped(model, 1e-4, 0.03, seed=5)
    _, fd, _, _ = prepare_data(ds)
    est = fd.motion_noise.estimates
    assert {e["estimate"] for e in est.values()} == {"local"}
    assert all("times the motion noise" in e["note"] for e in est.values())
    for k in (6, 7, 8):  # the 5 Hz runs, after the ramp
        w = fd.theta_dot[k]
        assert abs(gain(w[600:], ds.runs[k].theta_dot[600:], 50) - 1) < 5e-4
    assert "local" in fd.motion_noise.describe()


def test_harmonic_modes_match_the_spread_of_refits():
    """The modes' variance of the velocity equals the variance of the series' velocity over
    noise draws (coefficients and fundamental refitted each time)."""
    t = np.arange(1000) / 500.0
    x0 = 0.05 * np.sin(2 * np.pi * 5.0 * t + 0.3) + 0.004 * np.sin(2 * np.pi * 15.0 * t)
    rng = np.random.default_rng(3)
    s = 1e-4
    draws = []
    for _ in range(200):
        h = fit_harmonics(t, x0 + rng.normal(0, s, t.size), s)
        draws.append(h.evaluate()[1][[0, 137, 500, 999]])
    h = fit_harmonics(t, x0 + rng.normal(0, s, t.size), s)
    assert h.harmonics == (1, 3)
    predicted = np.sum(h.error_modes()[1][[0, 137, 500, 999]] ** 2, axis=1)
    ratio = np.var(np.array(draws), axis=0, ddof=1) / predicted
    assert np.all((ratio > 0.75) & (ratio < 1.33)), ratio


def _z_rms(ds_list, propagate: bool) -> float:
    """RMS over draws and parameters of (estimate - truth) / SE of the declared Dahl fit."""
    zs = []
    with threadpool_limits(limits=1):
        for ds in ds_list:
            _, fd, _, _ = prepare_data(ds, motion_errors=propagate)
            assert (fd.motion_errors is not None) == propagate
            fit = OutputErrorFitter(fd, FamilyParametrization("dahl", "driven", DAHL)).fit(
                heldout=False
            )
            zs += [(fit.params[k] - v) / fit.stderr[k] for k, v in DAHL.items()]
    return float(np.sqrt(np.mean(np.square(zs))))


def test_motion_errors_enter_the_intervals():
    """Where the motion's errors dominate (motion noise 1e-3 rad, force noise 1e-4), the
    intervals from the force residual alone are ten times too narrow; with the motion
    estimate's errors propagated the z-scores have unit RMS."""
    model = Model("dahl", DAHL)
    data = [
        generate(model, "driven", (0, 0.5, 1), 4.0, 500.0, noise=1e-4, seed=60 + d,
                 drives=DRIVES, theta_noise=1e-3)
        for d in range(6)
    ]  # fmt: skip
    assert _z_rms(data, propagate=False) > 4.0
    assert 0.6 < _z_rms(data, propagate=True) < 1.5


def test_a_filtered_motion_is_the_filters_reconstruction():
    """A rig that declares a filter on the motion: the fit's motion is the reconstruction
    of the motion before it; the filter hides the motion's noise, whose errors are then
    reported, not propagated."""
    clean = issue_data(theta_noise=0.0)
    rng = np.random.default_rng(4)
    runs = [
        Run(
            r.name,
            r.t,
            causal_average(r.theta + rng.normal(0, 1e-4, r.t.size), 50),
            r.current,
            torque=causal_average(r.torque, 50),
        )
        for r in clean.runs
    ]
    filt = normalize_rig({"filter": {"window": 50, "channels": ["theta", "torque"]}}, "rig")
    _, fd, _, _ = prepare_data(Dataset(runs, "driven", "filtered", filt["filter"]))
    assert [e.method for e in fd.motion_errors] == ["filter"] * 9
    assert fd.motion_errors[8].modes()[1].shape == (2000, 0)
    assert all("not propagated" in e["note"] for e in fd.motion_noise.estimates.values())
    assert np.array_equal(fd.theta_dot[8], fd.motion_errors[8].theta_dot)


def _dahl_errors(monkeypatch, theta_noise: float, force_noise: float, pilot: int):
    """The declared Dahl fit of a ramped (local-fit) set: its standard errors and what
    the motion covariance reported, with ``pilot`` draws propagated first."""
    import hystdisc.fitting.intervals as intervals
    import hystdisc.fitting.motion_error as motion_error

    monkeypatch.setattr(motion_error, "PILOT_DRAWS", pilot)
    seen = []

    def spy(*args, **kwargs):
        out = motion_error.motion_covariance(*args, **kwargs)
        seen.append(out)
        return out

    monkeypatch.setattr(intervals, "motion_covariance", spy)
    ds = ramped(Model("dahl", DAHL), theta_noise, force_noise, seed=5)
    with threadpool_limits(limits=1):
        _, fd, _, _ = prepare_data(ds)
        fit = OutputErrorFitter(fd, FamilyParametrization("dahl", "driven", DAHL)).fit(
            heldout=False
        )
    return np.array([fit.stderr[k] for k in DAHL]), seen[-1]


def test_negligible_motion_errors_are_settled_by_the_pilot_draws(monkeypatch):
    """Motion noise 1e-7 rad under force noise 0.03: ten draws of each run show that the
    motion's part is negligible and the other 90 are not simulated; the standard errors
    are those of all 100 draws to 1e-4."""
    full, every = _dahl_errors(monkeypatch, 1e-7, 0.03, pilot=100)
    fast, pilot = _dahl_errors(monkeypatch, 1e-7, 0.03, pilot=10)
    assert every.modes == 900  # (the pilot is every draw)
    assert pilot.pilot and pilot.modes == 90
    assert np.max(np.abs(fast / full - 1)) < 1e-4


def test_motion_errors_that_matter_are_propagated_in_full(monkeypatch):
    """Motion noise 1e-3 rad under force noise 1e-4 (the motion dominates): the pilot is
    not decisive, every draw is propagated and the intervals are the same to the bit."""
    full, every = _dahl_errors(monkeypatch, 1e-3, 1e-4, pilot=100)
    fast, pilot = _dahl_errors(monkeypatch, 1e-3, 1e-4, pilot=10)
    assert not pilot.pilot and pilot.modes == every.modes == 900
    assert np.array_equal(fast, full)
