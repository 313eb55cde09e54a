"""Compiled simulations on threads (``hystdisc.simulation.parallel``).

The bitwise equality of a batch on threads and in turn is tested where the batches live
(``simulation/test_sensitivity.py`` for the term kernels, ``fitting/test_system_jacobian.py``
for the state-space integrator); here: how a batch is cut, the limit, a forked child, and the
discovery's threads (stage 1 and the first fits side by side).
"""

from __future__ import annotations

import multiprocessing
import threading

import numpy as np
import pytest

import hystdisc.simulation.batch as batch
from hystdisc import Discovery
from hystdisc.models import Model
from hystdisc.simulation.batch import integrate_z_flat
from hystdisc.simulation.parallel import (
    chunk_bounds,
    limit_threads,
    map_after,
    map_entries,
    map_tasks,
    n_threads,
)
from hystdisc.simulation.synth import generate


def test_chunks_are_contiguous_balanced_by_samples_and_never_too_small():
    off = np.concatenate([[0], np.cumsum([100, 100, 100, 700])])
    with limit_threads(2):
        # half the samples lie in the last entry: it is a chunk of its own
        assert chunk_bounds(off, 10) == [0, 3, 4]
        assert chunk_bounds(off, 600) == [0, 4]  # 1000 samples: one chunk of 600 at most
    with limit_threads(1):
        assert chunk_bounds(off, 10) == [0, 4]
    with limit_threads(8):
        bounds = chunk_bounds(off, 1)
        assert bounds[0] == 0 and bounds[-1] == 4 and bounds == sorted(set(bounds))
        assert len(bounds) - 1 <= min(n_threads(), 4)


def test_the_limit_is_restored_after_the_block():
    before = n_threads()  # the usable CPUs (at most 4)
    with limit_threads(1):
        assert n_threads() == 1
        with limit_threads(3):
            assert n_threads() == 3  # a limit, not the CPUs: at most MAX_THREADS (4)
        assert n_threads() == 1
    assert n_threads() == before


def test_two_threads_keep_their_own_limits_and_their_workers_inherit_them():
    """Two discoveries on two threads, each inside its own limit at the same time (a
    barrier holds both inside their blocks): each sees its own limit, and so does every
    worker its maps hand work to (a worker thread does not inherit a context variable
    unless the map copies the caller's context into it)."""
    inside = threading.Barrier(2, timeout=120)
    seen: dict[int, list[int]] = {}
    errors: list[BaseException] = []

    def discovery(limit: int) -> None:
        try:
            with limit_threads(limit):
                inside.wait()  # both limits are set now
                own = n_threads()
                tasks = map_tasks(lambda _: n_threads(), [0, 1, 2], n_jobs=2)
                entries = map_entries(lambda _: n_threads(), list(range(6)))
                firsts, afters = map_after(
                    lambda _: n_threads(), [0, 1], lambda _, ready: n_threads(), [0, 1], 2
                )
                inside.wait()  # neither has left its block yet
                seen[limit] = [own, *tasks, *entries, *firsts, *afters]
        except BaseException as exc:  # noqa: BLE001 - reported by the test thread
            errors.append(exc)
            inside.abort()

    before = n_threads()
    threads = [threading.Thread(target=discovery, args=(k,)) for k in (1, 3)]
    for th in threads:
        th.start()
    for th in threads:
        th.join()
    assert not errors, errors
    assert seen[1] == [1] * 14
    assert seen[3] == [3] * 14
    assert n_threads() == before  # this thread never had a limit


def _z_of_batch() -> np.ndarray:
    t = np.tile(np.linspace(0.0, 2.0, 2001), 4)
    off = np.arange(5) * 2001
    return integrate_z_flat(np.array([10.0, -10.0, 0, 0, 0]), 1.0, t, np.cos(3 * t), off)


def _child(_: int) -> float:
    batch.CHUNK_SAMPLES = 1000
    with limit_threads(2):
        return float(_z_of_batch().sum())


@pytest.mark.skipif(
    "fork" not in multiprocessing.get_all_start_methods(), reason="no fork on this platform"
)
def test_a_forked_child_runs_chunked_batches_on_a_pool_of_its_own(monkeypatch):
    # the parent's pool exists (its threads are not copied into a forked child)
    monkeypatch.setattr(batch, "CHUNK_SAMPLES", 1000)
    with limit_threads(2):
        want = float(_z_of_batch().sum())
    with multiprocessing.get_context("fork").Pool(1) as pool:
        got = pool.apply_async(_child, (0,)).get(timeout=120)
    assert got == want


def test_an_after_task_starts_before_every_before_task_has_ended():
    # before(0) can only end once after(0) has run: after(0) needs only before(1), so on
    # two threads it starts as soon as before(1) ends (waiting for all would deadlock)
    gate = threading.Event()

    def before(k):
        if k == 0:
            assert gate.wait(timeout=30), "after(0) did not start while before(0) ran"
        return 10 * k

    def after(j, ready):
        value = ready(1)
        gate.set()
        return value + j

    assert map_after(before, [0, 1], after, [0, 5], 2) == ([0, 10], [10, 15])


def test_discovery_answers_the_same_on_one_thread_and_two():
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=3, noise=1e-3, seed=4)
    kw = dict(families=["bingham", "dahl"], close_loop=False, n_starts=1, heldout=False)
    one = Discovery(n_jobs=1, **kw).fit(data)
    two = Discovery(n_jobs=2, **kw).fit(data)
    for name in ("bingham", "dahl"):
        assert one.family_fits_[name].params == two.family_fits_[name].params
        assert one.family_fits_[name].rms == two.family_fits_[name].rms
    assert one.discovered_fit_.rms == two.discovered_fit_.rms
    assert {s: f.s.tolist() for s, f in one.stage1_.items()} == {
        s: f.s.tolist() for s, f in two.stage1_.items()
    }
