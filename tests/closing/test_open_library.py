"""The open residual library (issue 35 item 2): sparse regression on a broad, named library
of candidate forces finds what the catalogue lacks, maps what it knows to its effects, and
finds nothing in the residual of the true model.

Driven sets made by the simulator (motion imposed, torque measured), sines whose periods are
no whole number of samples; an extra force is added to the measured torque where the
catalogue has no term for it (for a driven test a static force of the motion is exactly an
extra torque term).

The library's terms refitted into the model by output error and judged held out (issue 35
item 2's last step: "refit by output error; accept by held-out conditions"), on the same
driven sets: a damper with an asymmetric yield outside the catalogue (a force step ``STEP``
while the velocity is positive, ``[theta_dot>0]``), and the same damper without it.
"""

from __future__ import annotations

import copy
import warnings
from functools import cache
from types import SimpleNamespace as NS

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.closing.library_refit import TermsRefit, _softens, refit_terms
from hystdisc.closing.open_library import (
    MIN_INCLUSION,
    _open_terms,
    play_width,
    regress_output_residual,
    regress_residual,
)
from hystdisc.data import Dataset, Run
from hystdisc.models import Model
from hystdisc.models.backlash import play
from hystdisc.models.term_columns import term_column
from hystdisc.pipeline.close import refit_library
from hystdisc.registry import get_effect
from hystdisc.results.sections import OpenLibraryRecord
from hystdisc.results.text import open_library_lines
from hystdisc.simulation.synth import generate

FAMILY = "bouc-wen-std"
DRIVES = ["0.2@1.3", "0.1@2.7"]
NOISE = 0.01
#: The extra stiffness on one side only (N*m/rad).
ASYM = 1.0
#: The asymmetric yield added: a force step when the velocity turns positive (N*m).
STEP = 0.05


def _driven(
    seed: int, effects: dict | None = None, family: str = FAMILY, duration: float = 4.0
) -> Dataset:
    truth = Model(family, {"k_s": 0.0}, effects=effects or {})
    return generate(
        truth, experiment="driven", currents=(0, 0.5, 1), drives=DRIVES, duration=duration,
        noise=NOISE, seed=seed,
    )  # fmt: skip


@cache
def _fit(kind: str, family: str = FAMILY) -> Discovery:
    """The family fitted without the loop on the clean driven set (``kind="clean"``) or
    with the asymmetric yield step (``"step"``); made once for the tests that share it."""
    data = _driven(3, family=family)
    if kind == "step":
        data = _with_step(data)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return Discovery(model=family, close_loop=False, heldout=False).fit(data)


def _found(data: Dataset | str, output: bool = False, family: str = FAMILY):
    if isinstance(data, str):
        if output:
            return _residual(data, family)
        d = _fit(data, family)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = Discovery(model=family, close_loop=False, heldout=False).fit(data)
    fit = d.family_fits_[family]
    if output:
        return regress_output_residual(d.fit_data_, fit, seed=0)
    return regress_residual(d.eq_data_, fit.term_part, seed=0)


@cache
def _residual(kind: str, family: str = FAMILY):
    """The open library on the output-error residual of ``_fit(kind, family)`` (seed 0);
    made once for the tests that share it: a test that changes it takes a deep copy."""
    d = _fit(kind, family)
    return regress_output_residual(d.fit_data_, d.family_fits_[family], seed=0)


@cache
def _refit(kind: str, family: str, names: tuple[str, ...]):
    """``refit_terms`` of ``names`` into ``_fit(kind, family)``'s model (floor ``NOISE``,
    its default iterations); made once for the tests that share it (none changes it)."""
    d = _fit(kind, family)
    return refit_terms(d.fit_data_, d.family_fits_[family], list(names), floor=NOISE)


def _with_step(data: Dataset) -> Dataset:
    """``data`` with an asymmetric yield: a force step where the velocity is positive."""
    runs = [
        Run(
            r.name,
            r.t,
            r.theta,
            r.current,
            torque=r.torque + STEP * (np.gradient(r.theta, r.t) > 0),
        )
        for r in data.runs
    ]
    return Dataset(runs, "driven", "asymmetric yield")


