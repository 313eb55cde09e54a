"""The typed, versioned ``results.json`` record (hystdisc.results)."""

from __future__ import annotations

import dataclasses
import inspect
import json
import re
from pathlib import Path

import pytest

from hystdisc.errors import HystdiscError
from hystdisc.estimator import Discovery
from hystdisc.models import Model, TermModel
from hystdisc.results import (
    RECORDS,
    SCHEMA_VERSION,
    EffectStep,
    EffectTrial,
    FamilyResult,
    ParameterResult,
    Results,
    TermModelRecord,
)
from hystdisc.results.sections import (
    SECTION_RECORDS,
    SECTIONS,
    ConditionsRecord,
    EnvelopeRecord,
    NoiseRecord,
    RunEnvelopeRecord,
)
from hystdisc.simulation.synth import generate

FIXTURES = Path(__file__).parent / "fixtures"
SCHEMA1 = sorted(FIXTURES.glob("results_schema1_*.json"))


def _schema1(name: str) -> tuple[str, dict]:
    text = (FIXTURES / f"results_schema1_{name}.json").read_text(encoding="utf-8")
    return text, json.loads(text)


@pytest.fixture(scope="module")
def small_fit():
    """A real small fit with the closing loop (Dahl, three currents, 2 s)."""
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=2.0, noise=1e-3, seed=1)
    disc = Discovery(families=["dahl", "lugre"], heldout=False).fit(data)
    return disc, data


# ----------------------------------------------------------------------------- schema 1


@pytest.mark.parametrize("path", SCHEMA1, ids=lambda p: p.stem)
def test_schema1_file_loads_and_keeps_its_bytes(path):
    text = path.read_text(encoding="utf-8")
    old = json.loads(text)
    assert "schema_version" not in old
    res = Results.load(path)
    assert res.schema_version == SCHEMA_VERSION == 5
    summary = res.summary()
    assert list(summary) == ["schema_version", *old]
    assert {k: v for k, v in summary.items() if k != "schema_version"} == old
    # written back: today's bytes with one more line
    assert res.to_json() == text.replace("{\n", '{\n "schema_version": 5,\n', 1)
    assert Results.from_json(text).summary() == summary
    # the models are usable
    assert isinstance(res.term_model(), TermModel)
    for name in res.families:
        assert isinstance(res.term_model(name), TermModel)
    assert res.report()


def test_schema1_attributes_are_typed():
    _, old = _schema1("effects")
    res = Results.load(FIXTURES / "results_schema1_effects.json")
    assert isinstance(res.families["dahl"], FamilyResult)
    f = res.families["dahl"]
    assert f.rms == old["families"]["dahl"]["rms"]
    assert isinstance(f.parameters["rho"], ParameterResult)
    assert f.parameters["rho"].ci95 == old["families"]["dahl"]["parameters"]["rho"]["ci95"]
    assert isinstance(f.term_model, TermModelRecord)
    (eff,) = res.effects
    assert isinstance(eff, EffectStep) and eff.name == "coulomb"
    # an accepted effect's parameters have no "identifiable": it stays absent
    assert "identifiable" not in eff.parameters["f_c"]
    assert all(isinstance(e, EffectTrial) for e in res.effects_tried)
    assert res.diagnosis[0].candidates[0].name == old["diagnosis"][0]["candidates"][0]["name"]
    assert res.residual.whiteness_p == old["residual"]["whiteness_p"]
    assert res.final.effects == ["coulomb"]
    assert res.closed_loop
    # key access as in schema 1's plain dicts
    assert res.families["dahl"]["rms"] == f.rms
    assert res.effects[0]["parameters"]["f_c"]["value"] == eff.parameters["f_c"].value
    assert res.diagnosis[0]["candidates"][0]["evidence"] == res.diagnosis[0].candidates[0].evidence
    assert res.residual.get("dominant_hz", 0) == old["residual"]["dominant_hz"]


def test_schema1_without_loop():
    res = Results.load(FIXTURES / "results_schema1_no_loop.json")
    assert not res.closed_loop
    assert res.effects_tried is None and res.final is None and res.diagnosis is None
    assert res.effects_table() == []
    assert "effects_tried" not in res.summary()


# ----------------------------------------------------------------------------- round trip


def test_every_record_round_trips():
    _, old = _schema1("effects")
    samples = {
        "TermModelRecord": old["model"],
        "ParameterResult": old["families"]["dahl"]["parameters"]["rho"],
        "FamilyResult": old["families"]["dahl"],
        "Stage1Record": next(iter(old["discovered"]["stage1"].values())),
        "DiscoveredResult": old["discovered"],
        "EffectStep": old["effects"][0],
        "EffectTrial": old["effects_tried"][0],
        "SkippedEffect": {"name": "offset", "reason": "no rig spring"},
        "EffectCandidate": old["diagnosis"][0]["candidates"][0],
        "DiagnosisRound": old["diagnosis"][0],
        "ResidualSummary": old["residual"],
        "FinalResult": old["final"],
        "RunRecord": old["runs"][0],
    }
    assert set(samples) == {c.__name__ for c in RECORDS}
    for cls in RECORDS:
        d = samples[cls.__name__]
        rec = cls.from_dict(d)
        assert rec.to_dict() == d, cls.__name__
        back = cls.from_dict(json.loads(json.dumps(rec.to_dict())))
        assert back == rec, cls.__name__
        assert list(back.to_dict()) == list(d)
        # unknown keys are kept, at the end
        more = cls.from_dict({**d, "future_key": [1, 2]})
        assert more.extra == {"future_key": [1, 2]}
        assert more.to_dict() == {**d, "future_key": [1, 2]}


