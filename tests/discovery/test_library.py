"""The pysindy torque library (the design matrix of stage 1) and the hysteresis shapes."""

from __future__ import annotations

import numpy as np
import pysindy as ps
import pytest

from hystdisc.discovery import (
    DEFAULT_TORQUE_TERMS,
    FAMILY_SHAPE,
    SHAPES,
    Design,
    EqData,
    HysteresisShape,
    TorqueLibrary,
    torque_state,
)
from hystdisc.models import HYSTERESIS_TERM_NAMES, TORQUE_TERM_NAMES, Z_TORQUE_TERMS
from hystdisc.models.shapes import N_RANGE, shape_of
from hystdisc.registry import family_names, get_family


def _state(n=200, seed=0):
    rng = np.random.default_rng(seed)
    th, w, z = rng.normal(size=(3, n))
    i = rng.choice([0.0, 0.5, 1.25, 2.0], size=n)
    return torque_state(th, w, z, i)


def test_feature_names_and_sizes():
    lib = TorqueLibrary().fit(np.zeros((2, 4)))
    assert lib.get_feature_names() == list(DEFAULT_TORQUE_TERMS)
    assert lib.get_feature_names(["a", "b", "c", "d"]) == list(DEFAULT_TORQUE_TERMS)
    assert (lib.n_features_in_, lib.n_output_features_) == (4, len(DEFAULT_TORQUE_TERMS))
    assert lib.transform(_state()).shape == (200, len(DEFAULT_TORQUE_TERMS))


def test_transform_values_by_hand():
    x = np.array([[0.5, -2.0, 0.25, 1.5], [-1.0, 3e-4, -0.5, 0.0]])
    lib = TorqueLibrary(TORQUE_TERM_NAMES).fit(x)
    F = dict(zip(lib.get_feature_names(), lib.transform(x).T, strict=True))
    sgn = np.tanh(np.array([-2.0, 3e-4]) / 1e-3)
    expected = {
        "theta": [0.5, -1.0],
        "theta_dot": [-2.0, 3e-4],
        "i*theta_dot": [-3.0, 0.0],
        "z": [0.25, -0.5],
        "i*z": [0.375, 0.0],
        "|theta_dot|*z": [0.5, -1.5e-4],
        "sign(theta_dot)": sgn,
        "i*sign(theta_dot)": [1.5 * sgn[0], 0.0],
        "i^2*z": [0.5625, 0.0],
        "theta_dot*|theta_dot|": [-4.0, 9e-8],
        "theta^3": [0.125, -1.0],
        "1": [1.0, 1.0],
        "i^2*theta_dot": [-4.5, 0.0],
        # the library evaluates the shear-thinning term at m = 0.5, sign smoothed by 1e-3
        "sign(theta_dot)*|theta_dot|^m": [
            -2.0 * (4.0 + 1e-6) ** -0.25,
            3e-4 * (9e-8 + 1e-6) ** -0.25,
        ],
        "i^2*sign(theta_dot)": [2.25 * sgn[0], 0.0],
        "i": [1.5, 0.0],
        "|theta_dot|": [2.0, 3e-4],
        "i*|theta_dot|": [3.0, 0.0],
        "i^2*|theta_dot|": [4.5, 0.0],
        "|z|": [0.25, 0.5],
        "i*|z|": [0.375, 0.0],
        "i^2*|z|": [0.5625, 0.0],
    }
    assert set(F) == set(expected)
    for name, values in expected.items():
        np.testing.assert_allclose(F[name], values, rtol=1e-15, atol=0, err_msg=name)
    assert sgn[0] == -1.0 and 0.29 < sgn[1] < 0.3


def test_z_refresh_equals_full_transform_bit_for_bit():
    x = _state()
    lib = TorqueLibrary(TORQUE_TERM_NAMES).fit(x)
    F, factors = lib.transform_z_free(x * np.array([1.0, 1.0, np.nan, 1.0]))  # z not read
    assert [j for j, _, _ in factors] == [
        k for k, t in enumerate(TORQUE_TERM_NAMES) if t in Z_TORQUE_TERMS
    ]
    for seed in (1, 2):
        z = np.random.default_rng(seed).normal(size=x.shape[0])
        xz = x.copy()
        xz[:, 2] = z
        np.testing.assert_array_equal(TorqueLibrary.refresh_z(F, z, factors), lib.transform(xz))


def test_transform_z_free_writes_into_a_view():
    x = _state(50)
    lib = TorqueLibrary(["theta", "z", "sign(theta_dot)"]).fit(x)
    big = np.full((50, 4), -7.0)
    F, factors = lib.transform_z_free(x, out=big[:, 1:])
    TorqueLibrary.refresh_z(F, x[:, 2], factors)
    np.testing.assert_array_equal(big[:, 1:], lib.transform(x))
    assert np.all(big[:, 0] == -7.0)


