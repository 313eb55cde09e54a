"""Benchmark: the compiled RK4 rig simulator against scipy's solve_ivp at matched accuracy.

Task: a 5-run SAS release dataset (Bouc-Wen seed form, demo defaults, currents 0, 0.25,
0.5, 0.75, 1 A, theta0 = 0.3 rad, 6 s at 1 kHz). Reference: DOP853 with rtol 1e-12,
atol 1e-13, max_step 1e-4. For each of RK45, DOP853 and LSODA the loosest rtol (decreasing
by 10x from 1e-3, atol = rtol / 100) whose max |theta error| against the reference is within
1e-6 rad is timed, with a right-hand side in plain Python (what a user writes) and with a
numba-compiled one (the best case for solve_ivp). Every timing is the median of several
repeats; ours is timed after one warm-up call (numba compilation).

Run:  python benchmarks/bench_simulate.py   (writes benchmarks/results/bench_simulate.txt)
"""

from __future__ import annotations

import math
import os
import platform
import statistics
import time
from pathlib import Path

import numba
import numpy as np
import scipy
from scipy.integrate import solve_ivp

from hystdisc.data import atomic_write_text
from hystdisc.models import Model
from hystdisc.simulation import simulate_mech

CURRENTS = [0.0, 0.25, 0.5, 0.75, 1.0]
THETA0 = 0.3
T = np.arange(6000) / 1000.0
TOL = 1e-6
RTOLS = [10.0**-k for k in range(3, 13)]
METHODS = ("RK45", "DOP853", "LSODA")
MODEL = Model("bouc-wen")
TM = MODEL.to_terms()


def median_time(fn, repeats: int) -> float:
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return statistics.median(times)


# ------------------------------------------------------------------ right-hand sides


def _coefs(i: float) -> tuple[float, ...]:
    g = TM.torque.get
    h = TM.hysteresis.get
    return (
        g("theta", 0.0),
        g("theta_dot", 0.0) + i * g("i*theta_dot", 0.0),
        g("z", 0.0) + i * g("i*z", 0.0),
        h("theta_dot", 0.0),
        h("theta_dot*|z|^n", 0.0),
        h("|theta_dot|*z*|z|^n", 0.0),
        TM.n,
    )


def python_rhs(i: float):
    ks, c, a, d, b, g, n = _coefs(i)

    def f(t, y):
        th, w, z = y
        p = abs(z) ** n
        return [w, -(ks * th + c * w + a * z), d * w + b * w * p + g * abs(w) * z * p]

    return f


@numba.njit(cache=True)
def _numba_rhs(t, y, ks, c, a, d, b, g, n):
    th = y[0]
    w = y[1]
    z = y[2]
    p = abs(z) ** n
    out = np.empty(3)
    out[0] = w
    out[1] = -(ks * th + c * w + a * z)
    out[2] = d * w + b * w * p + g * abs(w) * z * p
    return out


def numba_rhs(i: float):
    args = _coefs(i)

    def f(t, y):
        return _numba_rhs(t, y, *args)

    return f


def run_ivp(make_rhs, method: str, rtol: float, atol: float, max_step: float = math.inf):
    out = []
    for i in CURRENTS:
        sol = solve_ivp(
            make_rhs(i),
            (T[0], T[-1]),
            [THETA0, 0.0, 0.0],
            method=method,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            t_eval=T,
        )
        if sol.status != 0:
            raise RuntimeError(sol.message)
        out.append(sol.y[0])
    return np.array(out)


def run_ours():
    res, _ = simulate_mech(MODEL, [T] * len(CURRENTS), CURRENTS, [THETA0] * len(CURRENTS))
    return np.array([r.theta for r in res])


# ------------------------------------------------------------------ benchmark


def main() -> str:
    lines = []

    def say(text: str = "") -> None:
        print(text, flush=True)
        lines.append(text)

    say("bench_simulate: 5-run SAS release, Bouc-Wen (seed form) demo defaults, 6 s at 1 kHz")
    say(
        f"python {platform.python_version()}, numpy {np.__version__}, scipy {scipy.__version__}, "
        f"numba {numba.__version__}, {platform.machine()}, {os.cpu_count()} cpus, "
        f"load average {os.getloadavg()[0]:.2f} at start"
    )
    t0 = time.perf_counter()
    ref = run_ivp(numba_rhs, "DOP853", 1e-12, 1e-13, max_step=1e-4)
    say(f"reference: DOP853 rtol 1e-12 atol 1e-13 max_step 1e-4 ({time.perf_counter() - t0:.1f} s)")
    say(f"accuracy target: max |theta - reference| <= {TOL:g} rad over all runs and samples")
    say()

    run_ours()  # warm-up: numba compilation
    ours = run_ours()
    err_ours = float(np.max(np.abs(ours - ref)))
    t_ours = median_time(run_ours, 21)
    rows = [("hystdisc RK4 (numba)", "-", err_ours, t_ours)]

    for rhs_name, make in (("python rhs", python_rhs), ("numba rhs", numba_rhs)):
        run_ivp(make, "RK45", 1e-3, 1e-5)  # warm-up (compilation)
        for method in METHODS:
            found = None
            for rtol in RTOLS:
                y = run_ivp(make, method, rtol, rtol / 100)
                err = float(np.max(np.abs(y - ref)))
                if err <= TOL:
                    found = (rtol, err)
                    break
            if found is None:
                rows.append(
                    (f"solve_ivp {method}, {rhs_name}", "none <= 1e-12", math.nan, math.nan)
                )
                continue
            rtol, err = found
            reps = 3 if rhs_name == "python rhs" else 5
            t_ivp = median_time(lambda m=method, r=rtol, mk=make: run_ivp(mk, m, r, r / 100), reps)
            rows.append((f"solve_ivp {method}, {rhs_name}", f"{rtol:.0e}", err, t_ivp))

    say(f"{'integrator':<34}{'rtol':>14}{'max err [rad]':>15}{'time [s]':>11}{'vs ours':>10}")
    for name, rtol, err, tm in rows:
        ratio = tm / t_ours
        say(f"{name:<34}{rtol:>14}{err:>15.2e}{tm:>11.4f}{ratio:>9.1f}x")
    say()
    say(
        f"ours within {TOL:g} rad: {'yes' if err_ours <= TOL else 'NO'} (max error {err_ours:.2e} rad)"
    )
    say("time = median wall time for the whole 5-run dataset (atol = rtol / 100, max_step = inf)")
    return "\n".join(lines) + "\n"


if __name__ == "__main__":
    text = main()
    out = Path(__file__).resolve().parent / "results" / "bench_simulate.txt"
    out.parent.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out, text, force=True)
    print(f"wrote {out}")