def test_nothing_in_the_true_models_residual():
    found = _found("clean")
    assert found.terms == [] and found.effects == [] and found.equation() == ""
    assert found.candidates > 25


def test_an_asymmetric_yield_the_catalogue_lacks_is_discovered():
    found = _found("step")
    top = found.terms[0]
    assert top.name == "[theta_dot>0]" and top.effect == ""
    assert top.coefficient == pytest.approx(STEP, rel=0.1)
    assert top.inclusion >= MIN_INCLUSION
    assert "[theta_dot>0]" in found.equation()
    assert found.explained > 0.5


@pytest.mark.parametrize("family", [FAMILY, "tanh"])
def test_the_output_error_residual_of_any_family(family):
    """The force residual of a driven test, the model's own sensitivities projected out:
    the step alone is found, for a term family and a state-space one (which has no
    equation-error form); the true model's residual gives nothing. Judged on held-out
    conditions (each of the two drives left out, the model refitted with the term), the
    step predicts the left-out drive at the noise, and the model without it does not."""
    found = _found("step", output=True, family=family)
    assert [t.name for t in found.terms][:1] == ["[theta_dot>0]"]
    assert found.terms[0].coefficient == pytest.approx(STEP, rel=0.1)
    h = found.heldout
    assert (h.folds, h.lower) == (2, 2)
    assert h.after == pytest.approx(NOISE, rel=0.05) and h.before > 2 * NOISE
    assert _found("clean", output=True, family=family).terms == []


def test_a_catalogued_effect_is_named():
    """A cubic spring (0.12 N*m at the largest stroke) is named ``cubic_stiffness``, its
    coefficient within 10 %. Not a quadratic damping: on such a set (``c_q = 0.05``) five
    odd forms of the velocity correlate with the residual equally (``|r| = 0.58-0.62``:
    ``theta_dot*|theta_dot|``, ``sign(theta_dot)*|theta_dot|^0.5``, ``tanh``,
    ``theta_dot^3``), the model's refit having taken the linear part, so which one a
    library names is chance; the loop's output-error refits and held-out conditions
    decide there."""
    found = _found(_driven(5, {"cubic_stiffness": {"k_3": 15.0}}))
    assert "cubic_stiffness" in found.effects
    named = [t for t in found.terms if t.effect == "cubic_stiffness"]
    assert named and named[0].name == "theta^3"
    assert named[0].coefficient == pytest.approx(15.0, rel=0.1)


def test_the_play_operator():
    x = np.sin(np.linspace(0, 4 * np.pi, 2001))
    y = play(x, 0.1)
    assert np.max(np.abs(y - x)) == pytest.approx(0.1, abs=1e-12)  # it lags by the width
    assert np.all(np.abs(y - x) <= 0.1 + 1e-12)
    flat = np.abs(np.diff(y)) == 0.0  # the dead zone after each reversal
    assert 0.02 < flat.mean() < 0.3


@cache
def _asymmetric_stiffness() -> Dataset:
    """A driven set with a stiffness in tension only (no catalogued effect has it)."""
    clean = _driven(3, duration=2.0)
    runs = []
    for r in clean.runs:
        extra = ASYM * r.theta * (r.theta > 0)
        runs.append(Run(r.name, r.t, r.theta, r.current, torque=r.torque + extra))
    return Dataset(runs, "driven", "asymmetric stiffness")