def test_bad_input():
    with pytest.raises(ValueError, match="unknown torque terms"):
        TorqueLibrary(["theta", "nope"]).fit(np.zeros((3, 4)))
    with pytest.raises(ValueError, match=r"\[theta, theta_dot, z, i\]"):
        TorqueLibrary().fit(np.zeros((3, 3)))


def test_list_of_trajectories():
    xs = [_state(30, 1), _state(40, 2)]
    lib = TorqueLibrary(["theta", "i*z"]).fit(xs)
    out = lib.transform(xs)
    assert [f.shape for f in out] == [(30, 2), (40, 2)]
    np.testing.assert_array_equal(np.asarray(out[1]), lib.transform(xs[1]))


def _dahl_toy(rho=20.0, n=2000):
    """A Dahl damper at four currents, exact signals: theta, theta_dot, z and the torque."""
    from hystdisc.models import SIGN_EPS
    from hystdisc.simulation import integrate_z

    t = np.linspace(0.0, 2.0, n)
    runs = []
    for k, i in enumerate((0.0, 0.5, 1.0, 1.5)):
        th = 0.2 * np.sin(2 * np.pi * (1.0 + 0.25 * k) * t)
        w = 0.2 * 2 * np.pi * (1.0 + 0.25 * k) * np.cos(2 * np.pi * (1.0 + 0.25 * k) * t)
        b = np.zeros(len(HYSTERESIS_TERM_NAMES))
        b[0], b[1] = rho, -rho
        (z,) = integrate_z(b, 1.0, [t], [w], SIGN_EPS)
        runs.append((t, th, w, z, i))
    return runs


def test_sindy_with_control_recovers_known_coefficients():
    """The library inside pysindy.SINDy: state [theta, theta_dot, z], control u = i."""
    rho, k_s, c0, ka, kb = 20.0, 3.0, 0.4, 0.5, 1.5
    ts, xs, us, xdots = [], [], [], []
    for t, th, w, z, i in _dahl_toy(rho):
        ts.append(t)
        torque = c0 * w + ka * z + kb * i * z
        xs.append(np.column_stack([th, w, z]))
        us.append(np.full((t.size, 1), i))
        # release-type dynamics (unit inertia) and the Dahl rate
        xdots.append(np.column_stack([w, -k_s * th - torque, rho * (w - np.abs(w) * z)]))
    lib = TorqueLibrary(["theta", "theta_dot", "i*theta_dot", "z", "i*z", "|theta_dot|*z"])
    model = ps.SINDy(feature_library=lib, optimizer=ps.STLSQ(threshold=0.05))
    model.fit(xs, t=ts, x_dot=xdots, u=us)
    assert model.get_feature_names() == lib.get_feature_names()
    C = model.coefficients()
    expected = np.array(
        [
            [0.0, 1.0, 0.0, 0.0, 0.0, 0.0],
            [-k_s, -c0, 0.0, -ka, -kb, 0.0],
            [0.0, rho, 0.0, 0.0, 0.0, -rho],
        ]
    )
    np.testing.assert_allclose(C, expected, atol=1e-8)


def test_stlsq_on_the_library_drops_absent_terms():
    runs = _dahl_toy()
    x = np.vstack([torque_state(th, w, z, i) for _, th, w, z, i in runs])
    lib = TorqueLibrary(DEFAULT_TORQUE_TERMS).fit(x)
    F = lib.transform(x)
    truth = dict.fromkeys(DEFAULT_TORQUE_TERMS, 0.0) | {"theta": 2.0, "theta_dot": 0.3, "i*z": 1.2}
    y = F @ np.array([truth[t] for t in DEFAULT_TORQUE_TERMS])
    opt = ps.STLSQ(threshold=0.05).fit(F, y)
    found = dict(zip(lib.get_feature_names(), np.ravel(opt.coef_), strict=True))
    for t, v in truth.items():
        assert found[t] == pytest.approx(v, abs=1e-9), t


