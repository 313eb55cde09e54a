"""A new family or effect is one module (issue 34): declared in this file alone, registered
at run time, and carried by discovery, prediction, the report and the control export; and
no family or effect is named outside ``hystdisc/models/`` and the registry.
"""

from __future__ import annotations

import ast
import json
from pathlib import Path

import numpy as np
import pytest

import hystdisc
from hystdisc import registry
from hystdisc.estimator import Discovery
from hystdisc.models import Effect, Family, Model, TermModel
from hystdisc.models.params import Param, param_table
from hystdisc.simulation.synth import generate

PACKAGE = Path(hystdisc.__file__).resolve().parent


class FrictionDahl(Family):
    """A toy family: Dahl with a dry friction torque of its own."""

    name = "friction-dahl"
    title = "Dahl with dry friction (a plugin)"
    color = "tab:brown"
    params = param_table("""
        # name  unit       lower  upper  default  doc
        k_x     N*m*s/rad  0      BIG    0.8      viscous damping
        k_wa    N*m        0      BIG    0.5      passive hysteretic torque
        k_wb    N*m/A      0      BIG    1.5      current-dependent hysteretic torque
        f_d     N*m        0      BIG    0.4      dry friction
        rho     1/rad      1e-9   BIG    20       hysteresis rate
    """)
    normalization = "w saturates at 1"
    current_params = ("k_wb",)
    current_laws = {"k_w": ("k_wa", "k_wb")}
    law_terms = {"k_w": "z"}
    linear_torque = {"theta_dot": "k_x", "z": "k_wa", "i*z": "k_wb", "sign(theta_dot)": "f_d"}
    torque_terms = tuple(linear_torque)
    hysteresis_terms = ("theta_dot", "|theta_dot|*z")
    correspondence = {"theta_dot": "k_x", "z": "k_wa", "i*z": "k_wb"}

    def to_terms(self, p):
        return TermModel(self.linear_coefs(p), {"theta_dot": p["rho"], "|theta_dot|*z": -p["rho"]})

    def from_terms(self, tm):
        b1 = tm.hysteresis.get("theta_dot", 0.0)
        b2 = -tm.hysteresis.get("|theta_dot|*z", 0.0)
        s = b1 / b2 if b2 != 0.0 else 1.0
        g = tm.torque.get
        return {
            "k_x": g("theta_dot", 0.0),
            "k_wa": g("z", 0.0) * s,
            "k_wb": g("i*z", 0.0) * s,
            "f_d": g("sign(theta_dot)", 0.0),
            "rho": b2,
        }

    def saturation_torque(self, p, which):
        return p.get("k_wa") if which == "a" else p.get("k_wb")

    def equations(self):
        return (
            "T = k_x*theta_dot + (k_wa + k_wb*i)*z + f_d*sign(theta_dot)\n"
            "dz/dt = rho*(theta_dot - |theta_dot|*z)"
        )


FRICTION_DAHL = FrictionDahl()

#: A toy effect: dry friction that grows with the current.
CURRENT_FRICTION = Effect(
    "current_friction",
    (Param("f_ci", "N*m/A", 0.0, 1e9, 0.3, "current-dependent dry friction"),),
    ("i*sign(theta_dot)",),
    "dry friction growing with the current, f_ci * i * sign(theta_dot)",
    lambda p, ks: {"i*sign(theta_dot)": p["f_ci"]},
    lambda c, ks: {"f_ci": c.get("i*sign(theta_dot)", 0.0)},
)

CURRENTS = (0.0, 0.5, 1.0)


@pytest.fixture
def plugins():
    with registry.registered(FRICTION_DAHL, CURRENT_FRICTION):
        yield


def test_a_family_from_this_file_runs_through_discover_predict_report_and_export(plugins, tmp_path):
    truth = Model("friction-dahl", {"f_d": 0.4, "k_s": 150.0})
    data = generate(truth, currents=CURRENTS, duration=2.0, noise=1e-3, seed=7)
    d = Discovery(families=["bingham", "friction-dahl"], close_loop=False).fit(data)
    assert d.family_ == "friction-dahl"
    fit = d.family_fits_["friction-dahl"]
    assert fit.rms < 1.05e-3 and fit.heldout_rms < 1.1e-3
    assert fit.params["f_d"] == pytest.approx(0.4, rel=0.05)
    # prediction on new runs of the same damper
    new = generate(truth, currents=(0.25, 0.75), duration=2.0, noise=1e-3, seed=8)
    pred = d.predict(new)
    for run, p in zip(new.runs, pred, strict=True):
        assert np.sqrt(np.mean((np.asarray(p) - run.theta) ** 2)) < 2e-3
    # results.json, the report and the python-control export know it
    data_json = json.loads(d.results_.to_json())
    assert data_json["family"] == "friction-dahl"
    from hystdisc.report import write_report

    html = tmp_path / "report.html"
    write_report(d, data, html)
    assert "Dahl with dry friction (a plugin)" in html.read_text(encoding="utf-8")
    pytest.importorskip("control")
    system = d.results_.to_control()
    assert "torque" in system.output_labels


def test_an_effect_from_this_file_is_found_by_the_closing_loop(plugins):
    truth = Model("dahl", {"k_s": 150.0}, effects={"current_friction": {"f_ci": 0.5}})
    data = generate(truth, currents=CURRENTS, duration=2.0, noise=1e-3, seed=9)
    d = Discovery(model="dahl").fit(data)
    assert "current_friction" in d.effects_
    final = d.final_fit_
    assert final.params["f_ci"] == pytest.approx(0.5, rel=0.05)
    assert final.rms < 1.05e-3


def test_unregistered_plugins_are_gone():
    with registry.registered(FRICTION_DAHL, CURRENT_FRICTION):
        assert "friction-dahl" in registry.family_names()
        assert "current_friction" in registry.effect_names()
    assert "friction-dahl" not in registry.family_names()
    assert "current_friction" not in registry.effect_names()
    with pytest.raises(hystdisc.HystdiscError, match="registered already"):
        registry.register_family(registry.get_family("dahl"))


#: String literals that equal a registered name but mean something else: (module, literal).
NOT_A_NAME = {
    # the offset of an encoder's lattice (results.json's encoder table), not the effect
    ("hystdisc/data/quantization.py", "offset"),
}


def _docstrings(tree: ast.AST) -> set[int]:
    out = set()
    for node in ast.walk(tree):
        body = getattr(node, "body", None)
        if isinstance(body, list) and body and isinstance(body[0], ast.Expr):
            value = body[0].value
            if isinstance(value, ast.Constant) and isinstance(value.value, str):
                out.add(id(value))
    return out


def test_no_family_or_effect_is_named_outside_the_models_and_the_registry():
    """The physics owns its hooks: other layers read declarations, they never branch on a
    family's or an effect's name."""
    names = set(registry.family_names()) | set(registry.effect_names())
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE.parent).as_posix()
        if rel.startswith("hystdisc/models/") or rel == "hystdisc/registry.py":
            continue
        tree = ast.parse(path.read_text(encoding="utf-8"))
        docs = _docstrings(tree)
        for node in ast.walk(tree):
            if (
                isinstance(node, ast.Constant)
                and isinstance(node.value, str)
                and node.value in names
                and id(node) not in docs
                and (rel, node.value) not in NOT_A_NAME
            ):
                found.append(f"{rel}:{node.lineno}: {node.value!r}")
    assert not found, "\n".join(found)
