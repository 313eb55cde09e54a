"""The measurement chain (issue 15 items 2c and 4): a delay between the channels, found
by the closing loop, and filters applied to the data before they reached hystdisc.

Every dataset is simulated here with the package's simulator: driven bouc-wen-std on a
sine grid of three amplitudes/frequencies at three currents, 2 s at 1 kHz, force noise 1 %
of the force's spread.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest

from hystdisc.cli import main
from hystdisc.closing import EffectSkipped, candidate_effects
from hystdisc.data import Dataset, Run
from hystdisc.discovery import FAMILY_SHAPE
from hystdisc.estimator import Discovery
from hystdisc.measurement.chain import (
    average_response,
    causal_average,
    delayed,
    smoothly_delayed,
    unfiltered_motion,
)
from hystdisc.models import TermModel
from hystdisc.models.model import Model
from hystdisc.results.records import TermModelRecord, term_model_from_dict, term_model_to_dict
from hystdisc.simulation.synth import generate

FAMILY = "bouc-wen-std"
TRUTH = {
    "alpha_1": 0.4,
    "alpha_2": 1.2,
    "c_1": 0.3,
    "c_2": 0.5,
    "beta": 4.0,
    "gamma": 12.0,
    "n": 2.0,
    "k_s": 50.0,
}
DRIVES = ["0.2@1.0", "0.3@2.0", "0.15@3.0"]
CURRENTS = (0.0, 0.5, 1.0)
DELAY = 0.003  # s: three samples at 1 kHz


def _data(delay: float, noise: float, seed: int = 1) -> Dataset:
    return generate(
        Model(FAMILY, TRUTH),
        "driven",
        currents=CURRENTS,
        duration=2.0,
        fs=1000.0,
        drives=DRIVES,
        noise=noise,
        seed=seed,
        delay=delay,
    )


@cache
def _noise() -> float:
    clean = _data(0.0, 0.0)
    return 0.01 * float(np.median([np.std(r.torque) for r in clean]))


@cache
def _discover(delay: float) -> Discovery:
    data = _data(delay, _noise())
    return Discovery(model=FAMILY, heldout=False, shapes=(FAMILY_SHAPE[FAMILY],)).fit(data)


# ----------------------------------------------------------------------------- delay


def test_delay_is_found_by_the_loop():
    disc = _discover(DELAY)
    noise = _noise()
    assert disc.effects_ == ["channel_delay"], disc.results_.effects_tried
    (entry,) = disc.results_.effects
    tau = entry["parameters"]["tau_d"]
    assert abs(tau["value"] - DELAY) < 0.5e-3
    assert tau["ci95"][0] < tau["value"] < tau["ci95"][1]
    # the residual was clearly above the noise before, at the noise after
    assert entry["rms_before"] > 1.05 * noise
    assert abs(disc.final_fit_.rms / noise - 1.0) < 0.1
    # the final model carries the delay (predict and results.json use it)
    tm = disc.results_.term_model()
    assert tm.delay == pytest.approx(tau["value"], rel=1e-6)
    assert disc.final_fit_.term_model.delay == pytest.approx(tau["value"])


def test_no_delay_is_not_claimed():
    disc = _discover(0.0)
    assert "channel_delay" not in disc.effects_
    assert disc.effects_ == []
    assert abs(disc.final_fit_.rms / _noise() - 1.0) < 0.1
    # it was a candidate and was scored, with no evidence
    scored = {c["name"]: c for c in disc.results_.diagnosis[0]["candidates"]}
    assert scored["channel_delay"]["evidence"] < 1e-3


def test_delay_candidate_for_two_channel_experiments_only():
    disc = _discover(0.0)
    fit = disc.family_fits_[FAMILY]
    cands, _ = candidate_effects(fit, disc.fit_data_)
    assert "channel_delay" in cands
    release = generate(Model("dahl"), currents=(0.0, 1.0), duration=1.0, seed=2)
    rd = Discovery(model="dahl", heldout=False, shapes=(FAMILY_SHAPE["dahl"],)).fit(release)
    cands, skipped = candidate_effects(rd.family_fits_["dahl"], rd.fit_data_)
    assert "channel_delay" not in cands
    assert EffectSkipped("channel_delay", "a release experiment records one channel") in skipped


def test_delayed_is_a_fractional_shift():
    t = np.arange(200) * 1e-3
    y = np.sin(2 * np.pi * 2.0 * t)
    out = delayed(t, y, 0.0025)
    want = np.sin(2 * np.pi * 2.0 * (t - 0.0025))
    assert np.abs(out - want)[3:].max() < 1e-4  # linear interpolation at 500 samples/cycle
    assert delayed(t, y, 0.0) is y


@pytest.mark.parametrize("uneven", [False, True])
def test_smoothly_delayed_keeps_a_sine_half_a_sample_late(uneven):
    # a 5 Hz motion at 500 Hz, 1.5 samples late (the driven suite's delay condition):
    # linear interpolation shrinks it by (w dt)^2 / 8 = 4.9e-4 of its amplitude between
    # samples, several standard errors of a fitted parameter; the cubic keeps it to 1e-6
    t = np.arange(2000) / 500.0
    if uneven:
        t = t + 2e-4 * np.sin(np.arange(2000))
    w = 2 * np.pi * 5.0
    want = np.sin(w * (t - 0.003))
    inner = slice(4, -4)
    lin = np.abs(delayed(t, np.sin(w * t), 0.003) - want)[inner].max()
    cub = np.abs(smoothly_delayed(t, np.sin(w * t), 0.003) - want)[inner].max()
    assert lin > 4e-4
    assert cub < 1e-6
    # held outside the record, as the linear shift does; no delay is the signal itself
    y = np.sin(w * t)
    assert smoothly_delayed(t, y, 0.003)[0] == y[0]
    assert smoothly_delayed(t, y, -0.003)[-1] == y[-1]
    assert smoothly_delayed(t, y, 0.0) is y


def test_term_model_delay_in_records_and_equations():
    tm = TermModel({"theta_dot": 2.0}, {}, delay=-0.004)
    d = term_model_to_dict(tm)
    assert d["delay"] == -0.004
    assert term_model_from_dict(d).delay == -0.004
    assert TermModelRecord.of(tm).to_term_model().delay == -0.004
    # an older record without the key reads as no delay, and writes none
    old = {"torque": {"theta_dot": 2.0}, "hysteresis": {}, "n": 1.0, "J": 1.0}
    assert term_model_from_dict(old).delay == 0.0
    assert "delay" not in term_model_to_dict(term_model_from_dict(old))
    assert tm.equations().splitlines()[-1] == "measured(t) = model(t - -0.004 s)"


def test_simulate_cli_writes_delayed_data(tmp_path, capsys):
    args = ["simulate", "--model", FAMILY, "--experiment", "driven", "--currents", "0,1"]
    args += ["--duration", "1", "--noise", "0", "--drive", "0.2@2.0"]
    assert main([*args, "-o", str(tmp_path / "a.csv")]) == 0
    assert main([*args, "--delay", "0.004", "-o", str(tmp_path / "b.csv")]) == 0
    a = np.genfromtxt(tmp_path / "a.csv", delimiter=",", names=True)
    b = np.genfromtxt(tmp_path / "b.csv", delimiter=",", names=True)
    assert np.allclose(a["theta"], b["theta"])
    # after the start-up, b's torque is a's four samples later
    run = a["run"] == 0
    ta, tb = a["torque"][run], b["torque"][run]
    assert np.allclose(tb[504:], ta[500:-4], atol=1e-5 * np.ptp(ta))
    with pytest.raises(SystemExit):
        main(["simulate", "--help"])
    assert "--delay SECONDS" in capsys.readouterr().out
    assert main(["simulate", "--model", "dahl", "--delay", "0.01", "-o", str(tmp_path / "c.csv")])
    assert "records one; fix:" in capsys.readouterr().err


# ----------------------------------------------------------------------------- filter

FILTER = {"period_fraction": 0.1, "channels": ["theta", "torque"]}
#: the truth in the fit's normalization (z_sat = 1): z scaled by z_sat = sqrt(20 / 16)
#: (the demo delta = 20 against beta + gamma = 16, n = 2)
ZS = np.sqrt(20.0 / 16.0)
NORMALIZED = {
    "alpha_1": 0.4 * ZS,
    "alpha_2": 1.2 * ZS,
    "c_1": 0.3,
    "c_2": 0.5,
    "k_s": 50.0,
    "n": 2.0,
    "beta": 4.0 * ZS,
    "gamma": 12.0 * ZS,
}


@cache
def _filtered_runs() -> tuple[list[Run], float]:
    """Unfiltered simulation, filtered here as the UTFSM authors did (a causal moving
    average of a tenth of each test's period on both channels, zero initial state), then
    1 % force noise."""
    clean = _data(0.0, 0.0)
    noise = _noise()
    rng = np.random.default_rng(5)
    runs = []
    for k, r in enumerate(clean):
        f = float(DRIVES[k // len(CURRENTS)].split("@")[1])
        n = int(round(0.1 / (1e-3 * f)))
        theta = causal_average(r.theta, n)
        torque = causal_average(r.torque, n) + noise * rng.standard_normal(r.t.size)
        runs.append(Run(r.name, r.t, theta, r.current, torque=torque))
    return runs, noise


@cache
def _discover_filtered(declared: bool) -> Discovery:
    from hystdisc.data.rigs import normalize_rig

    runs, _ = _filtered_runs()
    filt = normalize_rig({"filter": FILTER}, "rig")["filter"] if declared else None
    data = Dataset(runs, "driven", "filtered", filt)
    return Discovery(model=FAMILY, heldout=False, shapes=(FAMILY_SHAPE[FAMILY],)).fit(data)


def test_declared_filter_recovers_the_damper():
    _, noise = _filtered_runs()
    disc = _discover_filtered(True)
    assert disc.fit_data_.filter_windows == [100] * 3 + [50] * 3 + [33] * 3
    fit = disc.final_fit_
    assert disc.effects_ == []
    assert abs(fit.rms / noise - 1.0) < 0.02
    p = fit.params
    for name in ("alpha_1", "alpha_2", "c_1", "c_2", "k_s"):
        assert p[name] == pytest.approx(NORMALIZED[name], rel=0.02), name
    assert p["n"] == pytest.approx(2.0, rel=0.05)
    for name in ("beta", "gamma"):  # the least determined pair of the shape
        assert p[name] == pytest.approx(NORMALIZED[name], rel=0.15), name


def test_undeclared_filter_biases_the_fit():
    """The same data without the declaration: the fit models the filter, not the damper."""
    _, noise = _filtered_runs()
    disc = _discover_filtered(False)
    fit = disc.family_fits_[FAMILY]
    assert fit.rms > 1.02 * noise
    assert abs(fit.params["beta"] / NORMALIZED["beta"] - 1.0) > 0.3


def test_motion_is_reconstructed_from_the_filtered_one():
    runs, _ = _filtered_runs()
    clean = _data(0.0, 0.0)
    disc = _discover_filtered(True)
    fd = disc.fit_data_
    for k in (0, 4, 8):
        m = fd.mask[k]
        assert not m[: fd.filter_windows[k]].any()  # the filter's start-up is left out
        scale = np.ptp(clean[k].theta)
        assert np.abs(fd.theta[k] - clean[k].theta)[m].max() < 1e-6 * scale
        wscale = np.ptp(clean[k].theta_dot)
        assert np.abs(fd.theta_dot[k] - clean[k].theta_dot)[m].max() < 1e-6 * wscale


def test_average_on_decimated_data_and_response():
    t = np.arange(4000) * 1e-3
    y = np.sin(2 * np.pi * 1.5 * t)
    full = causal_average(y, 60)
    dec = causal_average(y[::4], 60, step=4)
    # at most the linear interpolation's error between the decimated samples, h^2 w^2 / 8
    assert np.abs(dec - full[::4])[20:].max() < (4e-3 * 2 * np.pi * 1.5) ** 2 / 8
    # steady state of a sine: the response's gain and phase
    H = average_response(np.array([1.5]), 60, 1e-3)[0]
    want = np.abs(H) * np.sin(2 * np.pi * 1.5 * t + np.angle(H))
    assert np.abs(full - want)[60:].max() < 1e-9
    # a non-periodic record is inverted by the regularized frequency-domain inverse
    x = np.exp(-t) * (t - 1.0) ** 2
    th, _ = unfiltered_motion(t, causal_average(x, 20), 20)
    assert np.abs(th - x)[200:-200].max() < 1e-2 * np.ptp(x)


RIG = 'experiment = "driven"\n[columns]\nt = 0\ntheta = 1\ntorque = 2\n[current]\nvalue = 0.5\n'


def test_rig_filter_table(tmp_path):
    from hystdisc.data import load, read_rig

    rig = tmp_path / "rig.toml"
    rig.write_text(RIG + '[filter]\nwindow = 25\nchannels = ["theta", "torque"]\n')
    assert read_rig(rig)["filter"] == {
        "kind": "moving_average",
        "window": 25,
        "period_fraction": None,
        "channels": ["theta", "torque"],
    }
    t = np.arange(500) * 1e-3
    rows = np.column_stack([t, np.sin(2 * np.pi * 2 * t), np.cos(2 * np.pi * 2 * t)])
    np.savetxt(tmp_path / "a.txt", rows)
    ds = load([tmp_path / "a.txt"], rig=rig)
    assert ds.filter["window"] == 25 and ds.subset([0]).filter == ds.filter
    rig.write_text(RIG + '[filter]\nperiod_fraction = 0.1\nchannels = ["torque"]\n')
    assert read_rig(rig)["filter"]["period_fraction"] == 0.1
    assert read_rig(rig)["filter"]["window"] is None


@pytest.mark.parametrize(
    ("table", "message"),
    [
        (
            "window = 0",
            "[filter] window = 0 is invalid; fix: give a whole number of samples >= 1",
        ),
        (
            "period_fraction = 1.5",
            "[filter] period_fraction = 1.5 is invalid; fix: give a fraction of the period "
            "in (0, 1], e.g. 0.1",
        ),
        (
            'channels = ["theta"]',
            "[filter] needs exactly one of window and period_fraction; fix: give window = N "
            "(samples) or period_fraction = 0.1 (of each test's period)",
        ),
        (
            "window = 3\nperiod_fraction = 0.1",
            "[filter] needs exactly one of window and period_fraction; fix: give window = N "
            "(samples) or period_fraction = 0.1 (of each test's period)",
        ),
        (
            'window = 3\nchannels = ["force"]',
            "[filter] channels = ['force'] is invalid; fix: list the filtered columns among "
            'theta, torque, input, e.g. channels = ["theta", "torque"]',
        ),
        (
            'window = 3\norder = 2\nchannels = ["theta"]',
            "unknown [filter] setting(s) 'order'; fix: use window or period_fraction, and channels",
        ),
    ],
)
def test_rig_filter_bad_values(tmp_path, table, message):
    from hystdisc.data import read_rig
    from hystdisc.errors import HystdiscError

    rig = tmp_path / "rig.toml"
    rig.write_text(RIG + "[filter]\n" + table + "\n")
    with pytest.raises(HystdiscError) as err:
        read_rig(rig)
    assert str(err.value) == f"{rig}: {message}"
