"""The measurement, modelled (issue 16 item 3): encoders, period-to-period noise, and the
residual judged against the noise's own spectrum.

Every dataset is made by ``hystdisc simulate`` (a band-limited noise is added here to a
noise-free simulation, since the simulator draws white noise only).
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest
from scipy import signal

from hystdisc.cli import main
from hystdisc.closing.residual import NOISE_RATIO, assess_residual
from hystdisc.data import (
    Dataset,
    Run,
    detect_quantization,
    estimate_noise,
    measurement_noise,
    read_csv,
)
from hystdisc.estimator import Discovery

RELEASE = ["--model", "bouc-wen", "--currents", "0,0.25,0.5,0.75,1", "--seed", "1"]
DRIVEN = [
    "--model", "bouc-wen", "--set", "k_s=0", "--experiment", "driven", "--drive", "0.3@1",
    "--drive", "0.15@2", "--currents", "0,0.5,1", "--duration", "4", "--seed", "3",
]  # fmt: skip
#: Standard deviation of the noise the tests add to the driven torque (N*m).
SIGMA = 0.05


def simulate(tmp_path, *args: str) -> Dataset:
    """``hystdisc simulate ARGS`` into a CSV under ``tmp_path``, read back."""
    path = tmp_path / f"sim{len(list(tmp_path.iterdir()))}.csv"
    assert main(["simulate", *args, "-o", str(path), "--quiet"]) == 0
    return read_csv(path)


def band_limited(n: int, rng: np.random.Generator, std: float = SIGMA) -> np.ndarray:
    """Gaussian noise low-passed to a fifth of the Nyquist frequency (100 Hz at 1 kHz)."""
    b, a = signal.butter(4, 0.2)
    x = signal.lfilter(b, a, rng.normal(size=n + 500))[500:]
    return std * x / x.std()


@pytest.fixture(scope="module")
def driven_band_limited(tmp_path_factory) -> tuple[Dataset, list[np.ndarray]]:
    """Noise-free driven Bouc-Wen (two sines, three currents) plus band-limited torque
    noise of std SIGMA; returns the dataset and each run's noise."""
    clean = simulate(tmp_path_factory.mktemp("driven"), *DRIVEN, "--noise", "0")
    rng = np.random.default_rng(7)
    noises = [band_limited(r.n, rng) for r in clean.runs]
    runs = [
        Run(r.name, r.t, r.theta, r.current, torque=r.torque + e)
        for r, e in zip(clean.runs, noises, strict=True)
    ]
    return Dataset(runs, "driven", "band-limited"), noises


# ----------------------------------------------------------------------------- encoders


@pytest.mark.parametrize("counts", [4096, 2048])
def test_encoder_step_counts_and_floor_detected_exactly(tmp_path, counts):
    """Noise-free release data through an encoder: every run's lattice is found, with the
    exact counts per revolution; the difference estimate reads the deterministic
    quantization error below q/sqrt(12), and the floor is used instead."""
    ds = simulate(tmp_path, *RELEASE, "--noise", "0", "--encoder-counts", str(counts))
    q = 2 * math.pi / counts
    floor = q / math.sqrt(12)
    for r in ds.runs:
        enc = detect_quantization(r.theta, angle=True)
        assert enc is not None, r.name
        assert enc.counts_per_revolution == counts
        assert enc.step == q
        assert enc.floor == pytest.approx(floor, rel=1e-12)
        assert enc.on_lattice == 1.0
        assert abs(enc.offset) < 1e-6 * q
    est = measurement_noise(ds.runs, "release")
    assert est.encoder is not None and est.encoder.counts_per_revolution == counts
    assert est.differences < floor  # today's estimate alone (2.4e-4 < 4.4e-4 in the issue)
    assert est.method == "quantization"
    assert floor <= est.std <= 1.05 * floor
    assert est.to_dict()["quantization_floor"] == pytest.approx(floor, rel=1e-12)


def test_lattice_with_offset_and_glitches_is_found(tmp_path):
    """The zero of the angle need not be a count (an offset of 0.37 q plus 0.1 rad), and a
    few off-lattice glitches (0.05 % of the samples) do not hide the lattice."""
    ds = simulate(tmp_path, *RELEASE, "--noise", "0", "--encoder-counts", "4096")
    q = 2 * math.pi / 4096
    theta = ds.runs[0].theta + 0.1 + 0.37 * q
    theta[::2000] += 5.5 * q  # 3 glitches half a step off the lattice
    enc = detect_quantization(theta, angle=True)
    assert enc is not None and enc.counts_per_revolution == 4096
    off = (0.1 + 0.37 * q) / q % 1.0
    assert enc.offset / q % 1.0 == pytest.approx(off, abs=1e-4)
    assert 0.999 <= enc.on_lattice < 1.0


