"""Files the commands write (issue 8): atomic, never overwritten without --force, and no
partial or temporary file left by a failure or by Ctrl-C.

Every writing command is covered: ``simulate -o`` (and ``--regenerate``), ``discover``
(``--json``, ``--out``, ``--each``), ``predict -o`` and ``study -o``. Ctrl-C is simulated by
raising :class:`KeyboardInterrupt` inside the writer (``os.replace``, ``os.fsync``) or in the
serializer; the command must exit with 130 and one line on stderr.
"""

from __future__ import annotations

import json
import os
from pathlib import Path

import pytest

import hystdisc.data.writers
from hystdisc.cli import main
from hystdisc.data import atomic_write_bytes, atomic_write_text, write_csv
from hystdisc.errors import HystdiscError
from hystdisc.simulation.synth import generate

PRECIOUS = "the user's own file\n"
FAST_DISCOVER = ["--families", "dahl,bingham", "--no-heldout", "--no-effects", "--quiet"]
SIM = ["simulate", "--model", "dahl", "--currents", "0,1", "--duration", "0.5", "--quiet"]
STUDY = ["study", "--model", "dahl", "--vary", "rho=5,20", "--cycles", "2", "--fs", "200"]


# ----------------------------------------------------------------------------- helpers


def cli(argv, capsys) -> tuple[int, str]:
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert "Traceback" not in err + out
    return code, err


def error_line(err: str) -> str:
    lines = [line for line in err.splitlines() if line.startswith("hystdisc: error:")]
    assert len(lines) == 1, err
    msg = lines[0]
    assert msg == " ".join(msg.split()) and "fix:" in msg, msg
    return msg


def leftovers(folder: Path) -> list[str]:
    """Temporary or hidden files left in ``folder`` (recursively)."""
    return sorted(
        str(p.relative_to(folder))
        for p in folder.rglob("*")
        if p.name.startswith(".") or p.name.endswith(".tmp")
    )