def test_design_is_the_library_on_the_equation_rows():
    """Stage 1's design matrix: the inertia column of a forced experiment, then the library."""
    rng = np.random.default_rng(3)
    t = np.linspace(0.0, 1.0, 40)
    th, w, a, y = (rng.normal(size=(2, 40)) for _ in range(4))
    rows = [np.arange(40) % 3 != 0, np.arange(40) > 5]
    eq = EqData("forced", [t, t], list(th), list(w), list(a), list(y), np.array([0.5, 2.0]), rows)
    terms = ["theta", "z", "i*z", "sign(theta_dot)", "|theta_dot|*z"]
    design = Design(eq, terms)
    z = [rng.normal(size=40) for _ in range(2)]
    F, target = design.build(z)
    x = np.vstack(
        [torque_state(th[k][m], w[k][m], z[k][m], eq.currents[k]) for k, m in enumerate(rows)]
    )
    np.testing.assert_array_equal(F[:, 1:], TorqueLibrary(terms).fit(x).transform(x))
    np.testing.assert_array_equal(F[:, 0], np.concatenate([a[k][m] for k, m in enumerate(rows)]))
    np.testing.assert_array_equal(target, np.concatenate([y[k][m] for k, m in enumerate(rows)]))
    # a driven experiment has no inertia column
    eq.experiment = "driven"
    assert Design(eq, terms).build(z)[0].shape[1] == len(terms)


# ----------------------------------------------------------------------------- shapes


def test_shapes_are_classes_without_name_tests():
    assert set(SHAPES) == {"none", "dahl", "bouc-wen", "bouc-wen-std"}
    for name, sh in SHAPES.items():
        assert isinstance(sh, HysteresisShape) and sh.name == name
        assert sh.has_state == bool(sh.terms)
        assert set(sh.terms) <= set(HYSTERESIS_TERM_NAMES)


def test_shape_vectors_and_constants():
    b, n = SHAPES["none"].vector(np.zeros(0))
    assert (b.tolist(), n) == ([0.0] * 5, 1.0)
    b, n = SHAPES["dahl"].vector(np.log([20.0]))
    np.testing.assert_allclose(b, [20.0, -20.0, 0.0, 0.0, 0.0], rtol=1e-15)
    assert n == 1.0
    s = np.array([np.log(10.0), 0.25, np.log(2.0)])
    d = SHAPES["bouc-wen"].shape_dict(s)
    assert d == pytest.approx({"delta": 10.0, "beta": 2.5, "gamma": 7.5, "n": 2.0}, rel=1e-14)
    b, n = SHAPES["bouc-wen"].vector(s)
    np.testing.assert_allclose(b, [10.0, 0.0, -2.5, -7.5, 0.0], rtol=1e-14)
    s = np.array([np.log(10.0), np.pi / 6, np.log(2.0)])
    b, n = SHAPES["bouc-wen-std"].vector(s)
    np.testing.assert_allclose(b, [10.0, 0.0, -10 * np.sqrt(3) / 2, 0.0, -5.0], rtol=1e-14)
    assert n == pytest.approx(2.0)


def test_shape_grids_and_clipping():
    assert [g.size for g in SHAPES["none"].grid(1.0)] == [0]
    assert len(SHAPES["dahl"].grid(0.5)) == 13
    assert len(SHAPES["bouc-wen"].grid(0.5)) == 7 * 4 * 3
    assert len(SHAPES["bouc-wen-std"].grid(0.5)) == 7 * 8 * 3
    lo = np.log(0.1 / 0.5)
    s = SHAPES["bouc-wen"].clip(np.array([-50.0, 9.0, 9.0]), 0.5)
    np.testing.assert_allclose(s, [lo, 3.0, np.log(N_RANGE[1])])
    s = SHAPES["bouc-wen-std"].clip(np.array([50.0, 3 * np.pi / 2, -9.0]), 0.5)
    np.testing.assert_allclose(s, [lo + np.log(3e3), -np.pi / 2, np.log(N_RANGE[0])])
    np.testing.assert_allclose(SHAPES["dahl"].clip(np.array([0.0]), 0.5), [0.0])


def test_family_shape_follows_the_registry():
    # each term family's shape carries that family's own hysteresis terms
    for name, shape in FAMILY_SHAPE.items():
        assert SHAPES[shape].terms == tuple(get_family(name).hysteresis_terms), name
    assert not SHAPES[FAMILY_SHAPE["bingham"]].has_state
    assert FAMILY_SHAPE["lugre"] == FAMILY_SHAPE["dahl"]  # LuGre shares Dahl's shape
    # the state-space families have no stage-1 shape
    systems = [n for n in family_names() if get_family(n).is_system]
    assert systems
    for name in systems:
        assert name not in FAMILY_SHAPE
        with pytest.raises(KeyError):
            FAMILY_SHAPE[name]
    assert len(FAMILY_SHAPE) == len(family_names()) - len(systems)
    assert FAMILY_SHAPE == {
        "bingham": "none",
        "dahl": "dahl",
        "lugre": "dahl",
        "bouc-wen": "bouc-wen",
        "bouc-wen-std": "bouc-wen-std",
    }
    assert shape_of(get_family("lugre")) == "dahl"
