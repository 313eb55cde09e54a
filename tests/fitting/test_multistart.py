"""Global output-error fits (issue 16 items 1 and 2): several starts per family, nesting
consistency, and effects refitted from several starts.

Every dataset is written by the package's simulator with parameter values picked here
(not the demo defaults).
"""

from __future__ import annotations

import dataclasses
from functools import cache

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.cli import main
from hystdisc.data import load
from hystdisc.fitting import FamilyParametrization, OutputErrorFitter
from hystdisc.fitting.multistart import (
    best_of_starts,
    mapped_starts,
    nesting_pass,
    random_starts,
    start_rss,
)
from hystdisc.models import Model
from hystdisc.registry import get_family
from hystdisc.selection.staged import levels_start
from hystdisc.simulation.synth import generate

DAHL = {"k_x": 0.45, "k_wa": 0.7, "k_wb": 1.6, "rho": 30.0, "k_s": 135.0}
NOISE = 1e-3


@cache
def _dahl_fit():
    data = generate(Model("dahl", DAHL), currents=(0, 0.5, 1), duration=3, noise=NOISE, seed=4)
    return Discovery(families=["dahl", "lugre"], close_loop=False, heldout=False).fit(data)


def test_a_family_never_ends_worse_than_a_model_it_contains():
    d = _dahl_fit()
    fd, dahl = d.fit_data_, d.family_fits_["dahl"]
    # LuGre contains Dahl: Dahl's optimum maps into it exactly (zero extra terms)
    (start,) = mapped_starts("lugre", dahl)
    par = FamilyParametrization("lugre", "release", start)
    assert abs(start_rss(fd, par, dahl.nuisance) / dahl.rss - 1.0) < 1e-6
    # a LuGre fit that ended in a poor place (its parameters and RSS there) ...
    lugre = d.family_fits_["lugre"]
    bad_par = FamilyParametrization(
        "lugre",
        "release",
        {**start, "sigma_0": start["sigma_0"] / 10, "sigma_a": start["sigma_a"] / 5},
    )
    rss = start_rss(fd, bad_par, lugre.nuisance)
    n = lugre.n_obs
    bad = dataclasses.replace(
        lugre,
        par=bad_par,
        x=bad_par.x0,
        rss=rss,
        rms=float(np.sqrt(rss / n)),
        notes=[],
        starts=None,
        starts_note=None,
    )
    assert bad.rms > 1.5 * dahl.rms
    # ... is refitted from Dahl's optimum and ends at least as good as Dahl
    out = nesting_pass(fd, {"dahl": dahl, "lugre": bad}, max_nfev=40)
    assert out["dahl"] is dahl
    assert out["lugre"].rss <= dahl.rss * (1 + 1e-6)
    assert out["lugre"].nested_from == "dahl"
    assert any("refitted from the optimum of dahl" in n for n in out["lugre"].notes)