@pytest.mark.parametrize("noise", ["0", "1e-3"])
def test_floats_are_not_quantized(tmp_path, noise):
    """Noise-free and noisy floats (written with 7 significant digits, a fine decimal
    lattice of its own) are not an encoder: no lattice, no floor."""
    ds = simulate(tmp_path, *RELEASE, "--noise", noise)
    assert all(detect_quantization(r.theta, angle=True) is None for r in ds.runs)
    est = measurement_noise(ds.runs, "release")
    assert est.encoder is None and est.output_quantization is None
    assert est.method == "differences"
    assert est.std == est.differences


def test_release_through_an_encoder_end_to_end(tmp_path):
    """Dahl through a 4096-count encoder: results.json names the encoder and its floor, the
    console report says it, and the fit at the floor is not 'unexplained'."""
    ds = simulate(
        tmp_path,
        *["--model", "dahl", "--currents", "0,0.5,1", "--duration", "3", "--seed", "2"],
        *["--noise", "0", "--encoder-counts", "4096"],
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disc = Discovery(model="dahl").fit(ds)
    res = disc.results_
    floor = 2 * math.pi / 4096 / math.sqrt(12)
    assert res.encoder["counts_per_revolution"] == 4096
    assert res.encoder["step"] == pytest.approx(2 * math.pi / 4096, rel=1e-9)  # JSON digits
    assert res.encoder["floor"] == pytest.approx(floor, rel=1e-9)
    assert res.noise_std >= floor
    assert "Encoder: 4096 counts per revolution" in res.report()
    assert res.residual.rms_over_noise <= NOISE_RATIO
    assert res.unexplained is False


# ----------------------------------------------------------------------------- periods


def test_periodic_driven_noise_from_period_differences(tmp_path):
    """Driven sines repeat every 1000 (1 Hz) and 500 (2 Hz) samples: the period is found
    and the torque noise (white, std SIGMA) is estimated within 10 %."""
    ds = simulate(tmp_path, *DRIVEN, "--noise", str(SIGMA))
    est = measurement_noise(ds.runs, "driven")
    assert est.method == "period"
    assert sorted({r["period_samples"] for r in est.runs}) == [500, 1000]
    assert est.std == pytest.approx(SIGMA, rel=0.1)
    assert all(r["period"] == pytest.approx(SIGMA, rel=0.1) for r in est.runs)


def test_band_limited_noise_from_period_differences(driven_band_limited):
    """Band-limited noise (0-100 Hz at 1 kHz) is invisible to high-order differences (they
    read 0.4 % of it) but not to period-to-period differences (within 10 %)."""
    ds, noises = driven_band_limited
    est = measurement_noise(ds.runs, "driven")
    assert est.method == "period"
    assert est.std == pytest.approx(SIGMA, rel=0.1)
    assert est.differences < 0.1 * SIGMA
    assert np.median([estimate_noise(r.torque) for r in ds.runs]) == est.differences
    assert len(est.samples) == len(ds.runs)


def test_band_limited_noise_is_not_structure(driven_band_limited):
    """The true model's residual is the band-limited noise itself: judged against the
    noise's own spectrum it is the noise, not 'unexplained' (against white noise and the
    difference estimate, as before, it was); a 60 Hz tone added to it is found."""
    ds, noises = driven_band_limited
    est = measurement_noise(ds.runs, "driven")
    fs = ds.runs[0].fs
    res, unexplained, _ = assess_residual(noises, fs, est.std, noise_samples=est.samples)
    assert res.whiteness_test == "noise spectrum"
    assert res.whiteness_p >= 0.01 and not unexplained
    assert res.ljung_box_p < 1e-10  # coloured: Ljung-Box alone calls it structure
    assert assess_residual(noises, fs, est.differences)[1] is True  # the old verdict
    tone = [
        e + SIGMA * np.sin(2 * np.pi * 60.0 * r.t) for e, r in zip(noises, ds.runs, strict=True)
    ]
    res, unexplained, text = assess_residual(tone, fs, est.std, noise_samples=est.samples)
    assert unexplained and res.dominant_hz == pytest.approx(60.0, abs=2.0)
    assert "noise's own spectrum" in text


def test_driven_band_limited_end_to_end(driven_band_limited):
    """The declared Bouc-Wen on the band-limited set: the noise is estimated from the
    periods, the residual is judged against its spectrum, and nothing is 'unexplained'."""
    ds, _ = driven_band_limited
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disc = Discovery(model="bouc-wen").fit(ds)
    res = disc.results_
    assert res.noise["method"] == "period"
    assert res.noise_std == pytest.approx(SIGMA, rel=0.1)
    assert res.encoder is None
    assert res.residual.whiteness_test == "noise spectrum"
    assert res.residual.rms_over_noise <= NOISE_RATIO
    assert res.unexplained is False
    assert "period-to-period differences" in res.report()


# ------------------------------------------------- cycle-to-cycle repeatability (issue 35)

#: Sines whose periods are no whole number of samples (769.2 and 370.4 at 1 kHz), as on
#: every measured record.
DRIVEN_OFF_GRID = [
    "--model", "bouc-wen", "--set", "k_s=0", "--experiment", "driven", "--drive", "0.3@1.3",
    "--drive", "0.15@2.7", "--currents", "0,0.5,1", "--duration", "4", "--seed", "3",
]  # fmt: skip


def moving_average(n: int, rng: np.random.Generator, width: int = 15) -> np.ndarray:
    """White noise through a moving average of ``width`` samples (how the UTFSM records
    were filtered before they were stored), scaled to std SIGMA."""
    x = np.convolve(rng.normal(size=n + width), np.ones(width) / width, mode="valid")[:n]
    return SIGMA * x / x.std()


@pytest.fixture(scope="module")
def off_grid_filtered(tmp_path_factory) -> Dataset:
    clean = simulate(tmp_path_factory.mktemp("offgrid"), *DRIVEN_OFF_GRID, "--noise", "0")
    rng = np.random.default_rng(11)
    runs = [
        Run(r.name, r.t, r.theta, r.current, torque=r.torque + moving_average(r.n, rng))
        for r in clean.runs
    ]
    return Dataset(runs, "driven", "moving average")


def test_off_grid_white_noise_from_cycles(tmp_path):
    """No period of whole samples: the period estimate finds none, the cycles aligned on
    the motion give the white noise within 10 % on every run."""
    ds = simulate(tmp_path, *DRIVEN_OFF_GRID, "--noise", str(SIGMA))
    est = measurement_noise(ds.runs, "driven")
    assert est.method == "cycles"
    assert all(r["period"] is None for r in est.runs)
    assert all(r["cycles"] == pytest.approx(SIGMA, rel=0.1) for r in est.runs)
    assert est.pooled == pytest.approx(SIGMA, rel=0.1)
    assert "cycle-to-cycle repeatability" in est.describe()


def test_filtered_record_floor_from_cycles(off_grid_filtered):
    """A record filtered before it was stored: differences of neighbouring samples read a
    small fraction of the noise (the old 'noise' on the UTFSM set), the cycles read it."""
    est = measurement_noise(off_grid_filtered.runs, "driven")
    assert est.method == "cycles"
    assert est.std == pytest.approx(SIGMA, rel=0.1)
    assert est.differences < 0.2 * SIGMA
    assert len(est.samples) == len(off_grid_filtered.runs)


def test_filtered_record_true_model_is_at_the_floor(off_grid_filtered):
    """The declared true model on the filtered off-grid set: its residual is at the
    repeatability floor and nothing is 'unexplained' (judged by the differences, its
    residual was several times 'the noise' and called structure)."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        disc = Discovery(model="bouc-wen").fit(off_grid_filtered)
    res = disc.results_
    assert res.noise["method"] == "cycles"
    assert res.residual.rms_over_noise <= NOISE_RATIO
    assert res.unexplained is False
    assert res.residual.rms / res.noise["differences"] > 5  # what the old floor said


def test_difference_estimate_is_said_to_be_a_fallback():
    t = np.arange(3000) / 1000.0
    rng = np.random.default_rng(0)
    theta = 0.3 * np.exp(-t) * np.cos(2 * np.pi * 1.5 * t) + rng.normal(0, 1e-4, t.size)
    est = measurement_noise([Run("0", t, theta, 0.0)], "release")
    assert est.method == "differences" and est.pooled is None
    assert "a fallback: no run repeats" in est.describe()