def test_results_round_trip_dumps_loads():
    text, _ = _schema1("effects")
    res = Results.from_json(text)
    again = Results.from_json(res.to_json())
    assert again == res
    assert again.to_json() == res.to_json()


def test_records_built_in_code_write_every_attribute():
    p = ParameterResult(value=1.0, ci95=[0.5, 1.5])
    assert p.to_dict() == {"value": 1.0, "ci95": [0.5, 1.5], "identifiable": True}
    assert ParameterResult.from_dict(p.to_dict()) == p


def test_records_made_in_code_are_rounded_and_keep_the_order_given():
    p = ParameterResult.make(ci95=(float("nan"), 2 / 3), value=1 / 3)
    assert p.to_dict() == {"ci95": [None, 0.6666666667], "value": 0.3333333333}
    assert "identifiable" not in p and p.identifiable is True  # not given: not written
    assert ParameterResult.from_dict(p.to_dict()) == p
    # a key that is no attribute is kept in extra, in its place
    t = EffectTrial.make(name="offset", future_key=1, accepted=True)
    assert t.extra == {"future_key": 1} and list(t.to_dict()) == ["name", "future_key", "accepted"]


def test_a_fit_in_memory_is_its_file(small_fit):
    """The record built in the process (no table parsed back) is the one its file reads
    as: the same values, rounded alike, the same keys in the same order."""
    disc, _ = small_fit
    res = disc.results_
    again = Results.from_json(res.to_json())
    assert again == res
    assert again.to_json() == res.to_json()
    assert res.diagnosis and list(again.diagnosis[0]) == list(res.diagnosis[0])


def test_save_is_atomic_and_refuses_overwrite(tmp_path):
    res = Results.load(FIXTURES / "results_schema1_no_loop.json")
    path = res.save(tmp_path / "r.json")
    with pytest.raises(HystdiscError, match="exists"):
        res.save(path)
    res.save(path, force=True)
    assert Results.load(path) == res


# ----------------------------------------------------------------------------- checks


def test_newer_schema_is_refused(tmp_path):
    _, old = _schema1("no_loop")
    path = tmp_path / "r.json"
    path.write_text(json.dumps({"schema_version": SCHEMA_VERSION + 1, **old}))
    with pytest.raises(HystdiscError) as exc:
        Results.load(path)
    msg = str(exc.value)
    assert "newer" in msg and "fix:" in msg and "\n" not in msg


@pytest.mark.parametrize(
    ("key", "value", "where"),
    [
        ("runs", {"a": 1}, "runs"),
        ("residual", [1, 2], "residual"),
        ("effects", [3], "effects[0]"),
        ("discovered", {"stage1": 5}, "discovered.stage1"),
        ("noise", {"std": 0.1, "runs": "x"}, "noise.runs"),
        ("envelope", [0.3], "envelope"),
        ("reselection", {"families": {"dahl": 3}}, "reselection.families.dahl"),
    ],
)
def test_malformed_structure_is_one_line(tmp_path, key, value, where):
    _, old = _schema1("effects")
    path = tmp_path / "r.json"
    path.write_text(json.dumps({**old, key: value}))
    with pytest.raises(HystdiscError) as exc:
        Results.load(path)
    msg = str(exc.value)
    assert where in msg and "fix:" in msg and "\n" not in msg


@pytest.mark.parametrize("value", [5, "bogus", ["release"]])
def test_an_unknown_experiment_is_one_line(tmp_path, value):
    _, old = _schema1("no_loop")
    path = tmp_path / "r.json"
    path.write_text(json.dumps({**old, "experiment": value}))
    with pytest.raises(HystdiscError) as exc:
        Results.load(path)
    msg = str(exc.value)
    assert "experiment" in msg and "release" in msg and "fix:" in msg and "\n" not in msg


