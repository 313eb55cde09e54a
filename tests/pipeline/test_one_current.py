"""One current just works (issue 16 item 6): runs that all share one current (a rig without a
coil, the hysteretic benchmark) are discovered without any flag; the families are compared
at that current with one warning, and the current dependence is reported as not
identifiable in the console, the results and ``results.json``."""

from __future__ import annotations

import json

import numpy as np
import pytest

from hystdisc.cli import main
from hystdisc.registry import family_names, get_family

#: the one warning (``{}``: the file)
WARNING = (
    "hystdisc: warning: {}: all runs share one current (0.5 A); the families are compared "
    "at it, and the current dependence is not identifiable: the current-dependent "
    "parameters are fixed at 0 and the i* terms left out of the library"
)


@pytest.fixture(scope="module")
def one_current(tmp_path_factory):
    """A Dahl release at 0.5 A only (truth: k_wa 0.5, k_wb 1.5, so k_wa + k_wb i = 1.25)."""
    path = tmp_path_factory.mktemp("one") / "one.csv"
    argv = ["simulate", "--model", "dahl", "--currents", "0.5", "--duration", "3"]
    assert main([*argv, "--noise", "1e-3", "--seed", "3", "-o", str(path), "--quiet"]) == 0
    return path


def _discover(path, out, capsys, *flags):
    code = main(["discover", str(path), "--out", str(out), *flags])
    captured = capsys.readouterr()
    assert code == 0, captured.err
    warnings = [ln for ln in captured.err.splitlines() if ln.startswith("hystdisc: warning:")]
    return json.loads((out / "results.json").read_text()), captured.out, warnings


def test_one_current_without_flags(one_current, tmp_path, capsys):
    data, out, warnings = _discover(one_current, tmp_path, capsys)
    assert warnings == [WARNING.format(one_current)]
    # every family of a release was compared (the state-space ones are for driven data)
    assert list(data["families"]) == [n for n in family_names() if not get_family(n).is_system]
    assert data["family"] == "dahl"
    for name, entry in data["families"].items():
        for key in get_family(name).current_params:
            p = entry["parameters"][key]
            assert p["value"] == 0.0 and p["identifiable"] is False, (name, key)
    # the fitted k_wa is the hysteretic gain at 0.5 A: 0.5 + 1.5 * 0.5
    assert data["families"]["dahl"]["parameters"]["k_wa"]["value"] == pytest.approx(1.25, rel=0.02)
    cd = data["current_dependence"]
    assert cd["identifiable"] is False and cd["currents"] == [0.5] and cd["fixed"] == ["k_wb"]
    assert cd["note"] == (
        "all runs share one current (0.5 A); k_wb of dahl fixed at 0, the other parameters "
        "are its values at 0.5 A (every family's current-dependent parameters likewise)"
    )
    assert data["final"]["parameters"]["k_wb"]["identifiable"] is False
    assert f"Current dependence: not identifiable: {cd['note']}" in out.splitlines()
    assert "k_wb                  0   [0, 0]                          not identifiable" in out
    skipped = {s["name"]: s["reason"] for s in data["effects_skipped"]}
    assert skipped["current_viscous"] == "needs two current levels or more, the data have one"


def test_single_current_flag_silences_the_warning(one_current, tmp_path, capsys):
    report = tmp_path / "report.html"
    flags = ("--single-current", "--report", str(report))
    data, out, warnings = _discover(one_current, tmp_path, capsys, *flags)
    assert warnings == []
    assert data["current_dependence"]["identifiable"] is False
    assert "Current dependence: not identifiable" in out
    note = data["current_dependence"]["note"]
    summary = report.with_suffix(".md").read_text()
    assert f"| current dependence | not identifiable: {note} |" in summary


def test_several_currents_have_no_current_dependence_key(tmp_path):
    from hystdisc import Discovery
    from hystdisc.models import Model
    from hystdisc.simulation.synth import generate

    data = generate(Model("dahl"), currents=(0, 1), duration=2, noise=1e-3, seed=1)
    d = Discovery(families=["dahl"], heldout=False, close_loop=False, single_current=True)
    res = d.fit(data).results_
    assert not d.single_current_ and "current_dependence" not in res.summary()
    assert res.families["dahl"].parameters["k_wb"].identifiable


def test_benchmark_record_without_flags(data_dir, tmp_path, capsys):
    """The Noel-Schoukens estimation record (no coil: no current column) as the CSV a user
    would write (t, theta, input): ``hystdisc discover FILE --experiment forced`` with no
    other flag selects standard Bouc-Wen (the benchmark's system) and does not call the
    residual unexplained (its noise is band-limited, judged against period-to-period
    differences); it warns once for the missing current and once for the one current."""
    import scipy.io

    folder = data_dir / "boucwen_benchmark"
    if not folder.is_dir():
        pytest.skip(f"{folder} is missing")
    u = scipy.io.loadmat(folder / "uest_multisine.mat")["u"].ravel()
    y = scipy.io.loadmat(folder / "yest_multisine.mat")["y"].ravel()
    path = tmp_path / "benchmark.csv"
    table = np.column_stack([np.arange(u.size) / 750.0, y, u])
    np.savetxt(path, table, delimiter=",", header="t,theta,input", comments="")
    data, out, warnings = _discover(path, tmp_path, capsys, "--experiment", "forced")
    assert warnings == [
        f"hystdisc: warning: {path}: no 'current' column: every run is taken at 0 A (a rig "
        "without a coil); fix: add a 'current' column, or map yours with --column current=NAME",
        WARNING.format(path).replace("(0.5 A)", "(0 A)"),
    ]
    assert data["family"] == "bouc-wen-std" and data["unexplained"] is False
    assert len(data["families"]) >= 2 and data["experiment"] == "forced"
    cd = data["current_dependence"]
    assert cd["identifiable"] is False and cd["currents"] == [0.0]
    assert cd["fixed"] == list(get_family(data["family"]).current_params)
    assert "Current dependence: not identifiable" in out
