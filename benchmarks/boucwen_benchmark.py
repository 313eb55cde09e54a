"""The Noël–Schoukens hysteretic benchmark (issue 5): discover, map, validate.

Data: ``$HYSTDISC_DATA/boucwen_benchmark`` (forced: known input force ``u`` [N], measured
displacement ``y`` [m], 4 periods of a 8192-sample multisine at 750 Hz; see the data README).

1. **Discover** on periods 1-3 (one run; the families are compared at the benchmark's one
   "current"), with the closing loop.
2. **Map** the selected Bouc-Wen fit to the benchmark's parametrization
   ``m y'' + c y' + k y + z = u``, ``z' = alpha y' - beta (gamma |y'| |z|^(nu-1) z
   + delta y' |z|^nu)`` (:meth:`hystdisc.models.BoucWenStd.force_form`) and show it beside the
   true values. Only ``beta*gamma`` and ``beta*delta`` are identifiable; the table also gives
   ``gamma``, ``delta`` with ``beta`` fixed at the benchmark's 1000.
3. **Validate** on period 4 from its input alone: the model is simulated from rest over the
   input of period 4 repeated twice and the second repetition is compared (the multisine
   is periodic, so that is the periodic steady state, as in the record). Errors are given
   against the measured period (which carries the benchmark's noise, RMS ~7.3e-6 m) and
   against a noise-free reference: the benchmark definition simulated with its true
   parameters on the same input (this simulation matches the measured record to the noise
   floor, see the "true system" row).
4. **Independent tests** that are not in the repository nor in the data: a new multisine
   (other random phases, same band and RMS) and a 20 -> 50 Hz sine sweep from rest, both
   compared with the true system (noise-free), as the benchmark's own test signals are.

Run:  HYSTDISC_DATA=../shared/data python benchmarks/boucwen_benchmark.py
      (writes benchmarks/results/boucwen_benchmark.md)
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hystdisc.cli.common import progress_printer
from hystdisc.data import Dataset, Run, load
from hystdisc.estimator import Discovery
from hystdisc.models import TermModel, get_family
from hystdisc.simulation import simulate_forced

FS = 750.0
PERIOD = 8192
#: The benchmark definition (data README), standard Bouc-Wen with z in newtons.
TRUE = {
    "m": 2.0,
    "c": 10.0,
    "k": 5e4,
    "alpha": 5e4,
    "beta": 1e3,
    "gamma": 0.8,
    "delta": -1.1,
    "nu": 1.0,
}
RIG = Path(__file__).resolve().parents[1] / "data_synth" / "rigs" / "boucwen_benchmark.toml"


def true_model() -> TermModel:
    """The benchmark system in hystdisc's term form (forced, z in newtons)."""
    p = {
        "alpha_1": 1.0,
        "alpha_2": 0.0,
        "c_1": TRUE["c"],
        "c_2": 0.0,
        "beta": TRUE["beta"] * TRUE["delta"],
        "gamma": TRUE["beta"] * TRUE["gamma"],
        "delta": TRUE["alpha"],
        "n": TRUE["nu"],
    }
    tm = get_family("bouc-wen-std").to_terms(p)
    tm.torque["theta"] = TRUE["k"]
    tm.J = TRUE["m"]
    return tm


def load_benchmark(folder: str | Path) -> Dataset:
    """The estimation record as one forced run (via the rig description)."""
    return load(str(folder), rig=str(RIG))


def periods(ds: Dataset, which: list[int], name: str) -> Dataset:
    """A dataset of the given (0-based) periods of the record, as one run."""
    r = ds.runs[0]
    idx = np.concatenate([np.arange(k * PERIOD, (k + 1) * PERIOD) for k in which])
    run = Run(name, r.t[: idx.size], r.theta[idx], r.current, input=r.input[idx])
    return Dataset([run], "forced", f"{ds.source} periods {[k + 1 for k in which]}")