def test_the_loop_reports_what_the_catalogue_left(tmp_path):
    """End to end: a stiffness that differs in tension and compression (no catalogued
    effect has ``|theta|``) is left unexplained by the loop; the open library names it in
    results.json (kept on a round trip), in the printed report and in the HTML report."""
    from hystdisc.report import write_report
    from hystdisc.results import Results

    data = _asymmetric_stiffness()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = Discovery(model=FAMILY).fit(data)
    assert d.loop_.unexplained
    lib = d.open_library_
    assert lib is not None and lib.terms[0].name == "theta*[theta>0]"
    assert lib.terms[0].coefficient == pytest.approx(ASYM, rel=0.1)
    # refitted with the model, each drive left out: the left-out drive at the noise
    assert lib.heldout.lower == lib.heldout.folds == 2
    assert lib.heldout.after == pytest.approx(NOISE, rel=0.1)
    assert lib.heldout.before > 2 * lib.heldout.after, lib.heldout
    # refitted into the model by output error, both models refitted without each drive
    fix = lib.refit
    assert fix is not None and fix.accepted, fix
    assert fix.coefficients["theta*[theta>0]"] == pytest.approx(ASYM, rel=0.02)
    assert fix.heldout_after == pytest.approx(NOISE, rel=0.1) and fix.lower == 2
    # the catalogued effects the loop accepted as stand-ins for the stiffness (a constant
    # for its mean, ...) are redundant beside the term: the refitted model leaves them out
    stand_ins = set(d.loop_.effects)
    assert stand_ins and set(fix.redundant) == stand_ins
    assert all(z2 <= np.log(sum(r.t.size for r in data.runs)) for z2 in fix.redundant.values())
    kept = set(fix.params)
    assert not kept & {p.name for e in stand_ins for p in get_effect(e).params}
    res = Results.from_json(d.results_.to_json())
    assert res.open_library.refit.accepted and res.open_library.refit.lower == 2
    assert set(res.open_library.refit.redundant) == stand_ins
    assert f"the refitted model leaves out {', '.join(fix.redundant)}: " in res.report()
    assert f"(below): {FAMILY} + F_extra; {', '.join(fix.redundant)} only stood" in res.report()
    assert "refitted into the model by output error: F_extra = " in res.report()
    assert res.open_library["terms"][0]["name"] == "theta*[theta>0]"
    assert "Open library (" in res.report() and "T_extra = " in res.report()
    assert res.open_library.heldout.after == pytest.approx(lib.heldout.after, rel=1e-6)
    assert "held out (each condition left out, the model refitted" in res.report()
    html = tmp_path / "report.html"
    write_report(d, data, html)
    text = html.read_text(encoding="utf-8")
    assert "open library" in text and "Refitted into the model by output error (F_extra" in text
    assert f"The refitted model leaves out {', '.join(fix.redundant)}: " in text


def test_a_play_is_mapped_to_the_catalogued_backlash_and_refitted_first(monkeypatch):
    """Issue 35 item 2: the library's play terms name the catalogued play (``backlash``),
    started at the term's width (one width for every run); the loop asks the
    library once, when a round accepts nothing above the noise, and refits what it names
    in one more round, from those values (the catalogue's own score ranked the play low on
    UTFSM)."""
    from types import SimpleNamespace as NS

    import hystdisc.pipeline.close as close
    from hystdisc.closing import close_loop
    from hystdisc.closing.open_library import DiscoveredTerm, ResidualTerms
    from hystdisc.faults import Failures

    found = _found(_driven(4, {"backlash": {"r_b": 0.005}}, duration=2.0), output=True)
    # one width for every run, on a grid of shares of the median half-range (0.15 rad):
    # 0.003, 0.0075, 0.015; the largest play term is one of the two around the true 0.005
    widths = {0.003, 0.0075, 0.015}
    assert {play_width(t.name) for t in found.terms if "play(" in t.name} <= widths
    assert "backlash" in found.effects and found.play_found() in (0.003, 0.0075)
    assert {t.effect for t in found.terms if "play(" in t.name} == {"backlash"}
    # the start values: the term's width
    lib = ResidualTerms(
        [DiscoveredTerm("d/dt[play(theta,0.0075)-theta]", 0.4, 1.0, "backlash")],
        effects=["backlash"],
    )
    monkeypatch.setattr(close, "open_library", lambda state, fit: lib)
    state = NS(failures=Failures())
    assert close.library_effects(state, None) == {"backlash": {"r_b": 0.0075}}
    # the loop: a stiffness in tension only is no catalogued effect, so a round accepts
    # nothing above the noise; the library is asked once, its effect refitted from its value
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = Discovery(model=FAMILY, close_loop=False, heldout=False).fit(_asymmetric_stiffness())
    calls = []
    loop = close_loop(
        d.family_fits_[FAMILY], d.fit_data_, d.noise_std_, d.eq_data_, heldout=False,
        max_nfev=15, library=lambda fit: calls.append(fit) or {"backlash": {"r_b": 0.004}},
    )  # fmt: skip
    assert len(calls) == 1
    # the library's attempt is the last round's (with level_bias accepted on this
    # uncatalogued stiffness, the catalogue's queue also tries the play one round earlier)
    bl = [v for v in loop.tried if v.name == "backlash"][-1]
    assert bl.round == loop.diagnosis[-1].round > 1 and "backlash" not in loop.effects


