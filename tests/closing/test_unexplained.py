"""Beyond the catalogue: structure no effect explains is named, not patched
(a file of its own so that the closing tests spread over the test workers)."""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc.data import Dataset, Run
from hystdisc.discovery import FAMILY_SHAPE
from hystdisc.estimator import Discovery
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

NOISE = 1e-3
CURRENTS = (0.0, 0.5, 1.0)


def _discover(data: Dataset, family: str) -> Discovery:
    return Discovery(model=family, heldout=False, shapes=(FAMILY_SHAPE[family],)).fit(data)


def test_second_resonance_is_unexplained():
    """A lightly damped 6 Hz mode of the rig (not in the catalogue) is named, not patched."""
    f0, zeta, amp = 6.0, 0.03, 4e-3
    base = generate(Model("lugre"), currents=CURRENTS, duration=3.0, noise=NOISE, seed=77)
    w = 2 * np.pi * f0
    runs = [
        Run(r.name, r.t, r.theta + amp * np.exp(-zeta * w * r.t) * np.sin(w * r.t), r.current)
        for r in base.runs
    ]
    disc = _discover(Dataset(runs, "release", "lugre with a second mode"), "lugre")
    res = disc.results_
    assert res.unexplained is True
    assert res.residual["dominant_hz"] == pytest.approx(f0, rel=0.10)
    assert res.residual["whiteness_p"] < 0.01
    assert "resonance near 6.0 Hz" in res.unexplained_text
    assert "no catalogued effect explains" in res.unexplained_text
    assert disc.effects_ == []
    assert "Unexplained: a resonance near 6.0 Hz" in res.report()
