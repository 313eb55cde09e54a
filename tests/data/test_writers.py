"""Writing: atomic writes that never overwrite without force, and the CSV writer."""

from __future__ import annotations

import os

import pytest

from hystdisc.data import (
    atomic_write_bytes,
    atomic_write_text,
    read_csv,
    write_csv,
)
from hystdisc.errors import HystdiscError

from .helpers import (
    check_message,
    make_dataset,
)


def test_overwrite_refused_then_forced(tmp_path):
    ds = make_dataset("release")
    p = write_csv(ds, tmp_path / "out.csv")
    before = p.read_text()
    with pytest.raises(HystdiscError) as exc:
        write_csv(make_dataset("release", currents=(2.0,)), p)
    check_message(exc, "out.csv", "exists", "--force")
    assert p.read_text() == before
    write_csv(make_dataset("release", currents=(2.0,)), p, force=True)
    assert read_csv(p).currents.tolist() == [2.0]
    assert sorted(os.listdir(tmp_path)) == ["out.csv"]  # no temp files left behind


def test_atomic_write_leaves_no_temp_file_on_failure(tmp_path, monkeypatch):
    target = tmp_path / "results.json"
    atomic_write_text(target, "old\n")

    def boom(src, dst):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(HystdiscError) as exc:
        atomic_write_text(target, "new\n", force=True)
    check_message(exc, "results.json", "No space left")
    monkeypatch.undo()
    assert target.read_text() == "old\n"
    assert os.listdir(tmp_path) == ["results.json"]


def test_atomic_write_creates_parent_and_keeps_umask_mode(tmp_path):
    p = atomic_write_text(tmp_path / "sub" / "report.html", "<html></html>")
    assert p.read_text() == "<html></html>"
    umask = os.umask(0)
    os.umask(umask)
    assert (p.stat().st_mode & 0o777) == (0o666 & ~umask)
    with pytest.raises(HystdiscError, match="is a directory"):
        atomic_write_text(tmp_path / "sub", "x", force=True)


def test_prediction_columns_are_checked(tmp_path):
    ds = make_dataset("driven", currents=(0.0, 1.0))
    preds = [r.torque * 0.5 for r in ds]
    p = write_csv(ds, tmp_path / "ok.csv", predictions=preds)
    header = p.read_text().splitlines()[0]
    assert header == "run,t,theta,current,torque,torque_model"
    for name in ("theta", "", "a,b"):
        with pytest.raises(HystdiscError) as exc:
            write_csv(ds, tmp_path / "x.csv", predictions={name: preds})
        check_message(exc, "x.csv", f"prediction column name {name!r} is not allowed")
    with pytest.raises(HystdiscError) as exc:
        write_csv(ds, tmp_path / "x.csv", predictions={1: preds, "1": preds})
    check_message(exc, "prediction column name '1' is not allowed")
    with pytest.raises(HystdiscError) as exc:
        write_csv(ds, tmp_path / "x.csv", predictions=[preds[0], preds[1][:-1]])
    check_message(exc, "run 1", "has 199 samples but the run has 200")
    with pytest.raises(HystdiscError) as exc:
        write_csv([1, 2], tmp_path / "x.csv")  # type: ignore[arg-type]
    check_message(exc, "expected a Dataset, got list")
    assert sorted(os.listdir(tmp_path)) == ["ok.csv"]


def test_atomic_write_bytes_writes_exactly_the_bytes(tmp_path):
    data = bytes(range(256)) * 3
    p = atomic_write_bytes(tmp_path / "blob.bin", data)
    assert p.read_bytes() == data
    assert atomic_write_bytes(p, b"x", force=True).read_bytes() == b"x"