def test_a_family_above_the_floor_screens_an_approximate_optimum_that_starts_worse():
    """A seed-form Bouc-Wen on a 2048-count encoder (values of a stress-suite set the
    first two suites never drew) stuck at 1.3 times the floor near n = 0.1; the standard
    form, at the floor, maps into it only approximately: both readings start worse than
    the stuck fit, yet 8 iterations from one reach the floor and the truth."""
    truth = {"alpha_1": 0.445627, "alpha_2": 2.96231, "c_1": 0.25198, "c_2": 1.10231}
    truth |= {"beta": 7.36134, "gamma": 5.1155, "delta": 15.8588, "n": 0.593995, "k_s": 150.126}
    data = generate(
        Model("bouc-wen", truth), currents=(0, 0.5, 1), duration=3, noise=0.0,
        encoder_counts=2048, seed=5,
    )  # fmt: skip
    d = Discovery(families=["bouc-wen"], close_loop=False, heldout=False, n_starts=1).fit(data)
    fd = d.fit_data_
    floor = fd.noise_std

    def fit(family, start):
        par = FamilyParametrization(family, "release", {**start, "J": 1.0})
        return OutputErrorFitter(fd, par, max_nfev=40).fit(heldout=False)

    std = fit("bouc-wen-std", {"alpha_1": 0.53, "alpha_2": 3.64, "c_1": 0.26, "c_2": 1.11,
                               "beta": 6.9, "gamma": 4.59, "n": 1.28, "k_s": 150.2})  # fmt: skip
    stuck = fit("bouc-wen", {"alpha_1": 0.8, "alpha_2": 4.2, "c_1": 0.2, "c_2": 0.97,
                             "beta": 29.2, "gamma": 7.2, "n": 0.031, "k_s": 149.4})  # fmt: skip
    assert std.rms < 1.1 * floor < stuck.rms
    for p in mapped_starts("bouc-wen", std):  # every reading starts worse than the stuck fit
        assert start_rss(fd, FamilyParametrization("bouc-wen", "release", p)) > stuck.rss
    fits = {"bouc-wen": stuck, "bouc-wen-std": std}
    assert nesting_pass(fd, fits, max_nfev=40)["bouc-wen"] is stuck  # raw starts only
    new = nesting_pass(fd, fits, max_nfev=40, screen_above=1.1 * floor)["bouc-wen"]
    assert new.rms < 1.01 * floor
    # the truth in the family's normalization (z_sat = 1), as results.json reports it
    fam = get_family("bouc-wen")
    own = fam.from_terms(fam.to_terms({k: v for k, v in truth.items() if k != "k_s"}))
    for k, v in own.items():
        assert new.params[k] == pytest.approx(v, rel=0.03), k
    assert new.nested_from == "bouc-wen-std"
    # the notes are the new optimum's own and the refit's; none of the stuck fit's
    assert not set(stuck.notes) & set(new.notes)
    assert any("after 8 iterations" in n for n in new.notes)


def test_a_declared_family_above_the_floor_is_started_from_its_related_families():
    """--model bouc-wen on a 2048-count encoder (the set above, two currents, 6 s): stage
    1's start and its basins end at 19 times the floor; the standard form, Dahl and LuGre,
    fitted as starts only, take it to the floor and its truth, and only the declared
    family is reported."""
    truth = {"alpha_1": 0.445627, "alpha_2": 2.96231, "c_1": 0.25198, "c_2": 1.10231}
    truth |= {"beta": 7.36134, "gamma": 5.1155, "delta": 15.8588, "n": 0.593995, "k_s": 150.126}
    data = generate(
        Model("bouc-wen", truth), currents=(0.25, 1), duration=6, noise=0.0,
        encoder_counts=2048, seed=5,
    )  # fmt: skip
    d = Discovery(model="bouc-wen", close_loop=False, heldout=False).fit(data)
    assert list(d.family_fits_) == ["bouc-wen"]
    fit = d.family_fits_["bouc-wen"]
    assert fit.rms < 1.01 * d.fit_data_.noise_std
    fam = get_family("bouc-wen")
    own = fam.from_terms(fam.to_terms({k: v for k, v in truth.items() if k != "k_s"}))
    for k, v in own.items():
        assert fit.params[k] == pytest.approx(v, rel=0.05), k
    assert any("bouc-wen-std, dahl, lugre were fitted too" in n for n in fit.notes)


@pytest.mark.parametrize("family", ["bouc-wen", "bouc-wen-std"])
def test_dahl_maps_into_bouc_wen_where_its_exponent_makes_the_gamma_term_dahls(family):
    # seed form: |w| z |z|^n at n -> 0 (the lower bound); standard form: |w| z |z|^(n-1)
    # at n = 1; either way Bouc-Wen reproduces Dahl's optimum from that start
    d = _dahl_fit()
    fd, dahl = d.fit_data_, d.family_fits_["dahl"]
    (start,) = mapped_starts(family, dahl)
    assert start["n"] == (1e-4 if family == "bouc-wen" else 1.0)
    assert start["gamma"] > 0 and start["beta"] == 0
    par = FamilyParametrization(family, "release", start)
    assert abs(start_rss(fd, par, dahl.nuisance) / dahl.rss - 1.0) < 1e-3


