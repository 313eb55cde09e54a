"""hystdisc.simulation.synth: argument checks, run layout, inputs, rounding for the CSV files."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data import read_csv
from hystdisc.errors import HystdiscError
from hystdisc.models import Model
from hystdisc.simulation.synth import generate, make_input, round_significant, write_dataset
from hystdisc.simulation.synth_checks import DEFAULT_INPUT, parse_drive


def test_release_layout_and_theta0():
    ds = generate("dahl", currents=(0, 0.5), duration=0.5, fs=200, theta0=[0.1, -0.2], noise=0)
    assert ds.names == ["0", "1"] and ds.experiment == "release"
    assert [r.n for r in ds] == [100, 100]
    assert ds[0].t[1] == pytest.approx(1 / 200)
    assert ds[0].theta[0] == 0.1 and ds[1].theta[0] == -0.2
    assert all(r.torque is None and r.input is None for r in ds)


def test_driven_runs_are_drive_by_drive():
    ds = generate(
        Model("bouc-wen", {"k_s": 0}),
        "driven",
        currents=(0, 1),
        duration=1,
        drives=[{"amplitude": 0.3, "frequency": 1}, "0.1@3"],
        noise=0,
    )
    assert ds.currents.tolist() == [0, 1, 0, 1]
    assert [round(float(r.theta.max()), 3) for r in ds] == [0.3, 0.3, 0.1, 0.1]
    t = ds[2].t
    np.testing.assert_allclose(ds[2].theta_dot, 0.1 * 6 * np.pi * np.cos(6 * np.pi * t))
    assert np.abs(ds[1].torque).max() > np.abs(ds[0].torque).max()  # current raises torque


def test_forced_uses_model_inertia_and_default_input():
    light = generate(Model("lugre", {"J": 1.0}), "forced", currents=(0.5,), noise=0, seed=2)
    heavy = generate(Model("lugre", {"J": 4.0}), "forced", currents=(0.5,), noise=0, seed=2)
    np.testing.assert_array_equal(light[0].input, heavy[0].input)
    assert np.sqrt(np.mean(light[0].input ** 2)) == pytest.approx(DEFAULT_INPUT["rms"])
    assert light[0].theta[0] == 0.0  # forced runs start at rest at 0
    assert not np.allclose(light[0].theta, heavy[0].theta)


def test_make_input_kinds_and_errors():
    t = np.arange(2000) / 1000.0
    rng = np.random.default_rng(0)
    u = make_input({"kind": "multisine", "rms": 3, "f_min": 2, "f_max": 4}, t, rng)
    spec = np.abs(np.fft.rfft(u))
    f = np.fft.rfftfreq(t.size, 1e-3)
    assert set(f[spec > 1e-6 * spec.max()]) == {2.0, 2.5, 3.0, 3.5, 4.0}
    s = make_input({"kind": "sine", "amplitude": 2, "frequency": 5}, t, rng)
    np.testing.assert_allclose(s, 2 * np.sin(10 * np.pi * t))
    with pytest.raises(HystdiscError, match="holds no frequency"):
        make_input({"kind": "multisine", "f_min": 0.1, "f_max": 0.2}, t, rng)
    with pytest.raises(HystdiscError, match="unknown multisine input setting 'amp'"):
        make_input({"kind": "multisine", "amp": 1}, t, rng)
    with pytest.raises(HystdiscError, match="below f_min"):
        make_input({"f_min": 5, "f_max": 1}, t, rng)


@pytest.mark.parametrize(
    "kwargs, words",
    [
        ({"duration": 0}, "duration = 0 must be positive"),
        ({"fs": -5}, "fs = -5 must be positive"),
        ({"duration": 0.001, "fs": 100}, "gives 0 sample"),
        ({"currents": ()}, "no currents given"),
        ({"currents": (0, float("nan"))}, "not finite"),
        ({"noise": -1}, "noise = -1 is negative"),
        ({"seed": -1}, "seed = -1 is invalid"),
        ({"seed": 1.5}, "seed = 1.5 is invalid"),
        ({"encoder_counts": 10.5}, "encoder_counts"),
        ({"experiment": "bounce"}, "unknown experiment"),
        ({"theta0": [0.1, 0.2]}, "2 theta0 values for 5 currents"),
        ({"input_spec": {"kind": "sine"}}, "only used by forced"),
        ({"experiment": "driven", "theta0": 0.2}, "theta0 is not used by driven"),
        ({"experiment": "driven", "drives": ["0.3@-1"]}, "drive frequency = -1 must be positive"),
    ],
)
def test_generate_rejects_bad_arguments(kwargs, words):
    with pytest.raises(HystdiscError) as exc:
        generate("dahl", **kwargs)
    assert words in str(exc.value) and "fix:" in str(exc.value)
    assert "\n" not in str(exc.value)


def test_generate_rejects_non_models():
    with pytest.raises(HystdiscError, match="is not a Model"):
        generate(42)


def test_parse_drive_errors():
    with pytest.raises(HystdiscError, match="AMPLITUDE@FREQUENCY"):
        parse_drive("0.3-1")
    with pytest.raises(HystdiscError, match="lacks amplitude or frequency"):
        parse_drive({"amplitude": 0.3})


def test_round_significant_and_write_dataset(tmp_path):
    x = np.array([0.30012345678, -1.23456789e-5, 0.0, 123456.789])
    np.testing.assert_allclose(round_significant(x), [0.3001235, -1.234568e-5, 0, 123456.8])
    ds = generate("bouc-wen", currents=(0, 1), duration=1.0, seed=4)
    path = write_dataset(ds, tmp_path / "a.csv")
    back = read_csv(path)
    for a, b in zip(ds, back, strict=True):
        np.testing.assert_allclose(b.theta, a.theta, rtol=6e-7, atol=1e-12)
    longest = max(len(v) for line in path.read_text().splitlines()[1:] for v in line.split(","))
    assert longest <= len("-0.0001234567")
    with pytest.raises(HystdiscError, match="already exists"):
        write_dataset(ds, path)


def test_prefilter_is_the_rigs_moving_average(tmp_path):
    # the filter a rig's [filter] table declares, as the fit applies it
    from hystdisc.cli import main
    from hystdisc.measurement.chain import causal_average

    kw = dict(currents=(0, 1), duration=2.0, fs=500, drives=["0.1@2"], noise=0.01, seed=3)
    kw["theta_noise"] = 1e-4
    model = Model("dahl", {"k_s": 0.0})
    raw = generate(model, "driven", **kw)
    filt = generate(model, "driven", prefilter={"period_fraction": 0.1}, **kw)
    for a, b in zip(raw, filt, strict=True):  # 0.1 of a 2 Hz period at 500 Hz: 25 samples
        np.testing.assert_allclose(b.torque, causal_average(a.torque, 25), rtol=0, atol=1e-12)
        np.testing.assert_allclose(b.theta, causal_average(a.theta, 25), rtol=0, atol=1e-12)
        assert not np.allclose(a.torque, b.torque)
    one = generate(model, "driven", prefilter={"window": 7, "channels": ["torque"]}, **kw)
    np.testing.assert_array_equal(one[0].theta, raw[0].theta)
    np.testing.assert_allclose(one[0].torque, causal_average(raw[0].torque, 7), atol=1e-12)
    with pytest.raises(HystdiscError, match="records no input channel"):
        generate(model, "driven", prefilter={"window": 7, "channels": ["input"]}, **kw)
    with pytest.raises(HystdiscError, match="exactly one of window and period_fraction"):
        generate(model, "driven", prefilter={"channels": ["torque"]}, **kw)
    # the command line gives the same data as the API
    out = tmp_path / "f.csv"
    args = ["simulate", "--model", "dahl", "--set", "k_s=0", "--experiment", "driven"]
    args += ["--currents", "0,1", "--duration", "2", "--fs", "500", "--drive", "0.1@2"]
    args += ["--noise", "0.01", "--theta-noise", "1e-4", "--seed", "3", "--quiet"]
    assert main([*args, "--prefilter", "period_fraction=0.1", "-o", str(out)]) == 0
    back = read_csv(out)
    np.testing.assert_allclose(back[1].torque, filt[1].torque, rtol=1e-6)
    np.testing.assert_allclose(back[1].theta, filt[1].theta, rtol=1e-6, atol=1e-12)
