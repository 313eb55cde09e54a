"""Measured and benchmark data end to end (issue 5); skipped without ``HYSTDISC_DATA``.

The numbers asserted here are the ones reported in ``benchmarks/results/`` (with margins),
so that a regression in loading, discovery or simulation shows.
"""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

from hystdisc.closing.residual import assess_residual
from hystdisc.data import measurement_noise

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
import boucwen_benchmark as bwb  # noqa: E402
import mr_damper as mrd  # noqa: E402


@pytest.fixture(scope="module")
def benchmark_outcome(request):
    data_dir = request.getfixturevalue("data_dir")
    folder = data_dir / "boucwen_benchmark"
    if not folder.is_dir():
        pytest.skip(f"{folder} is missing")
    # Dahl as the rival family keeps the test short; the benchmark script compares all five
    return bwb.run(folder, families=["dahl", "bouc-wen-std"], close_loop=False)


def test_benchmark_selects_standard_bouc_wen(benchmark_outcome):
    d = benchmark_outcome.disc
    assert d.family_ == "bouc-wen-std"
    fits = d.family_fits_
    # reported: 7.36e-6 m against 1.59e-4 m for Dahl
    assert fits["bouc-wen-std"].rms < 7.6e-6
    assert fits["dahl"].rms > 10 * fits["bouc-wen-std"].rms
    # never saturating: z is in newtons (alpha_1 = 1), not normalized to z_sat = 1
    assert fits["bouc-wen-std"].params["alpha_1"] == 1.0


def test_benchmark_parameters_within_one_percent(benchmark_outcome):
    """Reported errors: m +0.02 %, c +0.15 %, k -0.02 %, alpha +0.04 %, beta*gamma -0.28 %,
    beta*delta +0.25 %, nu +0.07 %; the issue asks for 5 %."""
    mapped = benchmark_outcome.mapped
    truth = dict(bwb.TRUE)
    truth["beta*gamma"] = bwb.TRUE["beta"] * bwb.TRUE["gamma"]
    truth["beta*delta"] = bwb.TRUE["beta"] * bwb.TRUE["delta"]
    assert set(mapped) == {"m", "c", "k", "alpha", "beta*gamma", "beta*delta", "nu"}
    for key, value in mapped.items():
        assert value == pytest.approx(truth[key], rel=0.01), key
    # the intervals are reported for every mapped parameter and contain the estimate
    for key, (lo, hi) in benchmark_outcome.ci.items():
        assert lo < mapped[key] < hi, key


def test_benchmark_heldout_period_and_independent_signals(benchmark_outcome):
    """Period 4 predicted from its input alone: reported 2.45e-7 m against the noise-free
    reference and 7.32e-6 m against the measured period (noise floor 7.31e-6 m); a new
    multisine 2.4e-7 m and a 20->50 Hz sweep 1.6e-7 m against the true system."""
    e = benchmark_outcome.errors
    assert e["period 4 vs noise-free reference"] < 1e-6
    floor = e["true system vs measured period 4 (noise floor)"]
    assert 6e-6 < floor < 8.5e-6  # the benchmark's noise, RMS about 7.3e-6 m
    assert e["period 4 vs measured"] < 1.02 * floor
    assert e["new multisine vs true system"] < 1e-6
    assert e["sweep 20-50 Hz vs true system"] < 1e-6


def test_true_benchmark_system_matches_the_record(data_dir):
    """The simulator with a cubic input spline reproduces the benchmark's own generator: the
    residual of the true system is the measurement noise (period-averaged, it halves)."""
    ds = bwb.load_benchmark(data_dir / "boucwen_benchmark")
    u, y = ds.runs[0].input, ds.runs[0].theta
    pred = bwb.steady_state(bwb.true_model(), u[: bwb.PERIOD])
    err = np.array([pred - y[k * bwb.PERIOD : (k + 1) * bwb.PERIOD] for k in range(4)])
    per_period = np.sqrt(np.mean(err**2, axis=1))
    averaged = np.sqrt(np.mean(err.mean(axis=0) ** 2))
    assert np.all(per_period < 7.6e-6)
    # independent noise: averaging 4 periods divides it by 2 (a model error would not shrink)
    assert averaged == pytest.approx(per_period.mean() / 2, rel=0.05)