def test_every_section_is_typed_and_round_trips():
    """Each dict-shaped key of results.json reads as its record (the nested tables as
    theirs), writes back the same table in the same key order, and keeps unknown keys."""
    tables = json.loads((FIXTURES / "sections.json").read_text(encoding="utf-8"))
    assert set(tables) == set(SECTIONS)
    res = Results.from_dict({"version": "0", "experiment": "driven", **tables})
    for key, cls in SECTIONS.items():
        rec = getattr(res, key)
        assert type(rec) is cls, key
        assert rec.to_dict() == tables[key] and list(rec.to_dict()) == list(tables[key]), key
        more = cls.from_dict({**tables[key], "future_key": 1}, key)
        assert more.extra == {"future_key": 1} and list(more.to_dict())[-1] == "future_key"
    assert Results.from_json(res.to_json()) == res
    # nested tables are records too, read by attribute
    assert res.envelope.runs[1].current == 0.5 and res.noise.runs[0].method == "differences"
    assert res.outliers.items[0].signal == tables["outliers"]["items"][0]["signal"]
    assert res.reselection.families["spencer"].heldout_rms is not None
    assert res.current_laws.laws["c"].coefficients == {"c_a": 0.5, "c_b": 0.6}
    assert res.open_library.terms[1].effect == "quadratic_damping"
    assert res.open_library.heldout.lower == 2
    assert res.reduction.fit.bic == tables["reduction"]["fit"]["bic"]
    # and by key, as the plain tables of schema 1 were
    assert res.noise["method"] == "period" and dict(res.conditions) == tables["conditions"]


def test_every_attribute_is_documented():
    for cls in (Results, *RECORDS, *SECTION_RECORDS):
        doc = inspect.getdoc(cls)
        assert "Attributes\n----------" in doc, cls.__name__
        documented = set()
        for line in doc.split("Attributes\n----------", 1)[1].splitlines():
            m = re.match(r"^(\w+(?:, \w+)*) : ", line)
            if m:
                documented |= set(m.group(1).split(", "))
        fields = {f.name for f in dataclasses.fields(cls)}
        assert fields == documented, (cls.__name__, fields ^ documented)


# ----------------------------------------------------------------------------- a real fit

#: Keys schema 3 added: after ``seed`` at the top, after ``n_params`` in a family, at the
#: end of ``final`` (and the later ``system_model`` and ``outliers``).
NEW_TOP = ["conditions", "envelope", "selection_note", "system_model"]
NEW_FAMILY = ["admissible", "violations"]
#: Keys the measurement model added (issue 16 item 3; free keys, no schema change): at the
#: top after the schema-3 keys, in the residual after ``peak_q``.
NEW_TOP += ["noise", "encoder"]
#: The outliers screen (issue 16 item 4; a free key): after them.
NEW_TOP += ["outliers"]
#: The tasks that failed and were dropped (issue 33 item 1; a free key): after them.
NEW_TOP += ["failed"]
NEW_RESIDUAL = ["whiteness_test", "ljung_box_p"]


def _after(keys: list[str], anchor: str, new: list[str]) -> list[str]:
    k = keys.index(anchor) + 1
    return [*keys[:k], *new, *keys[k:]]


def test_real_fit_has_todays_keys_plus_schema_version(small_fit):
    disc, _ = small_fit
    summary = json.loads(disc.results_.to_json())
    _, old = _schema1("effects")  # written by today's code with the loop
    assert list(summary) == ["schema_version", *_after(list(old), "seed", NEW_TOP)]
    assert summary["schema_version"] == 5
    for name, fam in summary["families"].items():
        assert list(fam) == _after(list(old["families"]["dahl"]), "n_params", NEW_FAMILY), name
        assert fam["admissible"] is True and fam["violations"] == []
    assert list(summary["discovered"]) == list(old["discovered"])
    assert list(summary["final"]) == [*old["final"], *NEW_FAMILY]
    for e in summary["effects"]:
        assert e["heldout_rms_after"] < e["heldout_rms_before"]
    assert summary["conditions"]["heldout_by"] == "run"
    assert summary["envelope"]["theta_max"] == pytest.approx(0.3, rel=0.05)
    assert list(summary["residual"]) == _after(list(old["residual"]), "peak_q", NEW_RESIDUAL)
    assert summary["noise"]["method"] == "differences" and summary["encoder"] is None
    # typed attributes read the same values
    res = disc.results_
    assert isinstance(res.conditions, ConditionsRecord)
    assert res.conditions.folds == summary["conditions"]["folds"]
    assert isinstance(res.noise, NoiseRecord) and res.noise.std == summary["noise"]["std"]
    assert isinstance(res.envelope, EnvelopeRecord)
    assert all(isinstance(r, RunEnvelopeRecord) for r in res.envelope.runs)
    assert res.families["dahl"].rms == summary["families"]["dahl"]["rms"]
    assert res.family == disc.family_ and res.experiment == "release"
    assert res.term_model().torque == summary["model"]["torque"]


def test_real_fit_without_loop_has_no_loop_keys():
    data = generate(Model("dahl"), currents=(0, 0.5, 1), duration=2.0, noise=1e-3, seed=1)
    disc = Discovery(families=["dahl", "bingham"], heldout=True, close_loop=False)
    res = disc.fit(data).results_
    _, old = _schema1("no_loop")
    assert list(res.summary()) == ["schema_version", *_after(list(old), "seed", NEW_TOP)]
    assert res.residual.rms == pytest.approx(res.families[res.family].rms, rel=1e-6)
