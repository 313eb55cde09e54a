"""The UTFSM MR damper, end to end (issues 5 and 14): discover on all 30 sine tests, then
validate by leaving one test condition out.

Data: ``$HYSTDISC_DATA/utfsm_mr_damper`` (driven: imposed displacement, measured force;
six sine tests — 2 mm/5 Hz, 5 mm/3 Hz, 10 mm/1 Hz, 25 mm at 0.1, 0.25, 0.5 Hz — each at
0, 0.25, 0.5, 0.75 and 1 A), read with ``data_synth/rigs/utfsm_mr_damper.toml``.

1. ``hystdisc discover`` on all 30 files (the README command): family table, the closing
   loop (RMS force error and NRMSE before/after each accepted effect), held-out errors.
2. Leave one test out: for each of the six (amplitude, frequency) tests, ``hystdisc
   discover`` on the other 25 files, then ``hystdisc predict`` on the left-out test's five
   files with the final model and with the Bingham fit of the same run (the baseline a
   user would otherwise use).

NRMSE = RMS force error / RMS of the measured force over the same runs.

Run:  HYSTDISC_DATA=../shared/data python benchmarks/mr_damper.py [--folds N] [--no-effects]
      (writes benchmarks/results/mr_damper.md and keeps the outputs in --work)
"""

from __future__ import annotations

import argparse
import csv
import os
import re
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
REUSE = False
RIG = ROOT / "data_synth" / "rigs" / "utfsm_mr_damper.toml"
TEST_RE = re.compile(r"^(\d+(?:x\d+)?mm\d+(?:x\d+)?Hz)(\d+(?:x\d+)?)A$")


def tests_of(folder: Path) -> dict[str, list[Path]]:
    """Files grouped by sine test (amplitude and frequency), currents in order."""
    groups: dict[str, list[Path]] = defaultdict(list)
    for f in sorted(folder.glob("*.txt")):
        m = TEST_RE.match(f.stem)
        if m:
            groups[m.group(1)].append(f)
    return dict(groups)


def _names(effects: list) -> list[str]:
    return [e if isinstance(e, str) else e.name for e in effects]


def _results(path: Path):
    """The typed record of a ``results.json`` (hystdisc.results.Results)."""
    from hystdisc.results import Results

    return Results.load(path)


def hystdisc(*args: str, log: Path | None = None) -> tuple[str, float]:
    """Run the hystdisc command line; return its stdout and the CPU time of the child.

    With ``REUSE`` set and ``log`` already written (an earlier, interrupted run of this
    script), the command is not run again and the recorded CPU time is returned.
    """
    if REUSE and log is not None and log.exists() and log.with_suffix(".cpu").exists():
        return log.read_text(encoding="utf-8").split("\n--- stderr ---")[0], float(
            log.with_suffix(".cpu").read_text()
        )
    t0 = os.times()
    proc = subprocess.run(
        [sys.executable, "-m", "hystdisc", *args], capture_output=True, text=True, check=False
    )
    t1 = os.times()
    if log is not None:
        log.write_text(proc.stdout + "\n--- stderr ---\n" + proc.stderr, encoding="utf-8")
    if proc.returncode != 0:
        raise SystemExit(f"hystdisc {' '.join(args)} failed: {proc.stderr.strip()[-500:]}")
    cpu = (t1.children_user - t0.children_user) + (t1.children_system - t0.children_system)
    if log is not None:
        log.with_suffix(".cpu").write_text(f"{cpu:.3f}\n")
    return proc.stdout, cpu


def pooled_errors(pred_csv: Path) -> tuple[float, float]:
    """Pooled RMS force error (N) and NRMSE of a ``hystdisc predict`` output."""
    with pred_csv.open(encoding="utf-8") as fh:
        rows = [(float(r["torque"]), float(r["torque_pred"])) for r in csv.DictReader(fh)]
    y, p = np.array(rows, dtype=float).reshape(-1, 2).T
    return pooled_force_errors(y, p)


def pooled_force_errors(measured: np.ndarray, predicted: np.ndarray) -> tuple[float, float]:
    """Pooled RMS force error (N) and NRMSE (RMS error / RMS measured force) of samples
    pooled over several runs."""
    e = np.asarray(predicted, dtype=float) - np.asarray(measured, dtype=float)
    err2, ref2 = float(e @ e), float(np.asarray(measured, dtype=float) @ measured)
    return float(np.sqrt(err2 / e.size)), float(np.sqrt(err2 / ref2))


