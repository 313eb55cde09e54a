"""What the stress suites share (``stress.py``: release data; ``stress_driven.py``: driven).

The sampler's draw, the simultaneous intervals, the judgement of one fit's parameters
against the truth, the ``hystdisc`` command run in a fresh interpreter on the code beside
this file, the loop that runs the cases (kept, resumable) and the report's header.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
#: Two-sided 95 % normal quantile (the fits' intervals).
Z95 = 1.959963984540054
#: Relative tolerance of an identifiable parameter.
TOL = 0.05
#: RMS within this fraction of the floor.
RMS_TOL = 0.10


def draw(rng: np.random.Generator, spec: tuple[str, float, float]) -> float:
    """One parameter value: ``("log", lo, hi)`` log-uniform, ``("uni", lo, hi)`` uniform;
    rounded to the 6 significant digits ``--set`` passes."""
    kind, lo, hi = spec
    x = math.exp(rng.uniform(math.log(lo), math.log(hi))) if kind == "log" else rng.uniform(lo, hi)
    return float(f"{x:.6g}")  # exactly what --set passes


def joint_z(k: int, level: float = 0.95) -> float:
    """The z-score of simultaneous ``level`` intervals for ``k`` parameters (Bonferroni:
    each at ``1 - (1 - level) / k``). With ``k`` exact 95 % intervals the truth is inside
    all of them in only about ``0.95**k`` of the cases (0.70 for 7); inside these, in at
    least 95 %."""
    from scipy.stats import norm

    return float(norm.ppf(1.0 - (1.0 - level) / (2.0 * max(k, 1))))


def judge_parameters(pars: dict[str, Any], truth: dict[str, float], tol: float = TOL) -> dict:
    """One fit's parameters (``results.json``'s ``parameters``) against the truth.

    A parameter is *checked* when the fit reports it, flags it ``identifiable`` and gives
    it a finite interval; the others are listed in ``skipped``. For each checked one: the
    relative error (the absolute error when the truth is 0), whether the truth is inside
    the 95 % interval, and its z-score ``|value - truth| / SE`` with ``SE`` the interval's
    half-width over :data:`Z95`. ``limited``: the parameters whose simultaneous 95 %
    half-width (Bonferroni over the checked ones, :func:`joint_z`) is wider than ``tol``
    relative to the truth (the data cannot tell them to ``tol``), with that half-width;
    ``outside_data``: those outside ``tol`` and outside that half-width.

    Returns
    -------
    dict
        ``checked``, ``skipped``, ``outside_tolerance``, ``outside_ci``, ``z``,
        ``limited``, ``outside_data``, ``zj`` (the simultaneous bound).
    """
    out_tol, out_ci, skipped, checked = [], [], [], []
    zs: dict[str, float] = {}
    rel_se: dict[str, float] = {}  # standard error relative to the truth
    for name, t in truth.items():
        entry = pars.get(name)
        if entry is None:
            skipped.append(f"{name} (not reported)")
            continue
        if not entry.get("identifiable", True):
            skipped.append(name)
            continue
        ci = entry.get("ci95")
        if ci is None or any(x is None or not math.isfinite(float(x)) for x in ci):
            skipped.append(f"{name} (no finite interval)")
            continue
        v = float(entry["value"])
        lo, hi = (float(x) for x in ci)
        rel = abs(v - t) / abs(t) if t != 0 else abs(v)
        checked.append(name)
        if not rel <= tol:
            out_tol.append({"name": name, "truth": t, "value": v, "rel": rel})
        if not lo <= t <= hi:
            out_ci.append({"name": name, "truth": t, "value": v, "ci95": [lo, hi]})
        se = (hi - lo) / (2.0 * Z95)
        zs[name] = abs(v - t) / se if se > 0 else (0.0 if v == t else math.inf)
        if t:
            rel_se[name] = se / abs(t)
    # what the data can tell: a parameter whose simultaneous interval is wider than tol
    # cannot be asked to be within tol (an efficient estimator misses it about as often as
    # its z-score passes tol / SE); it is judged at that limit instead, and listed
    zj = joint_z(len(zs))
    limited = {n: zj * r for n, r in rel_se.items() if zj * r > tol}
    out_data = [o for o in out_tol if o["rel"] > max(tol, limited.get(o["name"], 0.0))]
    return {
        "checked": checked,
        "skipped": skipped,
        "outside_tolerance": out_tol,
        "outside_ci": out_ci,
        "z": zs,
        "limited": limited,
        "outside_data": out_data,
        "zj": zj,
    }


def hystdisc_cli(args: Sequence[str], root: Path = ROOT) -> tuple[int, str]:
    """Run ``python -m hystdisc ARGS`` in a fresh interpreter on the code in ``root``
    (``PYTHONPATH=root``); the exit code and the last line of stderr."""
    env = {**os.environ, "PYTHONPATH": str(root)}
    cp = subprocess.run(
        [sys.executable, "-m", "hystdisc", *args], capture_output=True, text=True, env=env
    )
    return cp.returncode, (cp.stderr.strip().splitlines() or ["?"])[-1]


def run_cases(
    cases: Sequence[Any],
    one: Callable[[Any], dict],
    jobs: int,
    on_record: Callable[[dict, int], None],
) -> None:
    """Run ``one(case)`` for every case on ``jobs`` threads, calling
    ``on_record(record, done)`` as each finishes."""
    done = 0
    with ThreadPoolExecutor(max_workers=max(1, jobs)) as pool:
        futs = {pool.submit(one, c): c for c in cases}
        for fut in as_completed(futs):
            done += 1
            on_record(fut.result(), done)


def kept_record(path: Path) -> dict | None:
    """The record a previous run of a case left (``None`` when there is none)."""
    return json.loads(path.read_text()) if path.exists() else None


def report_header(title: str, meta: dict, count: str) -> list[str]:
    """The first lines of a benchmark report: title, command, commit, time and ``count``."""
    return [
        f"# {title}",
        "",
        f"Command: `{meta['command']}`  ",
        f"Commit: {meta['commit']}; {meta['when']}; wall time {meta['wall_s']:.0f} s; {count}.",
        "",
    ]


def git_commit(root: Path = ROOT) -> str:
    """The short commit of ``root`` ("unknown" outside a repository)."""
    try:
        return subprocess.run(
            ["git", "-C", str(root), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