@pytest.mark.parametrize("family", [FAMILY, "tanh"])
def test_a_discovered_step_is_refitted_and_predicts_held_out_conditions_at_the_noise(family):
    """A term family and a state-space one: the refitted coefficient is the truth within
    3 of its standard errors, and each drive left out is predicted at the noise (within
    5 %) with the term, at more than twice the noise without it."""
    r = _refit("step", family, ("[theta_dot>0]",))
    assert r.accepted, r.note
    c, se = r.coefficients["[theta_dot>0]"], r.stderr["[theta_dot>0]"]
    assert abs(c - STEP) < 3 * se and se < 0.01 * STEP
    assert r.heldout_after == pytest.approx(NOISE, rel=0.05)
    assert r.heldout_before > 2 * NOISE and r.lower == 2 == len(r.fold_after)
    assert r.rms_after == pytest.approx(NOISE, rel=0.05) and r.admissible
    assert r.equation() == f"F_extra = {c:.4g}*[theta_dot>0]"


def test_an_effect_that_stood_in_for_the_term_is_left_out(tmp_path, capsys):
    """A constant bias fitted on the step takes the step's mean (significant without the
    term); beside the term it has nothing left to explain: the refit leaves it out (a
    state-space family: its parametrization is rebuilt without the effect), keeps the
    coefficient at the truth and predicts each drive left out at the noise; ``hystdisc
    predict`` runs the refitted model without it, at the noise, and says so."""
    import json

    from hystdisc.cli import main
    from hystdisc.closing.scores import wald_chi2
    from hystdisc.data import write_csv
    from hystdisc.fitting import OutputErrorFitter
    from hystdisc.pipeline.record import library_section

    d = _fit("step", "tanh")
    base = d.family_fits_["tanh"]
    par = base.par.like({**base.params, "f_0": STEP / 2}, ("bias",))
    fit = OutputErrorFitter(d.fit_data_, par, max_nfev=60).fit(heldout=False)
    assert wald_chi2(fit, "bias") > 10 * np.log(fit.n_obs)  # it stood in for the step
    r = refit_terms(d.fit_data_, fit, ["[theta_dot>0]"], floor=NOISE)
    assert r.accepted, r.note
    assert list(r.redundant) == ["bias"] and r.redundant["bias"] <= np.log(fit.n_obs)
    assert "f_0" not in r.params and r.fit.par.effects == ()
    c, se = r.coefficients["[theta_dot>0]"], r.stderr["[theta_dot>0]"]
    assert abs(c - STEP) < 3 * se
    assert r.heldout_after == pytest.approx(NOISE, rel=0.05) and r.lower == 2
    # through results.json: the refitted model (without the bias) plus the term
    lib = regress_output_residual(d.fit_data_, fit, seed=0)
    lib.refit = r
    table = json.loads(d.results_.to_json())
    table["open_library"] = library_section(lib).to_dict()
    res = tmp_path / "results.json"
    res.write_text(json.dumps(table))
    csv = write_csv(_with_step(_driven(3, family="tanh")), tmp_path / "step.csv")
    out = tmp_path / "p.csv"
    assert main(["predict", str(res), str(csv), "-o", str(out)]) == 0
    assert "(without bias, which only stood in for them)" in capsys.readouterr().out
    p = np.genfromtxt(out, delimiter=",", names=True)
    assert np.sqrt(np.mean((p["torque"] - p["torque_pred"]) ** 2)) == pytest.approx(NOISE, rel=0.1)