def test_best_of_starts_keeps_the_best_basin_and_says_how_many_reached_it():
    d = _dahl_fit()
    fd, dahl = d.fit_data_, d.family_fits_["dahl"]
    good = {k: dahl.params[k] for k in (*DAHL, "J") if k in dahl.params}
    far = {**good, "rho": 0.3, "k_wa": 5.0, "k_wb": 0.05}  # a start far off
    starts = [("far", far), ("good", good), *random_starts("dahl", good, 1, seed=1)]
    pars = [(lb, FamilyParametrization("dahl", "release", st)) for lb, st in starts]
    fit = best_of_starts(fd, pars, max_nfev=40, screen_nfev=4)
    assert abs(fit.rms / NOISE - 1.0) < 0.05
    assert fit.rss <= dahl.rss * (1 + 1e-3)
    note = [n for n in fit.notes if "starts reached the optimum" in n][0]
    # the far start did not reach the optimum in its screen, and the note says so
    assert note.startswith("1 of 3") and "RMS within 1%: good)" in note and "(far)" in note
    assert set(fit.starts) == {"far", "good", "random 1"}
    # with the noise floor known, a first start at the floor ends the search
    pars = [(lb, FamilyParametrization("dahl", "release", st)) for lb, st in starts[1:]]
    fit = best_of_starts(fd, pars, max_nfev=40, good_rms=1.1 * NOISE)
    assert fit.starts.keys() == {"good"}
    assert any("the others were not needed" in n for n in fit.notes)


def test_a_screen_that_stalls_far_above_the_first_start_can_still_win():
    """Why a screen is not stopped early once it looks clearly worse (issue 17 item 2):
    this start is 14 times the first start's RMS after one step and gains only 5 % of its
    RSS in the second (a stalled search by any rule on the trajectory), then reaches the
    noise floor in the screen's remaining steps and is the best start. best_of_starts
    screens every start its full iterations, so it is kept."""
    d = _dahl_fit()
    fd, dahl = d.fit_data_, d.family_fits_["dahl"]
    good = {k: dahl.params[k] for k in (*DAHL, "J") if k in dahl.params}
    par = FamilyParametrization("dahl", "release", {**good, "rho": 3000.0})
    # a first start that ended in a poorer place (1.5 times the noise)
    first = dataclasses.replace(
        dahl, rss=2.25 * dahl.rss, rms=1.5 * dahl.rms, notes=[], starts=None, starts_note=None
    )
    rms = {}
    for steps in (1, 2):
        _, rss = OutputErrorFitter(fd, par).screen(steps)
        rms[steps] = np.sqrt(rss / dahl.n_obs)
    assert rms[1] > 10 * first.rms and rms[2] ** 2 > 0.9 * rms[1] ** 2
    fit = best_of_starts(fd, [("first", dahl.par), ("rho off", par)], max_nfev=40, first=first)
    assert fit.rss <= dahl.rss * (1 + 1e-3) and fit.starts["rho off"] == fit.rms
    assert "RMS within 1%: rho off)" in fit.notes[-1]


