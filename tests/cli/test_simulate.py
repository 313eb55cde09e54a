"""``hystdisc simulate``: output, overwrite protection, one-line errors, scenarios, data_synth."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hystdisc.cli import main
from hystdisc.data import read_csv
from hystdisc.errors import HystdiscError
from hystdisc.models import Model
from hystdisc.simulation.scenarios import generate_from_scenario, load_scenario
from hystdisc.simulation.synth import generate

REPO = Path(__file__).resolve().parents[2]
DATA_SYNTH = REPO / "data_synth"
SHORT = ["--duration", "1", "--fs", "500"]


def run_cli(args: list[str], capsys) -> tuple[int, str, str]:
    try:
        code = main(args)
    except SystemExit as exc:  # argparse's own errors exit (through our one-line handler)
        code = exc.code
    out, err = capsys.readouterr()
    return code, out, err


def assert_one_line_error(code: int, err: str, *words: str) -> None:
    assert code == 2
    assert err.count("\n") == 1 and err.startswith("hystdisc: error: "), err
    assert "Traceback" not in err
    for w in words:
        assert w in err, err


def test_writes_csv_that_reads_back(tmp_path, capsys):
    out = tmp_path / "bw.csv"
    args = ["simulate", "--model", "bouc-wen", "--set", "k_s=150", "--set", "c_1=0.8"]
    args += ["--currents", "0,0.5,1", "--seed", "3", "-o", str(out), *SHORT]
    code, stdout, err = run_cli(args, capsys)
    assert code == 0 and err == ""
    assert stdout.count("\n") == 1
    for word in ("3 release runs", "1500 samples", "0, 0.5, 1 A", str(out)):
        assert word in stdout
    ds = read_csv(out)
    assert ds.experiment == "release" and ds.names == ["0", "1", "2"]
    assert ds.currents.tolist() == [0.0, 0.5, 1.0]
    assert all(r.n == 500 for r in ds)
    # the file holds what generate() makes, to the written precision
    ref = generate(
        Model("bouc-wen", {"k_s": 150, "c_1": 0.8}),
        currents=(0, 0.5, 1),
        duration=1,
        fs=500,
        seed=3,
    )
    for a, b in zip(ds, ref, strict=True):
        np.testing.assert_allclose(a.theta, b.theta, rtol=1e-6, atol=1e-9)
    default = generate("bouc-wen", currents=(0, 0.5, 1), duration=1, fs=500, seed=3)
    assert not np.allclose(ds[2].theta, default[2].theta)  # the --set values were used


def test_driven_forced_effects_encoder(tmp_path, capsys):
    out = tmp_path / "d.csv"
    code, stdout, _ = run_cli(
        [
            "simulate",
            "--model",
            "dahl",
            "--experiment",
            "driven",
            "--drive",
            "0.3@1",
            "--drive",
            "0.1@3",
            "--set",
            "k_s=0",
            "--noise",
            "0.01",
            "--currents",
            "0,1",
            "--effect",
            "current_viscous:c_i=0.4",
            "-o",
            str(out),
            *SHORT,
        ],
        capsys,
    )
    assert code == 0 and "4 driven runs of dahl + current_viscous" in stdout
    ds = read_csv(out)
    assert ds.experiment == "driven" and len(ds) == 4
    assert ds[0].torque is not None and ds[0].theta_dot is not None
    assert ds[2].theta.max() == pytest.approx(0.1, rel=1e-3)  # runs 2, 3: the second drive
    out = tmp_path / "f.csv"
    code, _, _ = run_cli(
        [
            "simulate",
            "--model",
            "lugre",
            "--experiment",
            "forced",
            "--set",
            "J=2",
            "--input",
            "sine:amplitude=5,frequency=1.5",
            "--effect",
            "coulomb",
            "--encoder-counts",
            "4096",
            "-o",
            str(out),
            *SHORT,
        ],
        capsys,
    )
    assert code == 0
    ds = read_csv(out)
    assert ds.experiment == "forced" and len(ds) == 5
    np.testing.assert_allclose(ds[0].input, 5 * np.sin(2 * np.pi * 1.5 * ds[0].t), atol=1e-6)
    q = 2 * np.pi / 4096
    np.testing.assert_allclose(ds[1].theta / q, np.round(ds[1].theta / q), atol=1e-3)


def test_refuses_to_overwrite(tmp_path, capsys):
    out = tmp_path / "x.csv"
    out.write_text("mine\n")
    code, stdout, err = run_cli(["simulate", "--model", "dahl", "-o", str(out), *SHORT], capsys)
    assert_one_line_error(code, err, "already exists", "--force")
    assert out.read_text() == "mine\n" and stdout == ""
    code, _, _ = run_cli(
        ["simulate", "--model", "dahl", "-o", str(out), "--force", "--quiet", *SHORT], capsys
    )
    assert code == 0 and read_csv(out).experiment == "release"


@pytest.mark.parametrize(
    "extra, words",
    [
        (["--model", "nope"], ["unknown model 'nope'"]),
        (["--model", "dahl", "--set", "zz=1"], ["unknown parameter 'zz'"]),
        (["--model", "dahl", "--set", "rho"], ["NAME=VALUE"]),
        (["--model", "dahl", "--set", "rho=abc"], ["not a number"]),
        (["--model", "dahl", "--set", "rho=-3"], ["outside its physical bounds"]),
        (["--model", "dahl", "--duration", "-1"], ["duration", "positive"]),
        (["--model", "dahl", "--fs", "0"], ["fs", "positive"]),
        (["--model", "dahl", "--currents", ","], ["--currents is empty"]),
        (["--model", "dahl", "--currents", "0,-1"], ["negative"]),
        (["--model", "dahl", "--noise", "-0.1"], ["noise", "negative"]),
        (["--model", "dahl", "--seed", "x"], ["--seed"]),
        (["--model", "dahl", "--encoder-counts", "0"], ["encoder_counts"]),
        (["--model", "dahl", "--experiment", "sideways"], ["unknown experiment"]),
        (["--model", "dahl", "--experiment", "driven", "--drive", "0.3"], ["AMPLITUDE@FREQUENCY"]),
        (["--model", "dahl", "--drive", "0.3@1"], ["only used by driven"]),
        (["--model", "dahl", "--experiment", "forced", "--input", "square"], ["input kind"]),
        (["--model", "dahl", "--effect", "magic"], ["unknown effect 'magic'"]),
        (["--model", "dahl", "--effect", "coulomb:g=1"], ["unknown parameter 'g'"]),
        # a share of a torque term a state-space family does not have: zero, not data
        (
            "--model spencer --experiment driven --drive 0.2@0.5 "
            "--effect asymmetric_damping:r_c=0.3".split(),
            [
                "spencer: asymmetric_damping would be zero: spencer is a state-space family: "
                "its force has no theta_dot term for asymmetric_damping to scale (the form on "
                "it is not built); fix: leave asymmetric_damping out, or use a family that "
                "carries it (bingham, dahl, lugre, bouc-wen, bouc-wen-std, tanh)"
            ],
        ),
        (["--model", "dahl", "--duration"], ["expected one argument"]),
        (["--set", "k_s=1"], ["no model given"]),
        (["--scenario", "missing.toml"], ["does not exist"]),
    ],
)
def test_bad_arguments_give_one_line(extra, words, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    code, stdout, err = run_cli(["simulate", *extra, "-o", "out.csv"], capsys)
    assert_one_line_error(code, err, *words)
    assert not (tmp_path / "out.csv").exists()


def test_no_output_given(capsys):
    code, _, err = run_cli(["simulate", "--model", "dahl", *SHORT], capsys)
    assert_one_line_error(code, err, "-o FILE")


SCENARIO = """\
# a test scenario
model = "dahl"
declared = "dahl"
currents = [0.0, 1.0]
duration = 1.0
fs = 500.0
noise = 0.002
seed = 9
output = "sc.csv"
[params]
rho = 12.0
[effects.current_viscous]
c_i = 0.5
[effects.coulomb]
"""


def test_scenario_and_overrides(tmp_path, capsys):
    sc_file = tmp_path / "s.toml"
    sc_file.write_text(SCENARIO)
    code, stdout, _ = run_cli(["simulate", "--scenario", str(sc_file)], capsys)
    assert code == 0 and "dahl + current_viscous + coulomb" in stdout
    written = read_csv(tmp_path / "sc.csv")  # output is relative to the scenario file
    sc = load_scenario(sc_file)
    assert sc["effects"] == {"current_viscous": {"c_i": 0.5}, "coulomb": {}}
    ref = generate_from_scenario(sc)
    for a, b in zip(written, ref, strict=True):
        np.testing.assert_allclose(a.theta, b.theta, rtol=1e-6, atol=1e-9)
    # flags override the scenario
    out = tmp_path / "other.csv"
    code, _, _ = run_cli(
        [
            "simulate",
            "--scenario",
            str(sc_file),
            "--seed",
            "10",
            "--currents",
            "0.5",
            "--set",
            "rho=30",
            "-o",
            str(out),
        ],
        capsys,
    )
    assert code == 0
    other = read_csv(out)
    assert other.currents.tolist() == [0.5] and other[0].n == 500
    ref = generate_from_scenario({**sc, "seed": 10, "currents": [0.5], "params": {"rho": 30.0}})
    np.testing.assert_allclose(other[0].theta, ref[0].theta, rtol=1e-6, atol=1e-9)


def test_scenario_unknown_key_is_named(tmp_path):
    p = tmp_path / "bad.toml"
    p.write_text('model = "dahl"\ncurents = [0, 1]\n')
    with pytest.raises(HystdiscError, match="unknown key 'curents'"):
        load_scenario(p)
    p.write_text('model = "dahl"\n[effects]\ncoulomb = 3\n')
    with pytest.raises(HystdiscError, match=r"effects\.coulomb must be a table"):
        load_scenario(p)
    p.write_text('model = "dahl"\ndrives = [{amplitude = 0.3, freq = 1}]\n')
    with pytest.raises(HystdiscError, match="unknown drive setting 'freq'"):
        load_scenario(p)
    p.write_text("model = [\n")
    with pytest.raises(HystdiscError, match="not valid TOML"):
        load_scenario(p)


def test_regenerate_reproduces_data_synth(tmp_path, capsys):
    tomls = sorted(DATA_SYNTH.glob("*.toml"))
    assert len(tomls) == 12
    code, stdout, err = run_cli(
        ["simulate", "--regenerate", str(DATA_SYNTH), "-o", str(tmp_path)], capsys
    )
    assert code == 0, err
    assert stdout.count("\n") == len(tomls)
    for toml in tomls:
        sc = load_scenario(toml)
        name = Path(sc["output"]).name
        committed = read_csv(DATA_SYNTH / name)
        fresh = read_csv(tmp_path / name)
        assert committed.experiment == fresh.experiment == sc.get("experiment", "release")
        assert committed.names == fresh.names
        np.testing.assert_array_equal(committed.currents, fresh.currents)
        for a, b in zip(committed, fresh, strict=True):
            np.testing.assert_array_equal(a.t, b.t)
            for key in ("theta", "torque", "input", "theta_dot"):
                x, y = getattr(a, key), getattr(b, key)
                assert (x is None) == (y is None), (name, key)
                if x is not None:
                    np.testing.assert_allclose(x, y, rtol=1e-6, atol=1e-9, err_msg=name)


def test_regenerate_refuses_existing_without_force(tmp_path, capsys):
    for f in ("dahl.toml", "lugre.toml"):
        shutil.copy(DATA_SYNTH / f, tmp_path / f)
    (tmp_path / "lugre.csv").write_text("mine\n")
    code, _, err = run_cli(["simulate", "--regenerate", str(tmp_path)], capsys)
    assert_one_line_error(code, err, "lugre.csv", "already exists", "--force")
    assert not (tmp_path / "dahl.csv").exists()  # nothing written
    code, stdout, _ = run_cli(["simulate", "--regenerate", str(tmp_path), "--force"], capsys)
    assert code == 0 and stdout.count("\n") == 2
    assert len(read_csv(tmp_path / "lugre.csv")) == 5


def test_python_m_hystdisc_exit_codes(tmp_path):
    out = tmp_path / "p.csv"
    cmd = [sys.executable, "-m", "hystdisc", "simulate", "--model", "dahl", "-o", str(out)]
    done = subprocess.run(cmd + SHORT, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    assert out.exists() and "wrote 5 release runs" in done.stdout
    done = subprocess.run(cmd + SHORT, capture_output=True, text=True, cwd=tmp_path)
    assert done.returncode == 2
    assert done.stderr.count("\n") == 1 and "Traceback" not in done.stderr
