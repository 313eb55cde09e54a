"""Scenarios: TOML files holding the settings of ``hystdisc simulate``, read and checked.

A scenario names a model (``model``, ``[params]``, ``[effects.<name>]``) and the settings
of :func:`~hystdisc.simulation.synth.generate`; ``data_synth/`` holds one per bundled
dataset, with the CSV it makes (``output``). :func:`load_scenario` reads one,
:func:`generate_from_scenario` makes its dataset.

Examples
--------
>>> sc = normalize_scenario({"model": "dahl", "currents": [0, 1], "duration": 1})
>>> scenario_model(sc).family.name, sc["currents"], sc["duration"]
('dahl', [0.0, 1.0], 1.0)
"""

from __future__ import annotations

import os
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from hystdisc.data import Dataset, parse_toml
from hystdisc.errors import HystdiscError
from hystdisc.models import Model
from hystdisc.simulation.synth import generate
from hystdisc.simulation.synth_checks import (
    check_currents,
    check_input_spec,
    check_number,
    parse_drive,
)

__all__ = [
    "SCENARIO_KEYS",
    "generate_from_scenario",
    "load_scenario",
    "normalize_scenario",
    "scenario_model",
]

SCENARIO_KEYS = (
    "model",
    "declared",
    "description",
    "params",
    "effects",
    "currents",
    "experiment",
    "theta0",
    "duration",
    "fs",
    "noise",
    "theta_noise",
    "delay",
    "seed",
    "encoder_counts",
    "spikes",
    "prefilter",
    "drives",
    "input",
    "output",
)
"""Keys a scenario TOML may hold (``declared`` and ``description`` are informative only)."""


def _scenario_error(source: str, problem: str, fix: str) -> HystdiscError:
    return HystdiscError(f"{source}: {problem}; fix: {fix}")


def _effect_params(name: str, ep: Any, source: str) -> dict[str, float]:
    """One ``[effects.<name>]`` table of a scenario, its values as numbers."""
    if not isinstance(ep, Mapping):
        raise _scenario_error(
            source,
            f"effects.{name} must be a table",
            f"write [effects.{name}] and its parameters below it",
        )
    return {str(k): check_number(v, f"effect {name} parameter {k}") for k, v in ep.items()}


def load_scenario(path: str | os.PathLike[str]) -> dict[str, Any]:
    """Read a scenario TOML file (the settings of ``hystdisc simulate``).

    Keys: ``model`` (family), ``[params]``, ``[effects.<name>]`` tables (an empty table
    takes the effect's defaults), ``currents``, ``experiment``, ``theta0``, ``duration``,
    ``fs``, ``noise``, ``theta_noise``, ``delay`` (s), ``seed``, ``encoder_counts``,
    ``spikes`` (``[N, SIZE]``), ``[prefilter]`` (a rig's ``[filter]`` table), ``drives`` (tables
    ``{amplitude, frequency}`` or ``"A@f"`` strings), ``[input]``, ``output`` (CSV file
    name, relative to the scenario file) and the informative ``declared`` (the family a
    user would declare for these data) and ``description``. Unknown keys are an error.

    Returns
    -------
    dict
        The settings, plus ``path`` (the scenario file) and ``output`` resolved against the
        scenario's folder. Settings not given are absent (the defaults of
        :func:`~hystdisc.simulation.synth.generate` apply).

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = pathlib.Path(d, "s.toml")
    ...     _ = p.write_text('model = "dahl"\\noutput = "dahl.csv"\\n[params]\\nrho = 15\\n')
    ...     sc = load_scenario(p)
    ...     print(sc["model"], sc["params"], pathlib.Path(sc["output"]).name)
    dahl {'rho': 15.0} dahl.csv
    """
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except FileNotFoundError:
        raise _scenario_error(source, "file does not exist", "check the path") from None
    except UnicodeDecodeError as exc:
        raise _scenario_error(
            source,
            f"is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at offset {exc.start})",
            "save the scenario as UTF-8 text (TOML)",
        ) from None
    except OSError as exc:
        raise _scenario_error(
            source, f"cannot be read ({exc.strerror or exc})", "check the path"
        ) from None
    sc = normalize_scenario(parse_toml(text, source), source)
    sc["path"] = source
    if "output" in sc:
        sc["output"] = str(Path(path).parent / sc["output"])
    return sc


