"""Fuzzing scenario files (``load_scenario``, ``scenario_model``, ``generate_from_scenario``)
and ``generate``'s sizes. See ``tests/fuzz``."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from hystdisc.data import EXPERIMENTS, Dataset
from hystdisc.errors import HystdiscError
from hystdisc.models import FAMILIES, Model
from hystdisc.simulation.scenarios import (
    SCENARIO_KEYS,
    generate_from_scenario,
    load_scenario,
    scenario_model,
)

from ..fuzz import attempt, check_error, fuzz_settings
from ..fuzz.toml import TOML_ANY, maybe, often, to_toml

#: the inputs tried per reader, printed after the module (tests/conftest.py)
pytestmark = pytest.mark.usefixtures("fuzz_counts")


_PARAM_NAMES = sorted({p.name for f in FAMILIES.values() for p in f.params} | {"k_s", "J", "bogus"})

_SCENARIO_JUNK = {
    "model": maybe(st.sampled_from([*FAMILIES, "Dahl", "bouc_wen", "spring"])),
    "declared": maybe(st.sampled_from(list(FAMILIES))),
    "description": TOML_ANY,
    "params": maybe(
        st.dictionaries(
            st.sampled_from(_PARAM_NAMES),
            maybe(st.floats(-5, 200) | st.sampled_from([0, 1e9, 1e12, -1e-9, 1e-300, 1e300])),
            max_size=3,
        )
    ),
    "effects": maybe(
        st.dictionaries(
            st.sampled_from(["coulomb", "current_viscous", "offset", "cubic_stiffness", "warp"]),
            st.dictionaries(
                st.sampled_from(["f_c", "c_i", "theta_off", "k_3", "zz"]),
                maybe(st.floats(-2, 2) | st.sampled_from([1e300, -1e300])),
                max_size=2,
            ),
            max_size=2,
        )
        | st.lists(st.sampled_from(["coulomb", "offset", "nope"]), max_size=2)
    ),
    "currents": maybe(st.lists(st.floats(-0.5, 2), max_size=3) | st.floats(0, 1)),
    "experiment": maybe(st.sampled_from([*EXPERIMENTS, "free"])),
    "theta0": maybe(st.floats(-1, 1) | st.lists(st.floats(-1, 1), max_size=3) | st.just(1e300)),
    "duration": maybe(st.sampled_from([0.05, 0.2, 0.0, -1.0, 1e-6, 1e300])),
    "fs": maybe(st.sampled_from([200.0, 1000.0, 1.0, 0.0, 1e300])),
    "noise": maybe(st.sampled_from([0.0, 1e-3, -1.0, 1e3, 1e300])),
    "theta_noise": maybe(st.sampled_from([0.0, 1e-3, -1.0])),
    "seed": maybe(st.integers(-3, 2**63 - 1)),
    "encoder_counts": maybe(st.integers(-2, 5000) | st.just(2**63 - 1)),
    "drives": maybe(
        st.lists(
            st.sampled_from(["0.3@1", "x@1", "1", "-1@2", "0.1@0", "1e300@1e300"])
            | st.fixed_dictionaries(
                {"amplitude": maybe(st.floats(-1, 1)), "frequency": maybe(st.floats(0, 5))}
            ),
            max_size=2,
        )
    ),
    "input": maybe(
        st.fixed_dictionaries(
            {"kind": st.sampled_from(["multisine", "sine", "chirp"])},
            optional={
                "rms": maybe(st.floats(0, 20)),
                "f_min": maybe(st.floats(0, 10)),
                "f_max": maybe(st.floats(0, 10)),
                "amplitude": st.floats(0, 5),
                "frequency": st.floats(0, 5),
            },
        )
    ),
    "output": maybe(
        st.sampled_from(["out.csv", "sub/out.csv", "", " ", "a\x00b.csv", "../x.csv", "é.csv"])
    ),
    "colour": st.text(max_size=3),
}


@st.composite
def scenario_documents(draw):
    """A small valid scenario, with up to three settings dropped, changed or added."""
    doc = {
        "model": draw(st.sampled_from(list(FAMILIES))),
        "currents": [0.0, 1.0],
        "duration": 0.2,
        "fs": 500.0,
        "noise": 1e-3,
        "output": "out.csv",
    }
    experiment = draw(st.sampled_from(EXPERIMENTS))
    if experiment != "release":
        doc["experiment"] = experiment
    for key in draw(st.lists(st.sampled_from(sorted(_SCENARIO_JUNK)), max_size=3, unique=True)):
        if key in doc and draw(st.booleans()):
            del doc[key]
        else:
            doc[key] = draw(_SCENARIO_JUNK[key])
    return doc


@fuzz_settings(300)
@given(
    doc=scenario_documents(),
    raw=often(st.none(), st.text(max_size=60)),
    garbage=often(st.none(), st.binary(max_size=30)),
)
def test_fuzz_scenario(work, doc, raw, garbage):
    path = work / "scenario.toml"
    text = to_toml(doc) if raw is None else raw
    path.write_bytes(text.encode("utf-8") + (garbage or b""))
    sc = attempt("scenario", load_scenario, path)
    if sc is None:
        return
    assert isinstance(sc, dict) and set(sc) <= set(SCENARIO_KEYS) | {"path"}
    for key in ("duration", "fs", "noise", "theta_noise"):
        if key in sc:
            assert math.isfinite(sc[key])
    if "output" in sc:
        assert "\x00" not in sc["output"] and Path(sc["output"]).name
    model = attempt("scenario>model", scenario_model, sc)
    if model is None:
        return
    assert isinstance(model, Model)
    samples = (
        sc.get("duration", 6.0) * sc.get("fs", 1000.0) * max(len(sc.get("currents") or [0] * 5), 1)
    )
    if samples <= 3000:  # keep the simulation bounded
        ds = attempt("scenario>generate", generate_from_scenario, sc)
        if ds is not None:
            assert isinstance(ds, Dataset)
            for r in ds.runs:
                for key in ("t", "theta", "torque", "input", "theta_dot"):
                    a = getattr(r, key)
                    assert a is None or np.all(np.isfinite(a)), f"NaN in generated {key}"


def test_generate_refuses_absurd_sizes():
    from hystdisc.simulation.synth import generate

    for kw in ({"duration": 1e200, "fs": 1e200}, {"duration": 1e12}):
        with pytest.raises(HystdiscError) as exc:
            generate("dahl", **kw)
        assert "samples" in check_error(exc.value)
