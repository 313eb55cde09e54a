"""The estimator's scikit-learn contract: parameters, clone, fitted attributes, pickling.

scikit-learn's own estimator checks run where they apply: those about parameters,
construction, cloning, the repr and the tags. The checks that fit on random ``X``/``y``
arrays do not apply (``Discovery.fit`` takes a :class:`~hystdisc.data.Dataset` of
runs); what they test — ``fit`` returns ``self``, leaves the parameters alone, sets only
attributes ending in ``_``, and a fitted estimator pickles — is tested here on a small
synthetic dataset.
"""

from __future__ import annotations

import contextlib
import copy
import io
import pickle
from functools import cache

import numpy as np
import pytest
from sklearn import clone
from sklearn.utils import estimator_checks as checks

import hystdisc
from hystdisc.closing import LoopResult
from hystdisc.estimator import Discovery
from hystdisc.fitting import OEFit
from hystdisc.measurement import FitData
from hystdisc.models import Model
from hystdisc.simulation.synth import generate

#: A fit of a second or two: the declared family's own hysteresis shape only.
FAST = {"model": "dahl", "shapes": ("dahl",), "heldout": False}

SKLEARN_CHECKS = [
    "check_parameters_default_constructible",
    "check_no_attributes_set_in_init",
    "check_get_params_invariance",
    "check_set_params",
    "check_estimator_cloneable",
    "check_estimator_repr",
    "check_do_not_raise_errors_in_init_or_set_params",
    "check_estimator_tags_renamed",
    "check_mixin_order",
]


@cache
def _data():
    return generate(Model("dahl"), currents=(0.0, 0.5, 1.0), duration=2.0, noise=1e-3, seed=4)


@cache
def _fit_call() -> tuple[Discovery, dict, object]:
    """``Discovery(**FAST)`` fitted on ``_data()``: the estimator, a copy of its parameters
    before ``fit``, and what ``fit`` returned; made once for the tests that read it."""
    d = Discovery(**FAST)
    before = copy.deepcopy(d.get_params())
    return d, before, d.fit(_data())


def _fitted() -> Discovery:
    return _fit_call()[0]


@cache
def _without_loop() -> tuple[Discovery, str]:
    """``Discovery(**FAST, close_loop=False)`` fitted on ``_data()``, with what the fit
    wrote on stderr; made once for the tests that read it."""
    err = io.StringIO()
    with contextlib.redirect_stderr(err):
        d = Discovery(**FAST, close_loop=False).fit(_data())
    return d, err.getvalue()


def _same(a, b) -> bool:
    """Parameter values equal (sequences compared by their items)."""
    if isinstance(a, (list, tuple)) and isinstance(b, (list, tuple)):
        return list(a) == list(b)
    return a == b


# ----------------------------------------------------------------------------- parameters


def test_clone_round_trips_get_params():
    d = hystdisc.Discovery()
    c = clone(d)
    assert c is not d and c.get_params() == d.get_params()
    d2 = Discovery(families=["dahl", "lugre"], seed=3, verbose=2, n_jobs=1, close_loop=False)
    assert clone(d2).get_params() == d2.get_params()


def test_set_params_and_get_params():
    d = Discovery()
    params = d.get_params()
    assert "verbose" in params and "progress" not in params
    assert d.set_params(seed=5, families=("dahl",)) is d
    assert d.seed == 5 and d.get_params()["families"] == ("dahl",)
    with pytest.raises(ValueError):
        d.set_params(no_such_option=1)


def test_init_only_stores_its_arguments():
    d = Discovery(families=["dahl"], threshold=0.1)
    assert set(vars(d)) == set(d.get_params())
    assert d.families == ["dahl"] and d.threshold == 0.1


@pytest.mark.parametrize("check", SKLEARN_CHECKS)
def test_sklearn_estimator_checks(check):
    getattr(checks, check)("Discovery", Discovery())


# ----------------------------------------------------------------------------- fit


def test_fit_returns_self_and_leaves_the_parameters_alone():
    d, before, returned = _fit_call()  # Discovery(**FAST), its parameters, fit(_data())
    assert returned is d
    after = d.get_params()
    assert set(before) == set(after)
    assert all(_same(before[k], after[k]) for k in before), after


def test_fitted_attributes_end_in_underscore():
    d = _fitted()
    params = set(d.get_params())
    fitted = set(vars(d)) - params
    assert fitted and all(k.endswith("_") and not k.startswith("_") for k in fitted), fitted
    for name in ("fit_data_", "eq_data_", "loop_", "final_fit_", "effects_", "results_"):
        assert name in fitted, name
    assert isinstance(d.fit_data_, FitData)
    assert isinstance(d.loop_, LoopResult) and isinstance(d.final_fit_, OEFit)
    assert d.final_fit_ is d.loop_.fit and d.effects_ == list(d.loop_.effects)


