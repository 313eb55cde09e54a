"""The families compared again with the effects the loop accepted (issue 16: the base fit
before the loop; ``hystdisc.closing.reselect``).

The data are written by the package's simulator with values picked here (not a bundled
set): a seed-form Bouc-Wen release whose spring rests 15 mrad below the sensor zero (an
effect of the rig), and a standard-form Bouc-Wen damper with quadratic damping (an effect
of the damper).
"""

from __future__ import annotations

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.cli import main
from hystdisc.closing.reselect import Reselection, refit_families, term_effects
from hystdisc.data import load
from hystdisc.discovery import FAMILY_SHAPE
from hystdisc.selection.families import select_family
from hystdisc.simulation.admissibility import check_admissible

TRUTH = "alpha_1=0.7,alpha_2=1.1,c_1=0.35,c_2=0.8,beta=14,gamma=7,n=1.5,k_s=190"
THETA_OFF = -0.015
NOISE = 1e-3


def _stage1_shape(disc):
    """Each family's stage-1 shape constants, from the estimator's public ``stage1_``."""
    return lambda fit: np.asarray(disc.stage1_[FAMILY_SHAPE[fit.par.family.name]].s)


@pytest.fixture(scope="module")
def offset_csv(tmp_path_factory):
    out = tmp_path_factory.mktemp("reselect") / "off.csv"
    argv = ["simulate", "--model", "bouc-wen", "--set", TRUTH]
    argv += ["--effect", f"offset:theta_off={THETA_OFF}", "--currents", "0,0.25,0.5,0.75,1"]
    argv += ["--duration", "3", "--noise", str(NOISE), "--seed", "5", "-o", str(out), "--quiet"]
    assert main(argv) == 0
    return out


@pytest.fixture(scope="module")
def base(offset_csv):
    return Discovery(close_loop=False).fit(load(offset_csv))


def test_only_term_effects_are_carried_to_every_family():
    assert term_effects(["quadratic_damping", "offset"]) == ["quadratic_damping", "offset"]
    # a compliant wheel is its own state-space system, not a term another family takes
    assert term_effects(["series_compliance", "cubic_stiffness"]) == ["cubic_stiffness"]


def test_with_the_offset_every_family_is_judged_fairly_and_the_true_one_wins(base):
    # without the offset every family misfits by 15-21x the noise: the table cannot tell
    noise = base.noise_std_
    assert min(f.rms for f in base.family_fits_.values()) > 10 * noise
    # the offset starts at 0: stage 1's start of family + offset has to find it
    fits = refit_families(
        base.family_fits_,
        ["offset"],
        base.fit_data_,
        base.eq_data_,
        {"theta_off": 0.0},
        _stage1_shape(base),
    )
    adm = {n: check_admissible(f.term_part, base.envelope_) for n, f in fits.items()}
    pick, _ = select_family(fits, adm)
    assert pick == "bouc-wen"
    fit = fits[pick]
    assert fit.rms < 1.03 * noise and fit.heldout_rms < 1.03 * noise
    lo, hi = fit.ci95["theta_off"]
    assert lo < THETA_OFF < hi and abs(fit.params["theta_off"] / THETA_OFF - 1) < 0.02
    # the families without the true hysteresis stay clearly worse on held-out runs
    for name in ("bingham", "dahl", "lugre"):
        assert fits[name].heldout_rms > 1.5 * fit.heldout_rms


STD_TRUTH = "alpha_1=0.45,alpha_2=1.3,c_1=0.6,c_2=0.5,beta=7,gamma=11,n=2.3,k_s=145,delta=18"
C_Q = 0.07


@pytest.fixture(scope="module")
def damper(tmp_path_factory):
    """The whole estimator on a standard-form Bouc-Wen damper with quadratic damping, made
    once for the two tests that read it. The closing loop reads the family table, the
    data, the noise, the envelope and stage 1 and changes none of them (``close_loop`` is
    read in ``pipeline/close.py`` alone): they are the run's without the loop, and the
    family selected from the table before the loop is ``reselection_.before``."""
    out = tmp_path_factory.mktemp("reselect") / "qd.csv"
    argv = ["simulate", "--model", "bouc-wen-std", "--set", STD_TRUTH]
    argv += ["--effect", f"quadratic_damping:c_q={C_Q}", "--currents", "0,0.25,0.5,0.75,1"]
    argv += ["--duration", "3", "--noise", str(NOISE), "--seed", "23", "-o", str(out), "--quiet"]
    assert main(argv) == 0
    return Discovery(families=["bouc-wen", "bouc-wen-std"]).fit(load(out))


