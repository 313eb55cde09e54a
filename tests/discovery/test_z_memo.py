"""The trajectories ``EqData.z_flat`` keeps: a repeated search is the same search, for free."""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest

import hystdisc
import hystdisc.discovery.data as eqdata
from hystdisc.discovery import EqData, family_start
from hystdisc.models.shapes import SHAPES


def _eq() -> EqData:
    """Two driven runs of a Bouc-Wen-like damper at two currents."""
    t = np.linspace(0.0, 4.0, 2001)
    th, w = 0.1 * np.sin(3 * t), 0.3 * np.cos(3 * t)
    runs = [(1.0 + i) * np.tanh(w / 0.05) + (0.5 + i) * w for i in (0.0, 1.0)]
    return EqData(
        "driven", [t, t], [th, th], [w, w], [0 * t, 0 * t], runs, np.array([0.0, 1.0]),
        [np.ones(t.size, dtype=bool)] * 2, scale=0.1,
    )  # fmt: skip


@pytest.fixture
def integrations(monkeypatch):
    """Count the ``z`` integrations ``EqData`` runs."""
    calls = []
    real = eqdata.integrate_z_flat

    def counted(*args):
        calls.append(1)
        return real(*args)

    monkeypatch.setattr(eqdata, "integrate_z_flat", counted)
    return calls


def test_a_repeated_search_integrates_nothing_and_gives_the_same_bits(integrations):
    eq = _eq()
    first = family_start(eq, "bouc-wen-std", ["1"])
    n_first = len(integrations)
    again = family_start(eq, "bouc-wen-std", ["1"])
    assert n_first > 80  # the shape's grid and the Nelder-Mead search
    assert len(integrations) == n_first  # every trajectory was kept
    assert again == first
    # and the memo changes no number: a fresh copy of the data gives the same start
    assert family_start(_eq(), "bouc-wen-std", ["1"]) == first


def test_the_kept_trajectories_are_read_only_and_equal_to_a_fresh_integration():
    eq = _eq()
    s = np.array([np.log(20.0), 0.3, 0.0])
    z = eq.z_flat(SHAPES["bouc-wen-std"], s)
    assert eq.z_flat(SHAPES["bouc-wen-std"], s.copy()) is z
    assert not z.flags.writeable
    with pytest.raises(ValueError, match="read-only"):
        z[0] = 1.0
    np.testing.assert_array_equal(_eq().z_flat(SHAPES["bouc-wen-std"], s), z)


def test_the_memo_stays_within_its_budget_and_is_not_pickled(monkeypatch):
    eq = _eq()
    nbytes = 2 * 2001 * 8
    monkeypatch.setattr(eqdata, "Z_MEMO_BYTES", 3 * nbytes)
    for r in range(6):
        eq.z_flat(SHAPES["dahl"], np.array([float(r)]))
    assert eq.memo_size() == 3
    copy = pickle.loads(pickle.dumps(eq))
    assert copy.memo_size() == 0
    np.testing.assert_array_equal(
        copy.z_flat(SHAPES["dahl"], np.array([5.0])), eq.z_flat(SHAPES["dahl"], np.array([5.0]))
    )


def test_a_fitted_discovery_keeps_its_data_but_not_the_memo():
    csv = Path(__file__).resolve().parents[2] / "data_synth" / "bouc-wen.csv"
    # a declared family: stage 1 and its fit fill the memo (about 900 trajectories on this
    # set, against about 1000 for every family) before the fitted estimator drops it
    disc = hystdisc.Discovery(model="bouc-wen", close_loop=False, heldout=False).fit(
        hystdisc.load(str(csv))
    )
    assert disc.eq_data_.t  # the equation-error data stay with the estimator
    assert disc.eq_data_.memo_size() == 0
