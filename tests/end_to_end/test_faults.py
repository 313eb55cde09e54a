"""Numerical faults and reproducibility (issue 8).

Each fault is tried through the public API (``Discovery(...).fit``, small data: 3 currents x
3 s at 1 kHz, ``close_loop=False, heldout=False``) and through the command line
(``main([...])``). Every case is either handled, with a :class:`HystdiscWarning` that says
what was done, or a one-line error naming the run and the fix; never a traceback, and never
a NaN (or null) parameter in ``results.json``.

Reproducibility: the same input and ``--seed`` give byte-identical ``results.json``, and so
does ``--each --jobs 2`` (:func:`test_jobs_do_not_change_results`).
"""

from __future__ import annotations

import json
import math
import warnings
from pathlib import Path

import numpy as np
import pytest

from hystdisc.cli import build_parser, main
from hystdisc.data import Dataset, Run, write_csv
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.estimator import Discovery
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

FAST = {"families": ["dahl", "bingham"], "heldout": False, "close_loop": False}
CLI_FAST = ["--families", "dahl,bingham", "--no-heldout", "--no-effects", "--quiet"]


# ----------------------------------------------------------------------------- helpers


@pytest.fixture(scope="module")
def base() -> Dataset:
    """Dahl data, 3 currents x 3 s at 1 kHz, 1 mrad noise."""
    return generate(Model("dahl"), currents=(0.0, 0.5, 1.0), duration=3.0, noise=1e-3, seed=1)


def replace_runs(ds: Dataset, fn, source: str = "fault.csv") -> Dataset:
    """A dataset whose runs are ``fn(run)`` (a Run or a dict of changed fields)."""
    runs = []
    for r in ds.runs:
        new = fn(r)
        if isinstance(new, dict):
            fields = {"t": r.t, "theta": r.theta, "current": r.current, **new}
            new = Run(r.name, fields["t"], fields["theta"], fields["current"])
        runs.append(new)
    return Dataset(runs, ds.experiment, source)


def one_line(msg: str) -> str:
    assert msg.strip() and msg == " ".join(msg.split()), repr(msg)
    assert "fix:" in msg, msg
    return msg


def _no_constants(name: str):
    raise AssertionError(f"results.json holds {name}")


def check_results_json(text: str) -> dict:
    """No NaN/Infinity literal, and every parameter, interval and error is a finite number."""
    data = json.loads(text, parse_constant=_no_constants)

    def finite(x, where):
        assert isinstance(x, (int, float)) and not isinstance(x, bool), f"{where} = {x!r}"
        assert math.isfinite(x), f"{where} = {x!r}"

    assert data["families"], "no family was fitted"
    for fam, entry in data["families"].items():
        for key, p in entry["parameters"].items():
            finite(p["value"], f"{fam}.{key}")
            assert len(p["ci95"]) == 2, f"{fam}.{key}.ci95"
            for bound in p["ci95"]:
                finite(bound, f"{fam}.{key}.ci95")
        for key in ("rms", "bic"):
            finite(entry[key], f"{fam}.{key}")
        tm = entry["term_model"]
        for key, v in {**tm["torque"], **tm["hysteresis"]}.items():
            finite(v, f"{fam}.term_model.{key}")
    for key, v in {**data["model"]["torque"], **data["model"]["hysteresis"]}.items():
        finite(v, f"model.{key}")
    finite(data["noise_std"], "noise_std")
    return data