def test_a_lone_familys_starts_are_screened_on_the_threads_with_the_same_answer(monkeypatch):
    """When one family alone is fitted from more starts, its starts run on the discovery's
    threads (issue 17: wall time) and the fit is the same, bit for bit, as in turn."""
    import hystdisc.pipeline.starts as estimator

    mappers = []

    def recording(*args, **kwargs):
        mappers.append(kwargs.get("mapper"))
        fit = best_of_starts(*args, **kwargs)
        return dataclasses.replace(fit, notes=[*fit.notes, "recorded"])

    monkeypatch.setattr(estimator, "best_of_starts", recording)
    monkeypatch.setattr(estimator, "NOISE_RATIO", 0.0)  # every fit is above the "floor"
    # ... and Dahl stays alone (no LuGre fitted as its start)
    monkeypatch.setattr(estimator, "helper_families", lambda fits, good, poor=(): {})
    data = generate(Model("dahl", DAHL), currents=(0, 0.5, 1), duration=2, noise=NOISE, seed=5)
    fits = {}
    for jobs in (1, 2):
        opts = {"families": ["dahl"], "close_loop": False, "heldout": False, "n_jobs": jobs}
        fits[jobs] = Discovery(**opts).fit(data).family_fits_["dahl"]
    assert len(mappers) == 2 and all(m is not None for m in mappers)
    assert all("recorded" in f.notes for f in fits.values())  # the estimator keeps it
    assert len(fits[1].starts) > 1  # it was fitted from more starts
    assert fits[2].starts == fits[1].starts
    assert fits[2].params == fits[1].params and fits[2].rss == fits[1].rss


def test_random_starts_stay_inside_the_admissible_box():
    from hystdisc.models import get_family

    fam = get_family("bouc-wen")
    start = {**Model("bouc-wen").params}
    for _, st in random_starts("bouc-wen", start, 20, seed=3):
        for p in fam.params:
            assert p.lower <= st[p.name] <= p.upper
        assert st["k_s"] > 0 and abs(st["n"] - start["n"]) <= 1.0


@pytest.fixture(scope="module")
def offset_run(tmp_path_factory):
    """Seed-form Bouc-Wen whose spring rests at 0.02 rad, declared with --model bouc-wen.

    One start stops at 10 times the noise with n = 9.4 (its stage-1 shape absorbed the
    offset); the loop then has to find ``offset`` from a stage-1 start that begins above
    the current optimum and converges to the noise."""
    out = tmp_path_factory.mktemp("offset")
    sets = "alpha_1=0.6,alpha_2=1.3,c_1=0.45,c_2=0.7,beta=8,gamma=12,n=1.2,k_s=150"
    argv = ["simulate", "--model", "bouc-wen", "--set", sets, "--effect"]
    argv += ["offset:theta_off=0.02", "--currents", "0,0.25,0.5,0.75,1", "--duration", "3"]
    argv += ["--noise", str(NOISE), "--seed", "3", "-o", str(out / "off.csv"), "--quiet"]
    assert main(argv) == 0
    return Discovery(model="bouc-wen").fit(load(out / "off.csv"))


def test_the_loop_finds_an_offset_from_several_starts(offset_run):
    loop = offset_run.loop_
    assert loop.effects == ["offset"]
    p, ci = loop.fit.params, loop.fit.ci95
    assert abs(p["theta_off"] / 0.02 - 1.0) < 0.02
    assert ci["theta_off"][0] < 0.02 < ci["theta_off"][1]
    noise = offset_run.noise_std_
    assert loop.fit.rms < 1.05 * noise and loop.fit.heldout_rms < 1.05 * noise
    assert not loop.unexplained
    # no stiffening or damping term stands in for the offset
    assert not {"cubic_stiffness", "quadratic_damping"} & set(loop.effects)


def test_a_local_effect_refit_that_falls_short_runs_once_more_from_the_fallback():
    """refit_with: the fallback start (the loop's stage-1 start, made on demand) is asked
    for only when the local refit falls short of the floor, and the better of the two
    refits by BIC is kept."""
    from hystdisc.closing.refit import refit_with

    truth = {**DAHL, "theta_off": 0.015}
    data = generate(
        Model("dahl", DAHL, effects={"offset": {"theta_off": 0.015}}), currents=(0, 0.5, 1),
        duration=2, noise=NOISE, seed=8,
    )  # fmt: skip
    d = Discovery(model="dahl", close_loop=False, heldout=False, n_starts=1).fit(data)
    fd, base = d.fit_data_, d.family_fits_["dahl"]
    asked = []

    def fallback():
        asked.append(1)
        return {**truth, "J": 1.0}

    near = refit_with(fd, base, "offset", good_rms=10 * NOISE, fallback=fallback)
    assert not asked  # the local refit reached the floor: no second start
    # a floor no fit reaches: the fallback runs, and the lower BIC of the two is kept
    both = refit_with(fd, base, "offset", good_rms=0.0, fallback=fallback)
    assert asked == [1]
    par = base.par.like({**truth, "J": 1.0}, ("offset",))
    alone = OutputErrorFitter(fd, par).fit(heldout=False)
    assert both.bic <= min(near.bic, alone.bic) + 1e-6
    assert refit_with(fd, base, "offset", good_rms=0.0, fallback=lambda: None).bic == near.bic