def steady_state(tm: TermModel, u: np.ndarray, repeats: int = 2) -> np.ndarray:
    """Response to a periodic input in steady state: simulate ``repeats`` periods from rest
    and keep the last (the input alone decides it)."""
    uu = np.tile(u, repeats)
    t = np.arange(uu.size) / FS
    out = simulate_forced(tm, t, 0.0, uu)
    return out.theta[-u.size :]


def from_rest(tm: TermModel, u: np.ndarray) -> np.ndarray:
    t = np.arange(u.size) / FS
    return simulate_forced(tm, t, 0.0, u).theta


def multisine(rng: np.random.Generator, n: int = PERIOD, rms: float = 50.0) -> np.ndarray:
    """A random-phase multisine over the benchmark's band (about 5-150 Hz), ``rms`` newtons."""
    k = np.arange(n // 2 + 1)
    f = k * FS / n
    spec = np.where((f >= 5.0) & (f <= 150.0), np.exp(2j * np.pi * rng.random(k.size)), 0.0)
    u = np.fft.irfft(spec, n)
    return u * rms / np.sqrt(np.mean(u**2))


def sweep(f0: float = 20.0, f1: float = 50.0, duration: float = 20.0, amp: float = 20.0):
    """A linear sine sweep from rest (amplitude ``amp`` newtons)."""
    t = np.arange(int(duration * FS)) / FS
    return amp * np.sin(2 * np.pi * (f0 * t + 0.5 * (f1 - f0) / duration * t**2))


def rms(x: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.asarray(x) ** 2)))


@dataclass
class Outcome:
    disc: Discovery
    cpu: float
    wall: float
    mapped: dict[str, float]
    ci: dict[str, tuple[float, float]]
    errors: dict[str, float]


def mapped_intervals(fit) -> dict[str, tuple[float, float]]:
    """95 % intervals of the benchmark parameters (alpha_1 = 1 normalization: the fit's
    delta, gamma, beta are alpha, beta*gamma, beta*delta themselves)."""
    keys = {
        "m": "J",
        "c": "c_1",
        "k": "k_s",
        "alpha": "delta",
        "beta*gamma": "gamma",
        "beta*delta": "beta",
        "nu": "n",
    }
    if fit.params.get("alpha_1") != 1.0:
        return {}
    return {k: tuple(fit.ci95[v]) for k, v in keys.items() if v in fit.ci95}


def run(folder: str | Path, families=None, close_loop: bool = True, say=None) -> Outcome:
    """Discover on periods 1-3, map to the benchmark parameters, validate."""
    ds = load_benchmark(folder)
    train = periods(ds, [0, 1, 2], "periods1-3")
    test = periods(ds, [3], "period4")
    t0, c0 = time.perf_counter(), time.process_time()
    disc = Discovery(
        families=families or ("bingham", "dahl", "lugre", "bouc-wen", "bouc-wen-std"),
        heldout=False,
        close_loop=close_loop,
        single_current=True,
    ).fit(train, progress=say)
    wall, cpu = time.perf_counter() - t0, time.process_time() - c0
    fit = disc.final_fit_ if getattr(disc, "final_fit_", None) is not None else disc.selected_fit_
    tm = fit.term_model
    mapped = (
        get_family(disc.family_).force_form(fit.params) if disc.family_ == "bouc-wen-std" else {}
    )
    truth = true_model()
    u4 = test.runs[0].input
    y4 = test.runs[0].theta
    pred = steady_state(tm, u4)
    ref = steady_state(truth, u4)
    rng = np.random.default_rng(20161)
    u_ms = multisine(rng)
    u_sw = sweep()
    errors = {
        "period 4 vs measured": rms(pred - y4),
        "period 4 vs noise-free reference": rms(pred - ref),
        "true system vs measured period 4 (noise floor)": rms(ref - y4),
        "period 4 output RMS": rms(y4),
        "new multisine vs true system": rms(steady_state(tm, u_ms) - steady_state(truth, u_ms)),
        "new multisine output RMS": rms(steady_state(truth, u_ms)),
        "sweep 20-50 Hz vs true system": rms(from_rest(tm, u_sw) - from_rest(truth, u_sw)),
        "sweep output RMS": rms(from_rest(truth, u_sw)),
    }
    return Outcome(disc, cpu, wall, mapped, mapped_intervals(fit), errors)


