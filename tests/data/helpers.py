"""Helpers shared by the data-layer tests: synthetic runs and small files."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from hystdisc.data import Dataset, Run

RIG_TOML = """\
experiment = "driven"
[columns]        # 0-based indices for whitespace tables
t = 0
theta = 1
theta_dot = 2
torque = 3
[units]
theta = "mm"
theta_dot = "mm/s"
torque = "N"
[current]
from_name = '(\\d+(?:x\\d+)?)A$'
decimal = "x"
"""


def make_run(
    name: str, current: float, n: int = 200, fs: float = 1000.0, seed: int = 0, **kw
) -> Run:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / fs
    theta = 0.3 * np.exp(-t) * np.cos(2 * np.pi * 3 * t) + rng.normal(0, 1e-4, n)
    return Run(name, t, theta, current, **kw)


def make_dataset(experiment: str, currents=(0.0, 0.5, 1.0), with_dot: bool = False) -> Dataset:
    runs = []
    for i, cur in enumerate(currents):
        r = make_run(str(i), cur, seed=i)
        rng = np.random.default_rng(100 + i)
        extra = rng.normal(size=r.n) * 12.345678901
        if experiment == "driven":
            r.torque = extra
        elif experiment == "forced":
            r.input = extra
        if with_dot:
            r.theta_dot = np.gradient(r.theta, r.t)
        runs.append(r)
    return Dataset(runs, experiment, "mem")


def write_lines(path: Path, header: str | None, rows: list[str]) -> Path:
    text = ((header + "\n") if header else "") + "\n".join(rows) + "\n"
    path.write_text(text, encoding="utf-8")
    return path


def good_rows(
    n: int = 40, run: str | None = "0", current: float = 0.5, extra: bool = False
) -> list[str]:
    rows = []
    for k in range(n):
        cells = [] if run is None else [run]
        cells += [f"{k * 0.001:.3f}", f"{math.sin(0.3 * k):.6f}", f"{current}"]
        if extra:
            cells.append(f"{math.cos(0.3 * k):.6f}")
        rows.append(",".join(cells))
    return rows


def check_message(exc: pytest.ExceptionInfo, *words: str) -> str:
    msg = str(exc.value)
    assert "\n" not in msg
    assert "fix:" in msg
    for w in words:
        assert w in msg, f"{w!r} not in {msg!r}"
    return msg


def assert_close(a, b, rtol: float = 1e-9) -> None:
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape
    scale = np.maximum(np.abs(b), np.max(np.abs(b)) * 1e-12 + 1e-300)
    assert np.all(np.abs(a - b) <= rtol * scale + 1e-15)


def csv_with(tmp_path: Path, name: str, header: str, rows: list[str]) -> Path:
    return write_lines(tmp_path / name, header, rows)


def write_table_dir(folder: Path, currents=("0", "0x5", "1"), rig: bool = True) -> Path:
    folder.mkdir(exist_ok=True)
    rng = np.random.default_rng(7)
    for cur in currents:
        t = np.arange(300) * 0.005
        x = 10.0 * np.sin(2 * np.pi * t)
        v = np.gradient(x, t)
        f = (100 + 300 * float(cur.replace("x", "."))) * np.tanh(v / 5) + rng.normal(0, 1, t.size)
        np.savetxt(folder / f"10mm1Hz{cur}A.txt", np.column_stack([t, x, v, f]), fmt="%.7e")
    (folder / "README.md").write_text("not data")
    if rig:
        (folder / "rig.toml").write_text(RIG_TOML)
    return folder