def test_a_damper_effect_found_on_the_wrong_form_is_carried_to_the_right_one(damper):
    # standard-form Bouc-Wen + quadratic damping: without the effect the seed form mimics
    # the missing term better and wins the table; with it, the standard form predicts the
    # held-out runs better
    base = damper  # its table, data and selection before the loop (see ``damper``)
    table = base.family_fits_
    assert base.reselection_.before == "bouc-wen" and table["bouc-wen"].rms > 1.1 * base.noise_std_
    fits = refit_families(
        table, ["quadratic_damping"], base.fit_data_, base.eq_data_, {"c_q": 0.0},
        _stage1_shape(base),
    )  # fmt: skip
    adm = {n: check_admissible(f.term_part, base.envelope_) for n, f in fits.items()}
    pick, _ = select_family(fits, adm)
    assert pick == "bouc-wen-std"
    fit = fits[pick]
    assert fit.heldout_rms < fits["bouc-wen"].heldout_rms and fit.rms < 1.03 * base.noise_std_
    lo, hi = fit.ci95["c_q"]
    assert lo < C_Q < hi
    assert abs(fit.params["n"] / 2.3 - 1) < 0.05  # the standard form's own exponent


def test_the_loops_final_model_stands_for_its_family_when_its_refit_fits_worse(monkeypatch):
    # the loop reached bouc-wen + offset from a restart (held-out 1e-3); the family's refit
    # with the offset from its own starts stopped in a worse basin (3e-3) and would have
    # handed the comparison to lugre (1.05e-3)
    from types import SimpleNamespace as NS

    import hystdisc.closing.reselect as rs

    def fit(bic, heldout, n_params=10):
        par = NS(effects=("offset",))
        return NS(
            bic=bic,
            heldout_rms=heldout,
            n_params=n_params,
            par=par,
            term_part=None,
            is_system=False,
        )

    final = fit(-1000.0, 1.0e-3)
    final.params, final.term_part = {"theta_off": 0.03}, NS(torque={})
    refits = {"bouc-wen": fit(-900.0, 3.0e-3), "lugre": fit(-950.0, 1.05e-3, n_params=9)}
    monkeypatch.setattr(rs, "refit_families", lambda *args, **kw: dict(refits))
    monkeypatch.setattr(rs, "check_admissible", lambda *args: NS(ok=True, violations=[]))
    closed = []
    ctx = rs.Context(NS(), None, None, closed.append, lambda f: None)
    loop = NS(fit=final, effects=["offset"])
    res = rs.reselect(dict.fromkeys(refits), "bouc-wen", loop, ["offset"], ctx)
    assert res.fits["bouc-wen"] is final and res.pick == "bouc-wen" and closed == []
    assert res.note == "with offset in every family, bouc-wen is still selected"
    # a loop whose final model fits worse than the refit does not replace it
    final.bic = -800.0
    refits["bouc-wen"] = fit(-1100.0, 1.0e-3)
    res = rs.reselect(dict.fromkeys(refits), "bouc-wen", loop, ["offset"], ctx)
    assert res.fits["bouc-wen"] is refits["bouc-wen"] and res.pick == "bouc-wen"