def full_set(files: list[str], work: Path, effects: bool) -> dict:
    out = work / "full"
    # the seed's flowchart too: per-current fits and the current laws (report section)
    args = ["discover", *files, "--rig", str(RIG), "--out", str(out), "--force", "--staged"]
    if not effects:
        args.append("--no-effects")
    t0 = time.perf_counter()
    stdout, cpu = hystdisc(*args, log=work / "full.log")
    wall = time.perf_counter() - t0
    res = _results(out / "results.json")
    return {"stdout": stdout, "wall": wall, "cpu": cpu, "results": res}


def fold(
    folder: Path,
    work: Path,
    name: str,
    groups: dict[str, list[Path]],
    effects: bool,
    families: str | None = None,
):
    """Discover without test ``name``; predict it with the final model and with every
    family's fit (Bingham among them: the baseline)."""
    train = [str(f) for k, fs in groups.items() if k != name for f in fs]
    test = [str(f) for f in groups[name]]
    out = work / f"without_{name}"
    args = ["discover", *train, "--rig", str(RIG), "--out", str(out), "--force", "--no-heldout"]
    if families:
        args += ["--families", families]
    if not effects:
        args.append("--no-effects")
    t0 = time.perf_counter()
    _, cpu = hystdisc(*args, log=work / f"without_{name}.log")
    wall = time.perf_counter() - t0
    res = _results(out / "results.json")
    row = {"test": name, "family": res.family, "effects": _names(res.effects)}
    row["cpu"] = cpu
    row["wall"] = wall
    labels = [("model", [])] + [(f, ["--family", f]) for f in res.families]
    for label, extra in labels:
        pred = work / f"pred_{name}_{label}.csv"
        hystdisc(
            "predict",
            str(out / "results.json"),
            *test,
            "--rig",
            str(RIG),
            "-o",
            str(pred),
            "--force",
            "--quiet",
            *extra,
        )
        row[label] = pooled_errors(pred)
    row["bingham"] = row.get("bingham", (float("nan"), float("nan")))
    return row


CURRENT_RE = re.compile(r"(\d+(?:x\d+)?)A$")


def per_current(groups: dict[str, list[Path]], work: Path, family: str) -> list[dict]:
    """``family`` fitted separately at each current (no current law): how much of the error
    is the family's shape, and how much the law linking the parameters to the current."""
    by_current: dict[str, list[str]] = defaultdict(list)
    for fs in groups.values():
        for f in fs:
            by_current[CURRENT_RE.search(f.stem).group(1)].append(str(f))
    rows = []
    for cur, files in sorted(by_current.items(), key=lambda kv: float(kv[0].replace("x", "."))):
        out = work / f"current_{cur}"
        args = ["discover", *files, "--rig", str(RIG), "--out", str(out), "--force"]
        hystdisc(
            *args,
            "--model",
            family,
            "--no-effects",
            "--no-heldout",
            "--quiet",
            log=work / f"current_{cur}.log",
        )
        res = _results(out / "results.json")
        rows.append(
            {
                "current": cur.replace("x", "."),
                "rms": res.families[family].rms,
                "runs": len(files),
            }
        )
    return rows


#: The small check the tests run (and this script reports): train on two tests, predict a
#: third at another amplitude and frequency.
CI_TRAIN = ("10mm1Hz", "25mm0x25Hz")
CI_TEST = "5mm3Hz"


def subset_validation(folder: Path, train=CI_TRAIN, test=CI_TEST, close_loop=False) -> dict:
    """Discover on the tests ``train`` and predict the test ``test`` (final model and the
    Bingham fit of the same run): the same as ``hystdisc discover`` + ``hystdisc predict``,
    in process."""
    from hystdisc.data import load
    from hystdisc.estimator import Discovery

    groups = tests_of(folder)
    files = [str(f) for k in train for f in groups[k]]
    c0 = time.process_time()
    disc = Discovery(heldout=False, close_loop=close_loop).fit(load(files, rig=str(RIG)))
    cpu = time.process_time() - c0
    ds = load([str(f) for f in groups[test]], rig=str(RIG))
    y = np.concatenate([r.torque for r in ds.runs])
    out = {"family": disc.family_, "effects": list(getattr(disc, "effects_", [])), "cpu": cpu}
    out["fit_rms"] = {k: f.rms for k, f in disc.family_fits_.items()}
    for label, fam in (("model", None), ("bingham", "bingham")):
        e = np.concatenate(disc.predict(ds, family=fam)) - y
        out[label] = (float(np.sqrt(np.mean(e**2))), float(np.sqrt(np.mean(e**2) / np.mean(y**2))))
    return out