def test_on_clean_data_nothing_is_accepted():
    d = _fit("clean", "tanh")
    r = refit_terms(d.fit_data_, d.family_fits_["tanh"], ["[theta_dot>0]"], floor=NOISE)
    assert not r.accepted and r.note == "BIC does not fall by the margin"
    assert abs(r.coefficients["[theta_dot>0]"]) < 3 * r.stderr["[theta_dot>0]"]


def test_a_softening_spring_of_the_terms_is_inadmissible():
    """Terms in the position alone whose stiffness turns negative within twice the
    training stroke (here ``theta - 1e4 theta^3``: at ``|theta| > 0.0058``, the stroke
    being 0.2) are named; a stiffening pair, and terms in the velocity, are not."""
    d = _fit("step", "tanh").fit_data_
    assert d.currents.size and max(np.max(np.abs(th)) for th in d.theta) > 0.01
    soft = _softens(d, ["theta", "theta^3", "theta_dot"], np.array([1.0, -1e4, -5.0]))
    assert soft is not None and soft.startswith("the terms' spring has a negative stiffness at ")
    assert _softens(d, ["theta", "theta^3"], np.array([1.0, 1e4])) is None
    assert _softens(d, ["theta_dot", "[theta_dot>0]"], np.array([-1.0, -1.0])) is None


def test_the_pipeline_refits_only_what_the_screen_says_predicts_better():
    """``refit_library``: the library's terms on the step are refitted (the linearized
    screen says they predict both drives better); on the true model's residual there is
    nothing to refit."""
    said: list[str] = []
    for kind, expected in (("step", True), ("clean", False)):
        d = _fit(kind, "tanh")
        fit = d.family_fits_["tanh"]
        lib = _residual(kind, "tanh")
        state = NS(fd=d.fit_data_, noise_std=NOISE, options=NS(max_nfev=60), envelope=None,
                   say=said.append)  # fmt: skip
        r = refit_library(state, lib, fit)
        assert (r is not None and r.accepted) is expected
    assert said == ["closing the loop: the open library's terms refitted into the model, held out"]


def test_the_refit_reaches_results_json_and_the_text_report():
    lib = copy.deepcopy(_residual("step", "tanh"))  # the test sets its refit
    lib.refit = _refit("step", "tanh", tuple(t.name for t in lib.terms))
    rec = OpenLibraryRecord.from_dict(lib.to_dict())
    assert rec.refit.accepted and rec.refit.lower == 2
    assert rec.refit.equation == lib.refit.equation()
    lines = open_library_lines(rec)
    assert lines[-3] == f"  refitted into the model by output error: {lib.refit.equation()}"
    assert lines[-1].startswith("    RMS ") and ": ACCEPTED, they remove" in lines[-1]


def test_every_candidate_name_is_computed_from_its_name():
    """Each name the library makes (a bias per level, tanh scales, play widths, products
    with the current) has its column; an unknown name is one clear error."""
    t = np.linspace(0, 2, 801)
    th, w = 0.01 * np.sin(2 * np.pi * t), 0.02 * np.pi * np.cos(2 * np.pi * t)
    names = _open_terms([0.0, 1.0, 2.0], 0.063, 0.01)
    assert len(names) == len(set(names)) > 15
    for n in names:
        col = term_column(n, th, w, 2.0, t)
        assert col.shape == th.shape and np.all(np.isfinite(col)), n
    assert term_column("bias[i=2 A]", th, w, 2.0, t).tolist() == [1.0] * th.size
    assert np.allclose(term_column("i*tanh(theta_dot/0.5)", th, w, 2.0, t), 2 * np.tanh(w / 0.5))
    with pytest.raises(ValueError, match=r"^unknown term 'cos\(theta\)': not a form of the "):
        term_column("cos(theta)", th, w, 0.0, t)