def test_a_delay_the_selected_family_absorbed_enters_the_comparison_again(monkeypatch):
    # issue 33, acceptance set tanh/10/delay: stage 1's scan saw the 3 ms lag but did not
    # call it; another family absorbed it and was selected, and the loop's delay on it
    # passed every test but the held-out one; tanh with the delay predicts
    from types import SimpleNamespace as NS

    import hystdisc.closing.again as ag
    import hystdisc.closing.reselect as rs

    def fit(bic, heldout, effects=()):
        return NS(bic=bic, heldout_rms=heldout, n_params=8, par=NS(effects=effects),
                  params={}, term_part=NS(torque={}), is_system=False)  # fmt: skip

    final = fit(-1000.0, 0.134)
    wanted = NS(name="channel_delay", ok=True, improves=True, significant=True,
                admissible=True, predicts=False)  # fmt: skip
    loop = NS(fit=final, effects=[], tried=[wanted], pointed={}, unexplained=False)
    refits = {"bouc-wen": fit(-1200.0, 0.130, ("channel_delay",)),
              "tanh": fit(-3000.0, 0.012, ("channel_delay",))}  # fmt: skip
    seen = []
    monkeypatch.setattr(rs, "refit_families", lambda *a, **kw: seen.append(a) or dict(refits))
    monkeypatch.setattr(rs, "check_admissible", lambda *args: NS(ok=True, violations=[]))
    monkeypatch.setattr(ag, "reduce_family", lambda *args: None)
    closed = NS(fit=fit(-3000.0, 0.012, ("channel_delay",)), effects=["channel_delay"])
    ctx = rs.Context(NS(), None, None, lambda f: closed, lambda f: None)
    table = dict.fromkeys(refits)
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    (args,) = seen
    assert args[1] == ["channel_delay"] and args[4] == {"tau_d": 0.002}  # effects, start
    assert out.family == "tanh" and out.loop is closed
    assert "which the loop tried on bouc-wen and did not accept (channel_delay)" in out.note
    # a delay whose refit also removed too little of the excess (driven stress set
    # tanh/16/delay: 7 % of Bouc-Wen's) is carried only when another family, refitted with
    # it alone, fits all the runs better than the selected final model predicts
    wanted.improves = False
    wanted.bic_before, wanted.bic_after = -1000.0, -1100.0
    screen = []

    def alone(table, effects, data, eq, values, shapes, max_nfev, heldout, mapper):
        screen.append((sorted(table), effects, values, heldout))
        return {n: NS(rms=rms[n]) for n in table}

    monkeypatch.setattr(ag, "refit_families", alone)
    rms = {"tanh": 0.150}  # above bouc-wen's held-out 0.134: tanh cannot win with it
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    assert screen == [(["tanh"], ["channel_delay"], {"tau_d": 0.002}, False)]
    assert out.family == "bouc-wen" and out.reselection is None and len(seen) == 1
    rms["tanh"] = 0.013  # below it: the families are compared with the delay
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    assert len(screen) == 2 and len(seen) == 2 and seen[1][1] == ["channel_delay"]
    assert out.family == "tanh" and out.loop is closed
    # so is one that predicts better but removes too little of the wrong family's excess
    # (never-drawn driven set tanh/19/delay: 2 % of Bouc-Wen's, every fold lower)
    wanted.predicts = True
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    assert len(screen) == 3 and len(seen) == 3 and out.family == "tanh"
    # a refit that did not lower BIC by the margin is not screened on a residual at the
    # noise, and is above it (never-drawn driven set tanh/21/delay: Bouc-Wen's delay refit
    # went to 0, a compliant mount took most of its excess, tanh with the delay was never
    # tried)
    wanted.bic_after = -1003.0
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    assert out.family == "bouc-wen" and len(screen) == 3 and len(seen) == 3
    loop.unexplained = True
    out = ag.compare_again(table, "bouc-wen", loop, ctx, {"channel_delay": {"tau_d": 0.002}})
    assert len(screen) == 4 and len(seen) == 4 and out.family == "tanh"


