"""A moving average read in the records themselves (issue 35: the UTFSM records as one CSV
went through the authors' filter, which nothing declared).

The windows are read, not assumed: every synthetic set below is drawn by
``generate`` with its own seed (the prefilter as ``hystdisc simulate --prefilter`` applies
it), and the real one is the shared UTFSM folder read without its rig file's filter.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from hystdisc import Discovery
from hystdisc.cli import main
from hystdisc.data import Dataset, detect_filter, filter_windows, load, with_detected_filter
from hystdisc.errors import HystdiscWarning
from hystdisc.models import Model
from hystdisc.simulation.synth import generate, write_dataset

#: three test frequencies at 1 kHz, 4 s each, noise on both channels (as in the README's
#: driven example)
DRIVES = ["0.1@0.5", "0.05@2", "0.02@5"]
KW = dict(currents=(0, 0.5, 1), duration=4.0, fs=1000, noise=0.01, theta_noise=1e-4)


def _driven(family: str, seed: int, prefilter=None, **kw) -> Dataset:
    opts = {**KW, **kw}
    return generate(Model(family), "driven", drives=DRIVES, prefilter=prefilter, seed=seed, **opts)


@pytest.mark.parametrize("family", ["bingham", "bouc-wen-std", "spencer"])
def test_unfiltered_records_show_no_filter(family):
    # Bingham's sign gives its force strong odd harmonics and no even ones: without the
    # motion's own notches, its force alone read windows of 9 to 87 samples
    assert detect_filter(_driven(family, 21).runs) is None
    # without noise a 5 Hz test at 1 kHz repeats every 200 samples, its rounding too: all
    # either channel has are harmonics, and both read 20 samples before the check
    assert detect_filter(_driven(family, 21, noise=0.0, theta_noise=0.0).runs) is None


@pytest.mark.parametrize("family", ["bingham", "dahl"])
def test_a_fixed_window_is_read_in_every_run(family):
    data = _driven(family, 22, {"window": 12})
    found = detect_filter(data.runs)
    assert found is not None
    assert set(found.windows.values()) == {12} and len(found.windows) == 9
    assert found.channels == ["torque", "theta"]
    assert min(found.contrast.values()) > 1.0  # decades below the sidelobes


def test_a_period_fraction_is_read_and_inferred_where_too_short_to_read():
    data = _driven("bouc-wen-std", 23, {"period_fraction": 0.1})
    want = filter_windows({"period_fraction": 0.1}, data.runs)  # 200, 50 and 20 samples
    found = detect_filter(data.runs)
    assert found is not None
    assert [found.windows[r.name] for r in data.runs] == want
    # two cycles of 0.5 Hz are too short for a spectrum that resolves 200 samples' notches:
    # those runs take the tenth of a period the others share
    assert found.inferred == ["0", "1", "2"] and found.missing == []


def test_the_utfsm_records_show_the_authors_windows(data_dir):
    folder = data_dir / "utfsm_mr_damper"
    if not folder.is_dir():
        pytest.skip(f"{folder} is missing")
    raw = load(folder, rig={"experiment": "driven", **_utfsm_columns()})
    assert raw.filter is None
    data, found = with_detected_filter(raw)
    assert found is not None and data.filter == found.table()
    # the authors' sincronize.m: round(1 / (10 Ts f)) samples with the test's nominal f
    nominal = {"10mm1Hz": 100, "25mm0x1Hz": 200, "25mm0x25Hz": 80, "25mm0x5Hz": 40,
               "2mm5Hz": 4, "5mm3Hz": 33}  # fmt: skip
    for r in raw.runs:
        want = next(w for key, w in nominal.items() if r.name.startswith(key))
        assert found.windows[r.name] == want, r.name
    # 4 samples have one notch below Nyquist: read from the period fraction of the others
    assert sorted(found.inferred) == sorted(r.name for r in raw.runs if r.name.startswith("2mm"))
    assert found.channels == ["torque", "theta"]


def _utfsm_columns() -> dict:
    """The rig file's reading of the UTFSM tables without its ``[filter]``."""
    return {
        "columns": {"t": 0, "theta": 1, "theta_dot": 2, "torque": 3},
        "units": {"theta": "mm", "theta_dot": "mm/s", "torque": "N"},
        "current": {"from_name": r"(\d+(?:x\d+)?)A$", "decimal": "x"},
    }


def test_discovery_fits_through_the_filter_it_reads(tmp_path, capsys):
    """A Dahl damper behind a 12-sample moving average: read and fitted through, the
    parameters come back; taken as unfiltered, the filter's lag is read as damper physics."""
    model = Model("dahl", {"k_s": 0.0})
    data = generate(
        model, "driven", drives=["0.1@2", "0.05@5"], prefilter={"window": 40}, seed=24,
        currents=(0, 0.5, 1), duration=3.0, fs=1000, noise=0.01, theta_noise=1e-4,
    )  # fmt: skip
    kw = dict(families=["dahl"], close_loop=False, heldout=False, n_starts=1)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        d = Discovery(**kw).fit(data)
    said = [str(w.message) for w in caught if issubclass(w.category, HystdiscWarning)]
    assert any("causal moving average of 40 samples (6 runs" in m for m in said), said
    assert d.prefilter_ is not None and set(d.prefilter_.windows.values()) == {40}
    assert d.results_.prefilter.windows == d.prefilter_.windows
    assert "Filter read in the records" in d.results_.report()
    fit = d.family_fits_["dahl"]
    err = {k: abs(fit.params[k] / v - 1) for k, v in model.params.items() if k in fit.params and v}
    floor = 0.01 / np.sqrt(40)  # the force noise through the filter
    assert max(err.values()) < 0.01, err  # measured: 0.13 % at most
    assert fit.rms < 1.1 * floor  # measured: 1.06 times
    blind = Discovery(**kw, detect_filter=False).fit(data)
    assert blind.prefilter_ is None and blind.results_.prefilter is None
    assert blind.family_fits_["dahl"].rms > 5 * fit.rms  # measured: 12 times
    # a prediction of new filtered records goes through their filter too
    new = generate(
        model, "driven", drives=["0.08@3"], prefilter={"window": 40}, seed=25,
        currents=(0.5,), duration=3.0, fs=1000, noise=0.01, theta_noise=1e-4,
    )  # fmt: skip
    pred = d.predict(new)[0]
    e = (pred.predicted - pred.measured)[200:]
    assert np.sqrt(np.mean(e**2)) < 1.2 * floor  # measured: 1.09 times
    # hystdisc predict does the same, and says so
    res, csv = tmp_path / "r.json", tmp_path / "new.csv"
    res.write_text(d.results_.to_json())
    write_dataset(new, csv)
    capsys.readouterr()
    assert main(["predict", str(res), str(csv), "-o", str(tmp_path / "p.csv"), "--quiet"]) == 0
    err = capsys.readouterr().err
    assert "moving average of 40 samples (1 run, on torque and theta;" in err, err
    assert err.rstrip().endswith("the prediction goes through it"), err
    got = np.loadtxt(tmp_path / "p.csv", delimiter=",", skiprows=1, usecols=(3, 4))
    # the same prediction, to the rounding of the records in the CSV (3e-8 here)
    np.testing.assert_allclose(got[:, 1], pred.predicted, rtol=0, atol=1e-6)
