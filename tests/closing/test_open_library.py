"""The open residual library (issue 35 item 2): sparse regression on a broad, named library
of candidate forces finds what the catalogue lacks, maps what it knows to its effects, and
finds nothing in the residual of the true model.

Driven sets made by the simulator (motion imposed, torque measured), sines whose periods are
no whole number of samples; an extra force is added to the measured torque where the
catalogue has no term for it (for a driven test a static force of the motion is exactly an
extra torque term).
"""

from __future__ import annotations

import warnings
from functools import cache

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.closing.open_library import (
    MIN_INCLUSION,
    play_width,
    regress_output_residual,
    regress_residual,
)
from hystdisc.data import Dataset, Run
from hystdisc.models import Model
from hystdisc.models.backlash import play
from hystdisc.registry import get_effect
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
        d = _fit(data, family)
    else:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            d = Discovery(model=family, close_loop=False, heldout=False).fit(data)
    fit = d.family_fits_[family]
    if output:
        return regress_output_residual(d.fit_data_, fit, seed=0)
    return regress_residual(d.eq_data_, fit.term_part, seed=0)


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