@pytest.fixture(scope="module")
def data_csv(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("data")
    ds = generate("dahl", currents=(0.0, 0.5, 1.0), duration=2.0, noise=1e-3, seed=1)
    return write_csv(ds, folder / "data.csv")


@pytest.fixture(scope="module")
def results_json(tmp_path_factory, data_csv) -> Path:
    out = tmp_path_factory.mktemp("res") / "results.json"
    assert main(["discover", str(data_csv), "--json", str(out), *FAST_DISCOVER]) == 0
    return out


def writers(tmp: Path, data_csv: Path, results_json: Path) -> dict[str, tuple[list, Path]]:
    """command -> (argv without --force, the file it writes)."""
    return {
        "simulate": ([*SIM, "-o", tmp / "sim.csv"], tmp / "sim.csv"),
        "discover --json": (
            ["discover", data_csv, "--json", tmp / "r.json", *FAST_DISCOVER],
            tmp / "r.json",
        ),
        "discover --out": (
            ["discover", data_csv, "--out", tmp / "out", *FAST_DISCOVER],
            tmp / "out" / "results.json",
        ),
        "discover --each": (
            ["discover", data_csv, "--each", "--out", tmp / "each", *FAST_DISCOVER],
            tmp / "each" / "data.results.json",
        ),
        "predict": (
            ["predict", results_json, data_csv, "-o", tmp / "pred.csv", "--quiet"],
            tmp / "pred.csv",
        ),
        "study": ([*STUDY, "-o", tmp / "loops.png", "--quiet"], tmp / "loops.png"),
    }


COMMANDS = ["simulate", "discover --json", "discover --out", "discover --each", "predict", "study"]


# ----------------------------------------------------------------------------- no overwrite


@pytest.mark.parametrize("command", COMMANDS)
def test_nothing_is_overwritten_without_force(command, tmp_path, data_csv, results_json, capsys):
    argv, target = writers(tmp_path, data_csv, results_json)[command]
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(PRECIOUS)
    before = target.stat().st_mtime_ns
    code, err = cli(argv, capsys)
    assert code == 2, err
    msg = error_line(err)
    assert str(target) in msg and "--force" in msg
    assert target.read_text() == PRECIOUS and target.stat().st_mtime_ns == before
    code, err = cli([*argv, "--force"], capsys)
    assert code == 0, err
    assert target.read_bytes() != PRECIOUS.encode()
    assert leftovers(tmp_path) == []


@pytest.mark.parametrize("existing", ["report.html", "report.md"])
def test_report_refuses_to_overwrite_before_fitting(existing, tmp_path, data_csv, capsys):
    """``report`` writes an HTML file and a Markdown summary: neither is replaced."""
    (tmp_path / existing).write_text(PRECIOUS)
    argv = ["report", data_csv, "-o", tmp_path / "report.html", *FAST_DISCOVER]
    code, err = cli(argv, capsys)
    assert code == 2, err
    msg = error_line(err)
    assert existing in msg and "--force" in msg
    assert (tmp_path / existing).read_text() == PRECIOUS
    assert sorted(p.name for p in tmp_path.iterdir()) == [existing]


def test_regenerate_writes_nothing_when_one_output_exists(tmp_path, capsys):
    for name in ("a", "b"):
        (tmp_path / f"{name}.toml").write_text(
            f'model = "dahl"\nduration = 0.3\ncurrents = [0.0]\noutput = "{name}.csv"\n'
        )
    (tmp_path / "b.csv").write_text(PRECIOUS)
    code, err = cli(["simulate", "--regenerate", tmp_path, "--quiet"], capsys)
    assert code == 2 and "b.csv" in error_line(err) and "--force" in err
    assert not (tmp_path / "a.csv").exists()  # all or nothing
    assert (tmp_path / "b.csv").read_text() == PRECIOUS
    code, err = cli(["simulate", "--regenerate", tmp_path, "--quiet", "--force"], capsys)
    assert code == 0, err
    assert (tmp_path / "a.csv").exists() and (tmp_path / "b.csv").read_text() != PRECIOUS


# ----------------------------------------------------------------------------- atomic writes


@pytest.mark.parametrize("command", COMMANDS)
def test_success_leaves_only_the_output(command, tmp_path, data_csv, results_json, capsys):
    argv, target = writers(tmp_path, data_csv, results_json)[command]
    code, err = cli(argv, capsys)
    assert code == 0, err
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    expected = [target]
    if command in ("discover --json", "discover --out"):  # and what the report draws
        from hystdisc.report.source import report_data_path

        expected.append(report_data_path(target))
    assert written == sorted(str(p.relative_to(tmp_path)) for p in expected)
    if target.suffix == ".json":
        json.loads(target.read_text())  # complete


def _boom_oserror(*args, **kwargs):
    raise OSError(28, "No space left on device")


@pytest.mark.parametrize("command", COMMANDS)
def test_failed_write_leaves_no_partial_file(
    command, tmp_path, data_csv, results_json, capsys, monkeypatch
):
    argv, target = writers(tmp_path, data_csv, results_json)[command]
    target.parent.mkdir(parents=True, exist_ok=True)
    target.write_text(PRECIOUS)
    monkeypatch.setattr(os, "replace", _boom_oserror)
    code, err = cli([*argv, "--force"], capsys)
    monkeypatch.undo()
    assert code == 2, err
    assert "No space left" in error_line(err)
    assert target.read_text() == PRECIOUS  # the old file survives a failed replacement
    assert leftovers(tmp_path) == []


# ----------------------------------------------------------------------------- Ctrl-C


def _interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def _check_interrupted(code: int, err: str) -> None:
    assert code == 130, err
    lines = [line for line in err.splitlines() if line.startswith("hystdisc:")]
    assert len(lines) == 1 and "interrupted" in lines[0], err


@pytest.mark.parametrize("where", ["replace", "fsync"])
@pytest.mark.parametrize("command", COMMANDS)
def test_ctrl_c_in_the_writer_leaves_nothing(
    command, where, tmp_path, data_csv, results_json, capsys, monkeypatch
):
    argv, target = writers(tmp_path, data_csv, results_json)[command]
    monkeypatch.setattr(os, where, _interrupt)
    code, err = cli(argv, capsys)
    monkeypatch.undo()
    _check_interrupted(code, err)
    assert not target.exists()
    assert leftovers(tmp_path) == []


def test_ctrl_c_over_an_existing_file_keeps_it(tmp_path, capsys, monkeypatch):
    target = tmp_path / "sim.csv"
    target.write_text(PRECIOUS)
    monkeypatch.setattr(os, "replace", _interrupt)
    code, err = cli([*SIM, "-o", target, "--force"], capsys)
    monkeypatch.undo()
    _check_interrupted(code, err)
    assert target.read_text() == PRECIOUS
    assert leftovers(tmp_path) == []


def test_ctrl_c_in_the_serializer_leaves_nothing(tmp_path, data_csv, capsys, monkeypatch):
    from hystdisc.results import Results

    monkeypatch.setattr(Results, "to_json", _interrupt)
    out = tmp_path / "out"
    code, err = cli(["discover", data_csv, "--out", out, *FAST_DISCOVER], capsys)
    _check_interrupted(code, err)
    assert not (out / "results.json").exists()
    assert leftovers(tmp_path) == []


def test_ctrl_c_during_the_fit_leaves_nothing(tmp_path, data_csv, capsys, monkeypatch):
    from hystdisc.estimator import Discovery

    monkeypatch.setattr(Discovery, "fit", _interrupt)
    out = tmp_path / "out"
    code, err = cli(["discover", data_csv, "--out", out, *FAST_DISCOVER], capsys)
    _check_interrupted(code, err)
    assert not out.exists() or not any(out.iterdir())


def test_ctrl_c_message_is_true_after_some_outputs(tmp_path, capsys, monkeypatch):
    files = []
    for seed in (1, 2):
        ds = generate("dahl", currents=(0.0, 1.0), duration=1.0, seed=seed)
        files.append(write_csv(ds, tmp_path / f"rig{seed}.csv"))
    # every file the package writes goes through this one primitive
    real = hystdisc.data.writers.atomic_write_bytes
    calls = []

    def second_interrupts(path, data, force=False):
        calls.append(path)
        if len(calls) == 2:
            raise KeyboardInterrupt
        return real(path, data, force=force)

    monkeypatch.setattr(hystdisc.data.writers, "atomic_write_bytes", second_interrupts)
    out = tmp_path / "out"
    code, err = cli(["discover", *files, "--each", "--out", out, *FAST_DISCOVER], capsys)
    _check_interrupted(code, err)
    assert (out / "rig1.results.json").exists()  # written whole before Ctrl-C
    assert "no output was written" not in err


# ----------------------------------------------------------------------------- the writer


def test_atomic_write_refuses_directories_and_unwritable_places(tmp_path):
    with pytest.raises(HystdiscError, match="is a directory"):
        atomic_write_text(tmp_path, "x", force=True)
    blocker = tmp_path / "file"
    blocker.write_text("x")
    with pytest.raises(HystdiscError, match="cannot create its folder") as exc:
        atomic_write_bytes(blocker / "sub" / "out.csv", b"x")
    assert "fix:" in str(exc.value)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_atomic_write_keyboard_interrupt_inside_write(tmp_path, monkeypatch):
    target = tmp_path / "out.json"
    monkeypatch.setattr(os, "fsync", _interrupt)
    with pytest.raises(KeyboardInterrupt):
        atomic_write_text(target, "{}\n")
    monkeypatch.undo()
    assert list(tmp_path.iterdir()) == []