def fit(ds: Dataset, **kw) -> tuple[Discovery | None, str | None, list[str]]:
    """Fit; return (discovery or None, error message or None, HystdiscWarning texts)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            d = Discovery(**{**FAST, **kw}).fit(ds)
            err = None
        except HystdiscError as exc:
            d, err = None, one_line(str(exc))
    texts = [str(w.message) for w in caught if issubclass(w.category, HystdiscWarning)]
    for t in texts:
        assert t == " ".join(t.split())
    if d is not None:
        check_results_json(d.results_.to_json())
    return d, err, texts


def cli(argv: list[str], capsys) -> tuple[int, str, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err and "Traceback" not in out
    return code, out, err


def cli_error(argv, capsys, *words) -> str:
    code, _, err = cli(argv, capsys)
    errors = [line for line in err.splitlines() if line.startswith("hystdisc: error:")]
    assert code == 2, (code, err)
    assert len(errors) == 1, err
    msg = one_line(errors[0])
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    return msg


def cli_discover(ds: Dataset, tmp_path: Path, capsys, *extra) -> tuple[int, str, Path]:
    data = write_csv(ds, tmp_path / "data.csv", force=True)
    out = tmp_path / "results.json"
    out.unlink(missing_ok=True)
    code, _, err = cli(["discover", data, "--json", out, *CLI_FAST, *extra], capsys)
    return code, err, out


# ----------------------------------------------------------------------------- stiff / divergent


def test_stiff_rates_are_fitted_without_nan():
    """Coulomb-like data push the hysteretic families to huge rates (a stiff state)."""
    truth = Model("bingham", {"c_a": 0.05, "c_b": 0.02, "f_a": 2.0, "f_b": 3.0})
    ds = generate(truth, currents=(0.0, 0.5, 1.0), duration=3.0, noise=1e-3, seed=1)
    d, err, _ = fit(ds, families=["dahl", "lugre", "bingham"])
    assert err is None, err
    assert d.family_ == "bingham"
    rho = d.family_fits_["dahl"].params["rho"]
    assert rho > 1e3 and math.isfinite(rho)  # near-discontinuous, yet finite with intervals


def test_divergent_model_in_predict_is_one_line_naming_parameters(base, tmp_path, capsys):
    data = write_csv(base, tmp_path / "data.csv")
    res = {
        "experiment": "release",
        "families": {},
        "model": {
            "torque": {"theta": 158.0, "theta_dot": -500.0},  # negative damping: blows up
            "hysteresis": {},
            "n": 1.0,
            "J": 1.0,
        },
    }
    (tmp_path / "results.json").write_text(json.dumps(res))
    out = tmp_path / "pred.csv"
    msg = cli_error(
        ["predict", tmp_path / "results.json", data, "-o", out], capsys, "diverged", "500"
    )
    assert "theta_dot" in msg  # the parameters are named
    assert not out.exists()


def test_divergent_family_start_in_output_error_fit(base):
    """A rate that explodes z during the fit is contained (penalized), not propagated."""
    from hystdisc.fitting import FamilyParametrization, OutputErrorFitter

    d = Discovery(**FAST).fit(base)
    start = {"alpha_1": 0.5, "alpha_2": 1.0, "c_1": 0.5, "c_2": 0.5, "k_s": 158.0}
    start.update({"beta": -500.0, "gamma": -500.0, "n": 3.0})  # |z| runs away
    par = FamilyParametrization("bouc-wen", "release", start)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)
        try:
            res = OutputErrorFitter(d.fit_data_, par, max_nfev=15).fit(heldout=False)
        except HystdiscError as exc:
            one_line(str(exc))
            return
    assert all(math.isfinite(v) for v in res.params.values()), res.params
    assert math.isfinite(res.rms) and math.isfinite(res.bic)


# ----------------------------------------------------------------------------- locked damper


def locked(ds: Dataset) -> Dataset:
    rng = np.random.default_rng(5)

    def lock(r):
        if r.name != "1":
            return r
        return {"theta": 0.3 + rng.normal(0.0, 1e-3, r.n)}  # held at theta0: only noise

    return replace_runs(ds, lock, "locked.csv")


def test_locked_damper_is_an_error_naming_the_run(base):
    _, err, _ = fit(locked(base))
    assert err is not None
    assert "run 1" in err and "locked" in err and "remove the run" in err


def test_locked_damper_cli(base, tmp_path, capsys):
    data = write_csv(locked(base), tmp_path / "locked.csv")
    cli_error(["discover", data, *CLI_FAST], capsys, "locked.csv", "run 1", "locked")
    assert not (tmp_path / "results.json").exists()


# ----------------------------------------------------------------------------- never decays


def undamped(ds: Dataset) -> Dataset:
    rng = np.random.default_rng(6)
    return replace_runs(
        ds,
        lambda r: {"theta": 0.3 * np.cos(2 * np.pi * 2.0 * r.t) + rng.normal(0, 1e-3, r.n)},
        "undamped.csv",
    )


def test_motion_that_never_decays_is_warned_and_fitted(base):
    d, err, texts = fit(undamped(base))
    assert err is None, err
    assert any("does not decay" in t and "run 0" in t for t in texts), texts
    # the damping cannot be identified; it is reported so, with finite numbers
    dahl = d.family_fits_["dahl"]
    assert not all(dahl.identifiable[k] for k in ("k_x", "k_wa", "k_wb"))


def test_motion_that_never_decays_cli(base, tmp_path, capsys):
    code, err, out = cli_discover(undamped(base), tmp_path, capsys)
    assert code == 0, err
    assert "hystdisc: warning:" in err and "does not decay" in err
    check_results_json(out.read_text())


# ----------------------------------------------------------------------------- clipped sensor


def clipped(ds: Dataset, limit: float = 0.2) -> Dataset:
    return replace_runs(ds, lambda r: {"theta": np.clip(r.theta, -limit, limit)}, "clipped.csv")


def test_clipped_sensor_is_detected_and_warned(base):
    d, err, texts = fit(clipped(base))
    assert err is None, err
    hits = [t for t in texts if "clipped" in t]
    assert hits and "maximum 0.2" in hits[0] and "kept" in hits[0], texts


def test_clipped_sensor_cli(base, tmp_path, capsys):
    code, err, out = cli_discover(clipped(base), tmp_path, capsys)
    assert code == 0, err
    assert "saturated or clipped" in err
    check_results_json(out.read_text())


def test_unclipped_and_quantized_data_raise_no_warning():
    """No false alarm on quantized encoders (their turning points repeat levels too)."""
    for counts in (None, 4096, 512):
        ds = generate("dahl", currents=(0.0, 1.0), duration=3.0, noise=0.0, encoder_counts=counts)
        with warnings.catch_warnings():
            warnings.simplefilter("error", HystdiscWarning)
            from hystdisc.data import validate

            validate(ds)


# ----------------------------------------------------------------------------- sampling


def test_irregular_sampling_is_an_error_with_the_fix(base, tmp_path, capsys):
    def jitter(r):
        t = r.t.copy()
        t[500:] += 0.0004  # one late sample: a step of 1.4 ms among 1 ms steps
        return {"t": t}

    ds = replace_runs(base, jitter, "irregular.csv")
    _, err, _ = fit(ds)
    assert err and "irregular sampling" in err and "resample" in err and "run 0" in err
    data = write_csv(ds, tmp_path / "irregular.csv")
    cli_error(["discover", data, *CLI_FAST], capsys, "irregular sampling", "run 0", "resample")


# ----------------------------------------------------------------------------- currents


def test_one_current_just_works(base, tmp_path, capsys):
    """One run (or runs that share one current): the families are compared at it, with
    one warning that the current dependence is not identifiable."""
    one = base.subset([1])
    d, err, texts = fit(one)
    assert err is None, err
    assert set(d.family_fits_) == {"dahl", "bingham"} and d.family_ in d.family_fits_
    assert d.family_fits_["dahl"].params["k_wb"] == 0.0  # fixed, said so in the warning
    (warning,) = [t for t in texts if "share one current" in t]
    assert "the families are compared at it" in warning and "not identifiable" in warning
    d, err, texts = fit(one, model="dahl")
    assert err is None, err
    assert any("the family is fitted at it" in t for t in texts)
    # --single-current is still accepted: it silences the warning and changes nothing else
    d2, err, texts2 = fit(one, single_current=True)
    assert err is None and d2.family_ == fit(one)[0].family_
    assert not [t for t in texts2 if "share one current" in t]
    data = write_csv(one, tmp_path / "one.csv")
    out = tmp_path / "results.json"
    code, _, err = cli(["discover", data, "--json", out, *CLI_FAST], capsys)
    assert code == 0 and "hystdisc: warning:" in err and "share one current" in err
    check_results_json(out.read_text())


def test_constant_current(base, tmp_path, capsys):
    ds = replace_runs(base, lambda r: {"current": 0.5}, "constant.csv")
    d, err, texts = fit(ds)
    assert err is None, err
    assert any("share one current (0.5 A)" in t and "check the current" not in t for t in texts)
    code, err, out = cli_discover(ds, tmp_path, capsys, "--model", "dahl")
    assert code == 0, err
    assert "share one current" in err
    check_results_json(out.read_text())


def test_all_zero_current_column(base, tmp_path, capsys):
    """All zero: a rig without a coil, or a wrong current column: compared at 0 A, and the
    warning says how to check the column."""
    ds = replace_runs(base, lambda r: {"current": 0.0}, "zero.csv")
    d, err, texts = fit(ds)
    assert err is None, err
    (warning,) = [t for t in texts if "share one current (0 A)" in t]
    assert "--column current=NAME" in warning and "--units current=mA" in warning
    code, err, out = cli_discover(ds, tmp_path, capsys, "--model", "bingham")
    assert code == 0, err
    check_results_json(out.read_text())


# ----------------------------------------------------------------------------- reproducibility


def _discover_bytes(data: Path, out: Path, *extra: str) -> bytes:
    argv = ["discover", str(data), "--families", "dahl,bingham", "--no-heldout", "--quiet"]
    code = main([*argv, "--seed", "7", "--json", str(out), *extra])
    assert code == 0
    return out.read_bytes()


def test_same_input_and_seed_give_identical_results(base, tmp_path, capsys):
    data = write_csv(base, tmp_path / "data.csv")
    first = _discover_bytes(data, tmp_path / "a" / "results.json")
    second = _discover_bytes(data, tmp_path / "b" / "results.json")
    capsys.readouterr()
    assert first == second
    check_results_json(first.decode())


def test_jobs_do_not_change_results(tmp_path, capsys):
    """``--each --jobs 2`` (parallel processes) writes the bytes of the serial run."""
    help_text = build_parser()._subparsers._group_actions[0].choices["discover"].format_help()
    assert "--jobs" in help_text  # a skip here would hide the option's loss
    files = []
    for seed in (1, 2):
        ds = generate("dahl", currents=(0.0, 1.0), duration=2.0, noise=1e-3, seed=seed)
        files.append(str(write_csv(ds, tmp_path / f"rig{seed}.csv")))
    argv = ["discover", *files, "--each", "--families", "dahl,bingham", "--no-heldout"]
    outs = {}
    for jobs in ("1", "2"):
        code = main(
            [*argv, "--quiet", "--seed", "7", "--jobs", jobs, "--out", str(tmp_path / jobs)]
        )
        assert code == 0
        outs[jobs] = {p.name: p.read_bytes() for p in sorted((tmp_path / jobs).iterdir())}
    capsys.readouterr()
    assert sorted(outs["1"]) == ["rig1.results.json", "rig2.results.json"]
    assert outs["1"] == outs["2"]


# ----------------------------------------------------------------------------- issue 37


def _without_current(data: Dataset, path: Path) -> Path:
    """``data`` written as a CSV that has lost its current column."""
    write_csv(data, path)
    rows = [line.split(",") for line in path.read_text().splitlines()]
    drop = rows[0].index("current")
    path.write_text("\n".join(",".join(r[:drop] + r[drop + 1 :]) for r in rows) + "\n")
    return path


@pytest.mark.parametrize("experiment", ["release", "driven"])
def test_runs_that_differ_without_a_current_column_are_an_error(base, experiment, tmp_path, capsys):
    # issue 37: such a file ran 80 s at 0 A and ended "the damper law itself may be wrong"
    data = (
        base
        if experiment == "release"
        else generate(
            Model("dahl"), "driven", currents=(0.0, 1.0), duration=2.0, noise=1e-3, seed=2
        )
    )
    path = _without_current(data, tmp_path / "lost.csv")
    code = main(["discover", str(path), "--out", str(tmp_path / "o")])  # not --quiet
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1, err  # the one line, no progress: nothing was fitted
    assert err.startswith(f"hystdisc: error: {path}: no 'current' column, so every run is ")
    assert "start alike and then differ by" in err and "; fix: add a 'current' column" in err
    assert not (tmp_path / "o").exists()


def test_repeated_runs_without_a_current_column_are_read_at_0_A(tmp_path):
    # the same release at one current, twice (other noise), and another release angle
    runs = [
        generate(Model("dahl"), currents=(0.5,), theta0=a, duration=2.0, noise=1e-3, seed=s)[0]
        for s, a in ((1, 0.3), (2, 0.3), (3, 0.15))
    ]
    runs = [Run(str(k), r.t, r.theta, r.current) for k, r in enumerate(runs)]
    path = _without_current(Dataset(runs, "release", "x"), tmp_path / "one.csv")
    from hystdisc.data import load

    with pytest.warns(HystdiscWarning, match="no 'current' column: every run is taken at 0 A"):
        data = load(path)
    assert [r.current for r in data.runs] == [0.0, 0.0, 0.0]
    # a driven sine repeated at one current
    twice = generate(Model("dahl"), "driven", currents=(0.5, 0.5), duration=2.0, seed=4)
    assert twice[0].torque[5] != twice[1].torque[5]  # other noise
    path = _without_current(twice, tmp_path / "driven.csv")
    with pytest.warns(HystdiscWarning, match="no 'current' column"):
        assert len(load(path).runs) == 2


def test_predict_with_a_release_fit_on_a_driven_file_is_an_error(base, tmp_path, capsys):
    # issue 37: it exited 0 with a meaningless output (the driven file read as releases)
    disc = Discovery(model="dahl", **{k: v for k, v in FAST.items() if k != "families"})
    fit = disc.fit(base).results_
    fit.save(tmp_path / "results.json")
    driven = generate(Model("dahl"), "driven", currents=(0.0, 1.0), duration=1.0, seed=5)
    data = write_csv(driven, tmp_path / "driven.csv")
    out = tmp_path / "pred.csv"
    msg = cli_error(
        ["predict", tmp_path / "results.json", data, "-o", out], capsys, "holds driven runs"
    )
    assert msg.startswith(f"hystdisc: error: {data}: holds driven runs (a torque column), but ")
    assert "is a fit of release runs" in msg and "; fix: give runs of a release test" in msg
    assert not out.exists()
    # the release file it was fitted on still predicts
    assert (
        main(
            [
                "predict",
                str(tmp_path / "results.json"),
                str(write_csv(base, tmp_path / "r.csv")),
                "-o",
                str(out),
                "--quiet",
            ]
        )
        == 0
    )