def test_benchmark_noise_is_measured_from_its_periods(data_dir):
    """Issue 16 item 3: the benchmark's noise is band-limited. High-order differences read
    it 21 % low (5.82e-6 m); the period-to-period differences give 7.39e-6 m, within 1 %
    of the true system's residual (7.34e-6 m). Judged against that noise's own spectrum the
    true system's residual is the noise (with the white test and the difference estimate it
    was "a resonance near 104.4 Hz ... 1.3x the noise"); a 104 Hz tone of 0.2 times the
    noise's RMS added to it is found (p 9e-10)."""
    ds = bwb.load_benchmark(data_dir / "boucwen_benchmark")
    run = ds.runs[0]
    est = measurement_noise(ds.runs, "forced")
    assert est.method == "period" and est.runs[0]["period_samples"] == bwb.PERIOD
    resid = run.theta - np.tile(bwb.steady_state(bwb.true_model(), run.input[: bwb.PERIOD]), 4)
    assert est.std == pytest.approx(bwb.rms(resid), rel=0.03)
    assert est.differences < 0.85 * bwb.rms(resid)
    res, unexplained, _ = assess_residual([resid], run.fs, est.std, noise_samples=est.samples)
    assert res.whiteness_p >= 0.01 and not unexplained
    assert assess_residual([resid], run.fs, est.differences)[1]  # the old verdict
    tone = resid + 0.2 * est.std * np.sqrt(2) * np.sin(2 * np.pi * 104.0 * run.t)
    res, _, _ = assess_residual([tone], run.fs, est.std, noise_samples=est.samples)
    assert res.whiteness_p < 1e-6 and res.dominant_hz == pytest.approx(104.0, abs=1.0)


def test_benchmark_fit_is_judged_against_the_noise(benchmark_outcome):
    """The selected fit's residual is at the period estimate of the noise and has its
    spectrum (the verdict of the closing loop, which adds no effect here)."""
    res = benchmark_outcome.disc.results_
    assert res.noise["method"] == "period"
    assert res.residual.whiteness_test == "noise spectrum"
    assert res.residual.whiteness_p >= 0.01
    assert res.residual.rms_over_noise <= 1.02
    assert res.unexplained is False


def test_predict_starts_a_mid_motion_record_in_its_own_state(benchmark_outcome, data_dir):
    """``hystdisc predict`` on period 4 alone (which starts mid-motion): the initial angle,
    velocity and z are fitted to its first half second, so the prediction matches the
    noise-free steady state (with z = 0 at the start the error was 1.6e-5 m)."""
    ds = bwb.load_benchmark(data_dir / "boucwen_benchmark")
    test = bwb.periods(ds, [3], "period4")
    pred = benchmark_outcome.disc.predict(test)[0]
    ref = bwb.steady_state(bwb.true_model(), test.runs[0].input)
    assert bwb.rms(pred - ref) < 1e-6


# ----------------------------------------------------------------------------- MR damper


def test_mr_damper_trained_on_two_tests_predicts_a_third(data_dir):
    """Discover on 10 mm/1 Hz and 25 mm/0.25 Hz (10 files, 0-1 A, the authors' filter
    declared in the rig file), predict 5 mm/3 Hz: measured (issue 15) spencer selected, fit
    RMS 51.0 N (bouc-wen-std 51.9 N), NRMSE on the unseen test 10.9 % against 21.6 % for
    the Bingham fit of the same run."""
    folder = data_dir / "utfsm_mr_damper"
    if not folder.is_dir():
        pytest.skip(f"{folder} is missing")
    out = mrd.subset_validation(folder)
    assert out["family"] in ("spencer", "bouc-wen-std", "lugre")
    assert out["fit_rms"][out["family"]] < 56.0
    assert out["fit_rms"]["bingham"] > 1.5 * out["fit_rms"][out["family"]]
    assert out["model"][1] < 0.12
    assert out["bingham"][1] > 0.19
    assert out["model"][1] < 0.6 * out["bingham"][1]