def report(
    full: dict,
    rows: list[dict],
    effects: bool,
    currents: list[dict] | None = None,
    subset: dict | None = None,
) -> str:
    res = full["results"]
    fams = res.families
    lines = [
        "# UTFSM MR damper (30 driven sine tests, 0-1 A)",
        "",
        f"`hystdisc discover ../shared/data/utfsm_mr_damper --rig "
        f"data_synth/rigs/utfsm_mr_damper.toml`{'' if effects else ' --no-effects'}: "
        f"{full['wall']:.0f} s wall, {full['cpu']:.0f} s CPU (load average "
        f"{os.getloadavg()[0]:.1f} at the end). Selected: **{res.family}**"
        + (f" + {', '.join(_names(res.effects))}" if res.effects else "")
        + ".",
        "",
        "Family table (held-out RMS: each of the six test conditions predicted by the fit "
        "without it, estimated inside the run from the joint optimum):",
        "",
        "| family | RMS force error (N) | held-out RMS (N) | BIC | physical |",
        "|---|---:|---:|---:|---|",
    ]
    for name, f in fams.items():
        star = " *" if name == res.family else ""
        ho = f.heldout_rms
        phys = (
            "yes" if f.admissible else ("no: " + "; ".join(f.violations) if f.violations else "-")
        )
        lines.append(
            f"| {name}{star} | {f.rms:.1f} | {'-' if ho is None else f'{ho:.1f}'} | {f.bic:.0f} "
            f"| {phys} |"
        )
    if res.selection_note:
        lines += ["", f"Selection: {res.selection_note}."]
    tried = res.effects_tried or []
    if tried:
        lines += [
            "",
            "Closing loop (RMS force error before -> after the refit with the effect):",
            "",
            "| effect | accepted | RMS before (N) | RMS after (N) | held-out before (N) "
            "| held-out after (N) | note |",
            "|---|---|---:|---:|---:|---:|---|",
        ]
        nan = float("nan")

        def num(x):
            return f"{x:.1f}" if x is not None else "-"

        for s in tried:
            before = s.rms_before if s.rms_before is not None else nan
            after = s.rms_after if s.rms_after is not None else nan
            lines.append(
                f"| {s.name} | {'yes' if s.accepted else 'no'} | {before:.1f} | {after:.1f} | "
                f"{num(s.heldout_rms_before)} | {num(s.heldout_rms_after)} | {s.note or ''} |"
            )
    if res.unexplained_text:
        lines += ["", f"Residual: {res.unexplained_text}"]
    if currents:
        fam = res.family
        pooled = np.sqrt(np.mean([c["rms"] ** 2 for c in currents]))
        lines += [
            "",
            f"{fam} fitted separately at each current (no law linking its parameters to the "
            f"current; `--model {fam}` on the six files of one current): RMS force error in N. "
            f"The joint fit above reaches {fams[fam].rms:.1f} N with the parameters linear "
            "in the current.",
            "",
            "| current (A) | " + " | ".join(c["current"] for c in currents) + " | pooled |",
            "|---|" + "---:|" * (len(currents) + 1),
            "| RMS (N) | " + " | ".join(f"{c['rms']:.1f}" for c in currents) + f" | {pooled:.1f} |",
        ]
    if rows:
        fam_names = list(res.families)
        lines += [
            "",
            "Leave one test condition out (discover on the other 25 files, `hystdisc predict` "
            "on the five left-out files with the final model and with each family's fit; "
            "NRMSE = RMS force error / RMS force over the five files):",
            "",
            "| left-out test | selected (+ effects) | final | "
            + " | ".join(fam_names)
            + " | CPU (s) |",
            "|---|---|---:|" + "---:|" * len(fam_names) + "---:|",
        ]
        for r in rows:
            fam = r["family"] + (f" + {', '.join(r['effects'])}" if r["effects"] else "")
            cells = " | ".join(f"{r[f][1]:.1%}" if f in r else "-" for f in fam_names)
            lines.append(
                f"| {r['test']} | {fam} | {r['model'][1]:.1%} | {cells} | {r['cpu']:.0f} |"
            )
        # a family the folds did not compare (--fold-families) has no mean
        mean = {
            k: np.mean([r[k][1] for r in rows if k in r])
            for k in ["model", *fam_names]
            if any(k in r for r in rows)
        }
        cells = " | ".join(f"{mean[f]:.1%}" if f in mean else "-" for f in fam_names)
        lines.append(f"| mean | | **{mean['model']:.1%}** | {cells} | |")
        best = min((f for f in fam_names if f in mean), key=lambda f: mean[f])
        lines += [
            "",
            f"Mean leave-one-condition-out NRMSE of the final model {mean['model']:.1%}; best "
            f"single family {best} {mean[best]:.1%}; Bingham {mean.get('bingham', float('nan')):.1%}.",
        ]
    if subset:
        lines += [
            "",
            f"Small check run by `tests/end_to_end/test_measured.py` (in process, all five families, no "
            f"loop): discover on {' + '.join(CI_TRAIN)} (10 files), predict {CI_TEST}: selected "
            f"{subset['family']} (fit RMS {subset['fit_rms'][subset['family']]:.1f} N), "
            f"held-out RMS {subset['model'][0]:.1f} N, NRMSE {subset['model'][1]:.1%}; Bingham "
            f"{subset['bingham'][0]:.1f} N, NRMSE {subset['bingham'][1]:.1%}; "
            f"{subset['cpu']:.0f} s CPU.",
        ]
    return "\n".join(lines) + "\n"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=os.environ.get("HYSTDISC_DATA", "../shared/data"))
    ap.add_argument("--work", default="/tmp/hystdisc_mr_damper", help="folder for the outputs")
    ap.add_argument("--out", default=str(ROOT / "benchmarks" / "results" / "mr_damper.md"))
    ap.add_argument("--folds", type=int, default=6, help="how many left-out tests (0-6)")
    ap.add_argument("--no-effects", action="store_true", help="skip the closing loop")
    ap.add_argument("--tests", help="comma-separated subset of tests, e.g. 10mm1Hz,2mm5Hz")
    ap.add_argument(
        "--fold-families",
        help="families the left-out folds compare (default: all; e.g. bingham,bouc-wen-std,spencer)",
    )
    ap.add_argument("--no-per-current", action="store_true", help="skip the per-current fits")
    ap.add_argument(
        "--reuse", action="store_true", help="keep the outputs an interrupted run left in --work"
    )
    args = ap.parse_args(argv)
    global REUSE
    REUSE = args.reuse
    folder = Path(args.data) / "utfsm_mr_damper"
    if not folder.is_dir():
        print(f"{folder}: not found; fix: set HYSTDISC_DATA", file=sys.stderr)
        return 2
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    effects = not args.no_effects
    groups = tests_of(folder)
    if args.tests:
        groups = {k: v for k, v in groups.items() if k in args.tests.split(",")}
    files = [str(folder)] if len(groups) == 6 else [str(f) for fs in groups.values() for f in fs]
    print(f"full set: {sum(map(len, groups.values()))} files", file=sys.stderr, flush=True)
    full = full_set(files, work, effects)
    print(full["stdout"], file=sys.stderr, flush=True)
    print("per-current fits", file=sys.stderr, flush=True)
    currents = [] if args.no_per_current else per_current(groups, work, full["results"].family)
    rows = []
    for name in list(groups)[: args.folds]:
        print(f"leave out {name}", file=sys.stderr, flush=True)
        rows.append(fold(folder, work, name, groups, effects, args.fold_families))
        Path(args.out).write_text(report(full, rows, effects, currents), encoding="utf-8")
    subset = subset_validation(folder) if len(groups) == 6 else None
    text = report(full, rows, effects, currents, subset)
    Path(args.out).write_text(text, encoding="utf-8")
    print(text)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