def table(out: Outcome) -> str:
    """The Markdown report: family table, mapped parameters, validation errors."""
    d = out.disc
    lines = [
        "# Noël–Schoukens hysteretic benchmark",
        "",
        f"Discover on periods 1-3 (24 576 samples): {out.wall:.1f} s wall, {out.cpu:.1f} s CPU "
        f"(load average {os.getloadavg()[0]:.1f}). Selected family: **{d.family_}**"
        + (f", effects accepted: {', '.join(d.effects_)}" if getattr(d, "effects_", None) else "")
        + ".",
        "",
        "| family | parameters | RMS (m) | BIC |",
        "|---|---:|---:|---:|",
    ]
    for name, f in d.family_fits_.items():
        star = " *" if name == d.family_ else ""
        lines.append(f"| {name}{star} | {f.n_params} | {f.rms:.4g} | {f.bic:.1f} |")
    if out.mapped:
        truth = dict(TRUE)
        truth["beta*gamma"] = TRUE["beta"] * TRUE["gamma"]
        truth["beta*delta"] = TRUE["beta"] * TRUE["delta"]
        lines += [
            "",
            "Benchmark parametrization (z in newtons; only the products with beta are "
            "identifiable):",
            "",
            "| parameter | true | discovered | 95 % interval | error |",
            "|---|---:|---:|---|---:|",
        ]
        for k, v in out.mapped.items():
            lo, hi = out.ci.get(k, (float("nan"), float("nan")))
            err = (v - truth[k]) / abs(truth[k])
            lines.append(f"| {k} | {truth[k]:.6g} | {v:.6g} | [{lo:.6g}, {hi:.6g}] | {err:+.2%} |")
        g = out.mapped["beta*gamma"] / TRUE["beta"]
        dl = out.mapped["beta*delta"] / TRUE["beta"]
        lines.append(
            f"| gamma (beta = 1000) | {TRUE['gamma']} | {g:.5g} | | "
            f"{(g - TRUE['gamma']) / TRUE['gamma']:+.2%} |"
        )
        lines.append(
            f"| delta (beta = 1000) | {TRUE['delta']} | {dl:.5g} | | "
            f"{(dl - TRUE['delta']) / abs(TRUE['delta']):+.2%} |"
        )
    lines += ["", "Simulation errors (RMS, m):", "", "| test | RMS |", "|---|---:|"]
    lines += [f"| {k} | {v:.3g} |" for k, v in out.errors.items()]
    lines += [
        "",
        "Published black-box simulation errors on the benchmark's (noise-free) test set are "
        "about 7.5e-6 to 1.6e-4 m. The measured period carries the benchmark's noise, so no "
        "model can score below the 'true system vs measured' floor against it; the "
        "noise-free rows measure the model error itself.",
    ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("HYSTDISC_DATA", "../shared/data"))
    ap.add_argument(
        "--out", default=str(Path(__file__).parent / "results" / "boucwen_benchmark.md")
    )
    ap.add_argument("--no-effects", action="store_true", help="skip the closing loop")
    args = ap.parse_args(argv)
    folder = Path(args.data) / "boucwen_benchmark"
    if not folder.is_dir():
        print(
            f"{folder}: not found; fix: set HYSTDISC_DATA to the shared data folder",
            file=sys.stderr,
        )
        return 2
    out = run(folder, close_loop=not args.no_effects, say=progress_printer(quiet=False))
    text = table(out)
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
