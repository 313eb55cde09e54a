"""The damper of a ``results.json`` as a python-control system (:func:`load_control`).

The export itself is :func:`hystdisc.apply.control.to_control`;
:meth:`hystdisc.results.Results.to_control` does the same on a results object.

Examples
--------
>>> from hystdisc.models import Model
>>> from hystdisc.simulation.synth import generate
>>> from hystdisc import Discovery
>>> data = generate(Model("dahl"), "driven", currents=(0.0, 1.0), duration=1.0, seed=0)
>>> d = Discovery(model="dahl", heldout=False, close_loop=False, n_starts=1).fit(data)
>>> path = d.results_.save(getfixture("tmp_path") / "results.json")
>>> sys = load_control(path)
>>> sys.input_labels, sys.output_labels
(['theta', 'theta_dot', 'current'], ['torque'])
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from hystdisc.results.results import Results


def load_control(path: str | Path, family: str | None = None, name: str = "damper") -> Any:
    """The fitted damper of a ``results.json`` as a ``control.NonlinearIOSystem``.

    Parameters
    ----------
    path : str or Path
        A ``results.json`` written by ``hystdisc discover``.
    family : str, optional
        A family's own fit; default: the final model (selected family with its effects).
    name : str
        The system's name in an interconnection.

    Returns
    -------
    control.NonlinearIOSystem
        Inputs ``theta, theta_dot, current``, output ``torque``, the model's states
        (:func:`hystdisc.apply.control.to_control`).

    Raises
    ------
    HystdiscError
        For an unreadable file, a model that is not exportable, or without python-control.
    """
    return Results.load(path).to_control(family, name=name)