def test_the_record_round_trips_without_a_refit():
    assert OpenLibraryRecord.from_dict({"candidates": 3}).refit is None
    r = TermsRefit(["i"], {"i": 1.0}, {"i": 0.1}, {}, 2.0, 1.0, 0.0, -10.0, None, None)
    assert r.sentence().endswith("held out: not available: not accepted ()")


def test_predict_adds_accepted_terms_to_the_refitted_model(tmp_path, capsys):
    """``hystdisc predict`` and ``Discovery.predict``: with accepted terms the final model
    is the refitted one plus the terms, which predicts the step data at the noise (the
    catalogued model alone misses by the step); ``--family`` is the family's own fit."""
    import json

    from hystdisc.cli import main
    from hystdisc.data import load, write_csv
    from hystdisc.pipeline.record import library_section

    d = copy.copy(_fit("step", "tanh"))  # the test sets its open library
    lib = copy.deepcopy(_residual("step", "tanh"))  # and the library's refit
    lib.refit = _refit("step", "tanh", ("[theta_dot>0]",))
    table = json.loads(d.results_.to_json())
    table["open_library"] = library_section(lib).to_dict()
    res = tmp_path / "results.json"
    res.write_text(json.dumps(table))
    csv = write_csv(_with_step(_driven(3, family="tanh")), tmp_path / "step.csv")
    rms = {}
    for extra in ([], ["--family", "tanh"]):
        out = tmp_path / f"p{len(extra)}.csv"
        assert main(["predict", str(res), str(csv), "-o", str(out), *extra]) == 0
        p = np.genfromtxt(out, delimiter=",", names=True)
        rms[len(extra)] = float(np.sqrt(np.mean((p["torque"] - p["torque_pred"]) ** 2)))
    text = capsys.readouterr().out
    assert text.count("with the open library's accepted terms: F_extra = ") == 1
    assert rms[0] == pytest.approx(NOISE, rel=0.1) and rms[2] > 2 * NOISE
    d.open_library_ = lib  # as the pipeline leaves it when the loop ran
    pred = d.predict(load(csv))
    e = np.concatenate([r.predicted - r.measured for r in pred])
    assert float(np.sqrt(np.mean(e**2))) == pytest.approx(rms[0], rel=1e-6)
    # python-control: the refitted model with the terms, as predict uses it
    ct = pytest.importorskip("control")
    from hystdisc.apply.control import SOLVE_IVP_KWARGS, driven_inputs
    from hystdisc.results import Results

    sys = Results.load(res).to_control()
    (T, U), run = driven_inputs(load(csv))[0], pred[0]
    y = ct.input_output_response(sys, T, U, solve_ivp_kwargs=SOLVE_IVP_KWARGS).outputs
    assert np.max(np.abs(y - run.predicted)) < 1e-6 * np.max(np.abs(run.predicted))


def test_a_softening_spring_is_dropped_and_the_rest_refitted():
    """The step with a small softening spring added (``-1.25 theta^3``: 0.01 at the
    stroke, negative stiffness everywhere but at 0): with ``theta^3`` the terms' spring is
    inadmissible; refitted without it, the step is accepted on its own."""
    from hystdisc.closing.library_refit import refit_admissible

    step = _with_step(_driven(3, family="tanh"))
    runs = [Run(r.name, r.t, r.theta, r.current, torque=r.torque - 1.25 * r.theta**3)
            for r in step.runs]  # fmt: skip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        d = Discovery(model="tanh", close_loop=False, heldout=False).fit(
            Dataset(runs, "driven", "soft")
        )
    names = ["[theta_dot>0]", "theta^3"]
    r = refit_admissible(d.fit_data_, d.family_fits_["tanh"], names, floor=NOISE)
    assert r.terms == ["[theta_dot>0]"] and r.dropped == ["theta^3"]
    assert r.accepted and r.coefficients["[theta_dot>0]"] == pytest.approx(STEP, rel=0.05)
    assert r.note.endswith(
        "; without theta^3 (the model with them is not physical: the terms' spring has a "
        "negative stiffness at -0.4 (0 A))"
    )