def test_a_play_the_library_read_enters_the_comparison_when_another_family_fits_with_it(
    monkeypatch,
):
    # issue 35, the other-lab stand-in: the library named the true 0.5 mm of play on the
    # residual of the selected bouc-wen-std, whose refit with it collapsed; Spencer, refitted
    # with the play from the library's width, fits far better than bouc-wen-std predicts
    from types import SimpleNamespace as NS

    import hystdisc.closing.again as ag
    import hystdisc.closing.reselect as rs

    def fit(bic, heldout, rms=None, effects=()):
        return NS(bic=bic, heldout_rms=heldout, rms=rms, n_params=8, par=NS(effects=effects),
                  params={}, term_part=NS(torque={}), is_system=False)  # fmt: skip

    collapsed = NS(name="backlash", ok=True, improves=False, significant=False,
                   admissible=True, predicts=False)  # fmt: skip
    loop = NS(fit=fit(-1000.0, 106.0), effects=[], tried=[collapsed],
              pointed={"backlash": {"r_b": 0.0005}})  # fmt: skip
    screen, seen = [], []

    def alone(table, effects, data, eq, values, shapes, max_nfev, heldout, mapper):
        screen.append((sorted(table), effects, values, heldout))
        return {n: fit(0.0, None, rms[n], ("backlash",)) for n in table}

    refits = {"bouc-wen-std": fit(-1100.0, 105.0, 100.0, ("backlash",)),
              "spencer": fit(-3000.0, 24.4, 24.3, ("backlash",))}  # fmt: skip
    monkeypatch.setattr(ag, "refit_families", alone)
    monkeypatch.setattr(rs, "refit_families", lambda *a, **kw: seen.append(a) or dict(refits))
    monkeypatch.setattr(rs, "check_admissible", lambda *args: NS(ok=True, violations=[]))
    monkeypatch.setattr(ag, "reduce_family", lambda *args: None)
    closed = NS(fit=refits["spencer"], effects=["backlash"])
    ctx = rs.Context(NS(), None, None, lambda f: closed, lambda f: None)
    table = dict.fromkeys(refits)
    rms = {"spencer": 130.0}  # above bouc-wen-std's held-out 106: not compared again
    out = ag.compare_again(table, "bouc-wen-std", loop, ctx)
    assert screen == [(["spencer"], ["backlash"], {"r_b": 0.0005}, False)] and seen == []
    assert out.family == "bouc-wen-std" and out.reselection is None
    rms["spencer"] = 24.3  # below it: compared again with the play, from its width
    out = ag.compare_again(table, "bouc-wen-std", loop, ctx)
    (args,) = seen
    assert args[1] == ["backlash"] and args[4] == {"r_b": 0.0005}  # effects, start
    assert out.family == "spencer" and out.loop is closed
    # an effect the loop accepted is not screened again
    loop.effects = ["backlash"]
    ag.compare_again(table, "bouc-wen-std", loop, ctx)
    assert len(screen) == 2


def test_the_record_says_what_was_compared(base):
    fits = {n: base.family_fits_[n] for n in ("dahl", "bouc-wen")}
    res = Reselection(["offset"], fits, {"dahl": True, "bouc-wen": True}, "dahl", "bouc-wen")
    res.final_heldout = {"dahl": 2e-3, "bouc-wen": 1e-3}
    d = res.to_dict()
    assert d["effects"] == ["offset"] and d["pick"] == "bouc-wen" and not d["switched"]
    assert d["families"]["dahl"]["heldout_rms"] == fits["dahl"].heldout_rms
    assert set(d["families"]["bouc-wen"]) == {"rms", "heldout_rms", "bic", "admissible"}


def test_the_console_table_shows_the_families_with_the_rigs_effect():
    from hystdisc.results import Results
    from hystdisc.results.sections import ReselectionRecord

    res = Results(
        family="dahl",
        reselection=ReselectionRecord.from_dict(
            {
                "effects": ["offset"],
                "families": {
                    "dahl": {"heldout_rms": 0.002, "admissible": True},
                    "bouc-wen": {"heldout_rms": 0.001, "admissible": False},
                },
                "switched": False,
                "note": "with offset in every family, dahl is still selected",
            }
        ),
    )
    lines = res.family_table().splitlines()
    assert "held-out RMS with offset: dahl 0.002, bouc-wen 0.001 (not physical)" in lines
    assert "selection again: with offset in every family, dahl is still selected" in lines


def test_the_whole_estimator_switches_to_the_true_form_with_the_damper_effect(damper):
    """End to end (``closing/again.py``): the table picks the seed form, the loop finds
    the quadratic damping on it, the forms compared again with it pick the standard form,
    the loop is closed again from it, and the rule keeps the switch on the final models."""
    disc = damper
    res = disc.reselection_
    assert res.before == "bouc-wen" and res.effects == ["quadratic_damping"] and res.switched
    assert disc.family_ == "bouc-wen-std" and disc.effects_ == ["quadratic_damping"]
    assert disc.results_.reselection["switched"] is True and disc.reduction_ is None
    # the equal fits are read in the comparison that made the switch (both forms with the
    # effect), not in the table without it
    bics = {n: f.bic for n, f in res.fits.items()}
    want = [n for n in bics if n != disc.family_ and bics[n] - bics[disc.family_] < 6.0]
    assert disc.equal_fits_ == want
    lo, hi = disc.final_fit_.ci95["c_q"]
    assert lo < C_Q < hi and disc.final_fit_.rms < 1.03 * disc.noise_std_