def test_without_the_loop_the_final_fit_is_the_selected_one():
    d, _ = _without_loop()
    assert d.loop_ is None and d.effects_ == []
    assert d.final_fit_ is d.family_fits_[d.family_]
    assert "effects_tried" not in d.results_.summary()


def test_a_fitted_estimator_pickles():
    d = _fitted()
    e = pickle.loads(pickle.dumps(d))
    assert e.get_params() == d.get_params()
    assert e.family_ == d.family_ and e.effects_ == d.effects_
    assert e.results_.summary() == d.results_.summary()
    for p, q in zip(e.predict(_data()), d.predict(_data()), strict=True):
        np.testing.assert_array_equal(p, q)


def test_an_unfitted_estimator_pickles_and_clones_after_fit():
    d = Discovery(verbose=1)
    assert pickle.loads(pickle.dumps(d)).get_params() == d.get_params()
    c = clone(_fitted())
    assert not hasattr(c, "results_") and c.get_params() == _fitted().get_params()


# ----------------------------------------------------------------------------- progress


def test_verbose_prints_progress_on_stderr(capsys):
    Discovery(**FAST, close_loop=False, verbose=1).fit(_data())
    err = capsys.readouterr().err.splitlines()
    assert err and all(line.startswith("[") and " s] " in line for line in err), err
    assert any("stage 2: output-error fit of dahl" in line for line in err)


def test_progress_callback_replaces_verbose(capsys):
    messages: list[str] = []
    Discovery(**FAST, verbose=1).fit(_data(), progress=messages.append)
    assert capsys.readouterr().err == ""
    assert messages[0] == "preparing data (noise, derivatives)"
    assert "closing the loop: residual -> catalogued effects" in messages


def test_quiet_by_default():
    _, err = _without_loop()  # Discovery(**FAST, close_loop=False).fit(_data())'s stderr
    assert err == ""


def test_predict_labels_each_run():
    # issue 37: predict returned bare arrays, without run, time and current
    d, data = _fitted(), _data()
    preds = d.predict(data)
    assert [p.run for p in preds] == [r.name for r in data.runs]
    for p, r in zip(preds, data.runs, strict=True):
        assert p.current == r.current and p.signal == "theta"
        np.testing.assert_array_equal(p.t, r.t)
        np.testing.assert_array_equal(p.measured, r.theta)
        assert p.predicted.shape == r.theta.shape
        assert p.rms == pytest.approx(np.sqrt(np.mean((p.predicted - r.theta) ** 2)))
        # it still acts as the array of predicted values
        np.testing.assert_array_equal(p - r.theta, p.predicted - r.theta)
    table = preds.table()
    n = sum(r.n for r in data.runs)
    assert all(len(v) == n for v in table.values())
    assert list(table) == ["run", "t", "current", "measured", "predicted"]
    assert d.score(data) > 0.9  # score reads the predictions too


def test_the_fit_options_reach_every_fit(monkeypatch):
    """``Discovery(jacobian=...)`` and the pipeline's own integration settings travel with
    the fits' data to every fit of a discovery, the closing loop's refits included: with
    forward differences not one exact Jacobian is computed. An unknown mode fails before
    any fit."""
    import hystdisc.fitting.output_error as oe
    from hystdisc.errors import HystdiscError
    from hystdisc.pipeline import Options, run
    from hystdisc.simulation import Integration

    exact = []
    # the recorder returns None, as a diverged run does: the fit takes differences
    monkeypatch.setattr(oe, "exact_jacobian", lambda *args: exact.append(1))
    d = Discovery(**FAST, jacobian="forward").fit(_data())  # the loop on
    assert d.loop_ is not None and not d.failed_
    assert not exact and d.fit_data_.jacobian == "forward"
    how = Integration(max_sub=6)
    state = run(_data(), Options(**FAST, close_loop=False, integration=how))
    assert exact  # the default mode asks for exact Jacobians
    fd = state.fit_data
    assert fd.jacobian == "exact" and fd.integration == how
    assert fd.subset([1]).integration == how
    assert fd.bulk() is None or fd.bulk().integration == how
    with pytest.raises(HystdiscError, match="unknown Jacobian mode 'central'"):
        Discovery(**FAST, jacobian="central").fit(_data())