def test_current_levels_start_undoes_a_trade_between_the_slopes():
    # a joint Bingham fit can trade the viscous slope c_b against the friction slope f_b;
    # fitted one current level at a time there is no slope to trade, and the lines
    # through the levels give both back
    truth = {"c_a": 0.42, "c_b": 0.47, "f_a": 0.59, "f_b": 0.77, "k_s": 212.7}
    data = generate(Model("bingham", truth), currents=(0, 0.5, 1), duration=2, noise=NOISE, seed=11)
    d = Discovery(model="bingham", close_loop=False, heldout=False).fit(data)
    fit = d.family_fits_["bingham"]
    swapped = {**fit.params, "c_b": fit.params["f_b"], "f_b": fit.params["c_b"]}
    lv = levels_start(d.fit_data_, fit.par.like(swapped, ()), swapped)
    for k in ("c_a", "c_b", "f_a", "f_b"):
        assert lv[k] == pytest.approx(truth[k], rel=0.05), k


def test_a_family_far_above_the_best_one_is_fitted_from_more_starts_too():
    # Bingham on Bouc-Wen data ends far above the best family (15x on the bundled set):
    # a far-off family may be the true one in a wrong basin (the stress suite's
    # bingham/1/enc4096 stopped at 4.9x LuGre's RMS from stage 1's start and reached the
    # floor only from its current-levels start), so it gets the other starts as well
    bw = {
        "alpha_1": 0.4,
        "alpha_2": 1.2,
        "c_1": 0.45,
        "c_2": 0.5,
        "beta": 9.0,
        "gamma": 11.0,
        "delta": 20.0,
        "n": 1.2,
        "k_s": 140.0,
    }
    data = generate(Model("bouc-wen", bw), currents=(0, 0.5, 1), duration=2, noise=NOISE, seed=8)
    est = Discovery(families=["bingham", "bouc-wen"], close_loop=False, heldout=False).fit(data)
    fits = est.family_fits_
    assert fits["bingham"].rms > 3 * fits["bouc-wen"].rms
    assert any("starts reached the optimum" in n for n in fits["bingham"].notes), fits[
        "bingham"
    ].notes


def test_a_family_whose_held_out_prediction_diverged_is_not_selected():
    # the stress suite's bingham/1/enc4096 crashed here (a None held-out RMS divided)
    from types import SimpleNamespace as NS

    def fit(bic, k, held):
        return NS(bic=bic, n_params=k, heldout_rms=held)

    from hystdisc.selection import select_family

    admissibility = dict.fromkeys(("bingham", "dahl", "lugre"), NS(ok=True, violations=[]))
    # dahl has the lowest BIC but its held-out prediction diverged
    fits = {
        "bingham": fit(-100.0, 10, 1.0e-3),
        "dahl": fit(-300.0, 10, None),
        "lugre": fit(-200.0, 12, 1.05e-3),
    }
    family, note = select_family(fits, admissibility)
    assert family == "lugre"
    assert note == "BIC prefers dahl, but its held-out prediction diverged: lugre selected"
    # without held-out errors (--no-heldout) BIC alone decides
    for f in fits.values():
        f.heldout_rms = None
    assert select_family(fits, admissibility) == ("dahl", None)