def normalize_scenario(raw: Mapping[str, Any], source: str = "scenario") -> dict[str, Any]:
    """Check the keys and value types of a scenario table (see :func:`load_scenario`)."""
    for key in raw:
        if key not in SCENARIO_KEYS:
            raise _scenario_error(
                source, f"unknown key '{key}'", f"use only {', '.join(SCENARIO_KEYS)}"
            )
    sc: dict[str, Any] = {}
    for key in ("model", "declared", "description", "experiment", "output"):
        if key in raw:
            if not isinstance(raw[key], str):
                raise _scenario_error(source, f"{key} = {raw[key]!r} is not text", "quote it")
            sc[key] = raw[key]
    if "output" in sc and (not sc["output"].strip() or "\x00" in sc["output"]):
        raise _scenario_error(
            source,
            f"output = {sc['output']!r} is not a usable file name",
            'name the CSV file, e.g. output = "dahl.csv"',
        )
    params = raw.get("params", {})
    if not isinstance(params, Mapping):
        raise _scenario_error(source, "params must be a table", "write [params] then k_s = 158")
    try:
        sc["params"] = {str(k): check_number(v, f"parameter {k}") for k, v in params.items()}
        effects = raw.get("effects", {})
        if isinstance(effects, list):  # effects = ["coulomb", ...] takes the defaults
            effects = {str(e): {} for e in effects}
        if not isinstance(effects, Mapping):
            raise _scenario_error(
                source, "effects must be a table", "write [effects.coulomb] then f_c = 0.3"
            )
        sc["effects"] = {
            str(name): _effect_params(name, ep, source) for name, ep in effects.items()
        }
        if "currents" in raw:
            sc["currents"] = check_currents(raw["currents"])
        for key in ("duration", "fs", "noise", "theta_noise", "delay"):
            if key in raw:
                sc[key] = check_number(raw[key], key)
        if "theta0" in raw:
            v = raw["theta0"]
            sc["theta0"] = (
                [check_number(x, "theta0") for x in v]
                if isinstance(v, list)
                else check_number(v, "theta0")
            )
        if "spikes" in raw:
            v = raw["spikes"]
            if not (isinstance(v, list) and len(v) == 2):
                raise _scenario_error(
                    source, f"spikes = {v!r} is not [N, SIZE]", "write spikes = [6, 0.05]"
                )
            sc["spikes"] = (v[0], check_number(v[1], "spike size", positive=True))
        for key in ("seed", "encoder_counts"):
            if key in raw:
                v = raw[key]
                if isinstance(v, bool) or not isinstance(v, int):
                    raise _scenario_error(
                        source, f"{key} = {v!r} is not a whole number", "give an integer"
                    )
                sc[key] = v
        if "prefilter" in raw:  # checked by generate (simulation.prefilter)
            sc["prefilter"] = raw["prefilter"]
        if "drives" in raw:
            if not isinstance(raw["drives"], list):
                raise _scenario_error(
                    source,
                    "drives must be a list",
                    'write drives = [{amplitude = 0.3, frequency = 1.0}] or ["0.3@1.0"]',
                )
            sc["drives"] = [parse_drive(d) for d in raw["drives"]]
        if "input" in raw:
            sc["input"] = check_input_spec(raw["input"])
    except HystdiscError as exc:
        msg = str(exc)
        raise HystdiscError(msg if msg.startswith(source) else f"{source}: {msg}") from None
    return sc


def scenario_model(scenario: Mapping[str, Any]) -> Model:
    """The :class:`~hystdisc.models.Model` a scenario describes (demo defaults if unset)."""
    if "model" not in scenario:
        raise HystdiscError(
            f'{scenario.get("path", "scenario")}: no model given; fix: add model = "bouc-wen" '
            "(or pass --model)"
        )
    return Model(scenario["model"], scenario.get("params") or {}, scenario.get("effects") or {})


def generate_from_scenario(scenario: Mapping[str, Any]) -> Dataset:
    """Generate the dataset a scenario (from :func:`load_scenario`) describes.

    Examples
    --------
    >>> ds = generate_from_scenario({"model": "lugre", "currents": [0, 1], "duration": 1.0})
    >>> len(ds), ds[0].n
    (2, 1000)
    """
    model = scenario_model(scenario)
    kw: dict[str, Any] = {}
    for key in (
        "experiment",
        "currents",
        "duration",
        "fs",
        "theta0",
        "noise",
        "seed",
        "encoder_counts",
        "drives",
        "theta_noise",
        "delay",
        "spikes",
        "prefilter",
    ):
        if scenario.get(key) is not None:
            kw[key] = scenario[key]
    if scenario.get("input") is not None:
        kw["input_spec"] = scenario["input"]
    try:
        return generate(model, **kw)
    except HystdiscError as exc:
        where = scenario.get("path")
        msg = str(exc)
        raise HystdiscError(
            f"{where}: {msg}" if where and not msg.startswith(where) else msg
        ) from None
