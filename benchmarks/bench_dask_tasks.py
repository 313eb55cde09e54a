"""Benchmark (issue 36): one discovery's tasks on threads and on a Dask cluster.

Times one discovery (:class:`hystdisc.Discovery`, in process) of a bundled dataset in four
ways, within one run:

- threads, ``n_jobs=1`` (the reference of every ratio) and ``n_jobs=2``;
- a ``LocalCluster`` of 1 and of 2 worker processes (one thread each), the tasks sent
  there with ``Discovery(scheduler=client, n_jobs=1)``.

Each way is warmed up once (numba's on-disk cache loaded in every process), then timed
``--repeats`` times, the ways alternated in each repeat (so a change of the machine's load
falls on all of them); the table gives the median wall time, this process's CPU time (the
workers' is not in it) and the speed-up against ``n_jobs=1``. The clusters are started
before the timing (their start-up is printed apart) and the client is connected once (an
address would add its connection to every fit). Every ``results.json`` is compared with the
reference's: the ways must give the same answer, bit for bit.

Run:  python benchmarks/bench_dask_tasks.py [--data data_synth/bouc-wen.csv] [--repeats 3]
      [--families dahl,bingham] [--no-effects]
      (prints a Markdown section; nothing is written)
"""

from __future__ import annotations

import argparse
import logging
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], cwd=ROOT,
                             capture_output=True, text=True, check=True)  # fmt: skip
    except (OSError, subprocess.CalledProcessError):
        return "unknown"
    dirty = subprocess.run(["git", "status", "--porcelain", "--", "hystdisc"], cwd=ROOT,
                           capture_output=True, text=True, check=False).stdout.strip()  # fmt: skip
    return out.stdout.strip() + (" (hystdisc/ modified)" if dirty else "")


def _fit(data, options: dict, **engine) -> tuple[float, float, str, str]:
    """Wall and CPU time (s) of one discovery, its family and its results.json text."""
    from hystdisc import Discovery

    t0, c0 = time.perf_counter(), time.process_time()
    disc = Discovery(**options, **engine).fit(data)
    return time.perf_counter() - t0, time.process_time() - c0, disc.family_, disc.results_.to_json()


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--data", default=str(ROOT / "data_synth" / "bouc-wen.csv"))
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--families", help="comma-separated (default: every family)")
    p.add_argument("--no-effects", action="store_true", help="no closing loop")
    args = p.parse_args(argv)

    import dask
    import distributed
    from distributed import Client, LocalCluster

    from hystdisc import __version__
    from hystdisc.data import load

    options: dict = {}
    if args.families:
        options["families"] = args.families.split(",")
    if args.no_effects:
        options["close_loop"] = False
    data = load(args.data)
    load0 = os.getloadavg()

    clusters, clients, started = {}, {}, {}
    for n in (1, 2):
        t0 = time.perf_counter()
        clusters[n] = LocalCluster(n_workers=n, threads_per_worker=1, processes=True,
                                   dashboard_address=":0", silence_logs=logging.ERROR)  # fmt: skip
        clients[n] = Client(clusters[n], set_as_default=False)
        clients[n].wait_for_workers(n)
        started[n] = time.perf_counter() - t0
    ways = {
        "threads, n_jobs=1": {"n_jobs": 1},
        "threads, n_jobs=2": {"n_jobs": 2},
        "LocalCluster, 1 worker": {"n_jobs": 1, "scheduler": clients[1]},
        "LocalCluster, 2 workers": {"n_jobs": 1, "scheduler": clients[2]},
    }
    try:
        for name, engine in ways.items():  # warm-up: every process loads numba's cache
            wall, _, _, _ = _fit(data, options, **engine)
            print(f"warm-up {name}: {wall:.2f} s", file=sys.stderr, flush=True)
        walls = {name: [] for name in ways}
        cpus = {name: [] for name in ways}
        answers: dict[str, set] = {name: set() for name in ways}
        for rep in range(args.repeats):
            for name, engine in ways.items():
                wall, cpu, family, text = _fit(data, options, **engine)
                walls[name].append(wall)
                cpus[name].append(cpu)
                answers[name].add(text)
                print(f"repeat {rep + 1} {name}: {wall:.2f} s wall, {family}", file=sys.stderr,
                      flush=True)  # fmt: skip
    finally:
        for n in clients:
            clients[n].close()
            clusters[n].close()
    load1 = os.getloadavg()

    ref_name = "threads, n_jobs=1"
    ref = statistics.median(walls[ref_name])
    reference = answers[ref_name]
    same = all(a == reference for a in answers.values()) and len(reference) == 1
    rel = os.path.relpath(args.data, ROOT)
    cmd = "python benchmarks/bench_dask_tasks.py" + "".join(
        f" {a}" for a in (argv if argv is not None else sys.argv[1:])
    )
    print(f"Command: `{cmd}` at commit {_commit()} (hystdisc {__version__}, dask "
          f"{dask.__version__}, distributed {distributed.__version__}, Python "
          f"{sys.version.split()[0]}); data `{rel}`, options {options or 'the defaults'}; "
          f"{os.cpu_count()} CPUs, load average {load0[0]:.2f} before and {load1[0]:.2f} "
          f"after; median of {args.repeats} runs after a warm-up, the ways alternated.\n")  # fmt: skip
    print(
        "| engine | wall (s), median | runs (s) | CPU of this process (s) | speed-up vs n_jobs=1 |"
    )
    print("|---|---|---|---|---|")
    for name in ways:
        w = statistics.median(walls[name])
        runs = ", ".join(f"{x:.2f}" for x in walls[name])
        print(f"| {name} | {w:.2f} | {runs} | {statistics.median(cpus[name]):.2f} | "
              f"{ref / w:.2f}x |")  # fmt: skip
    print(f"\nCluster start-up (not in the table): 1 worker {started[1]:.1f} s, 2 workers "
          f"{started[2]:.1f} s. Same results.json in every run and way: "
          f"{'yes' if same else 'NO'}.")  # fmt: skip
    return 0 if same else 1


if __name__ == "__main__":
    sys.exit(main())
