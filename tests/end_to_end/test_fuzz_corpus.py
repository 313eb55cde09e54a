"""The nasty inputs fuzzing found, one file each in ``fuzz_corpus/``, replayed with the
outcome expected of each (``CORPUS``): every reader's (CSV, MAT, tables, rig files,
scenarios, ``results.json``)."""

from __future__ import annotations

import math
import warnings
from pathlib import Path

import pytest

from hystdisc.data import EXPERIMENTS, Dataset, load, read_rig
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.results import Results
from hystdisc.simulation.scenarios import generate_from_scenario, load_scenario

from ..fuzz import check_dataset, check_error

CORPUS_DIR = Path(__file__).parent / "fuzz_corpus"

#: corpus file -> words its one-line error must contain ("ok": it must load)
CORPUS: dict[str, tuple[str, ...] | str] = {
    "csv_ok_double_bom.csv": "ok",  # a BOM written twice: was "column 't' is missing (found: t,...)"
    "csv_ok_cr_only_semicolons.csv": "ok",
    "csv_ok_huge_theta.csv": "ok",  # std() overflowed with a RuntimeWarning
    "csv_err_time_overflow.csv": ("run 0", "time steps overflow", "line 3"),
    "csv_err_nul_byte.csv": ("not a text file",),
    "csv_err_latin1.csv": ("UTF-8", "line 2"),
    "csv_err_ragged.csv": ("line 10", "4 fields"),
    "csv_err_overflow_cell.csv": ("'theta'", "inf", "line 7"),
    "csv_err_decimal_comma.csv": ("'0,5'", "decimal separator"),
    # one byte changed in an uncompressed v5 file: scipy's reader segfaulted (killed pytest)
    "mat_err_segfault_sparse_class.mat": ("damaged MATLAB", "crashed"),
    "mat_err_segfault_complex_flag.mat": ("damaged MATLAB", "crashed"),
    "mat_err_segfault_data_type.mat": ("damaged MATLAB", "crashed"),
    "mat_err_truncated.mat": ("not a readable MATLAB",),
    "mat_overflow_flip.mat": "ok",  # huge value: overflow RuntimeWarning in validate()
    "table_ok_10mm1Hz0x5A.txt": "ok",
    "rig_err_fs_inf.toml": ("fs = inf",),  # was accepted, then "time does not increase"
    "rig_err_current_text.toml": ("'0.5 A'", "not a number"),
    "rig_err_not_utf8.toml": ("UTF-8",),
    "scenario_err_not_utf8.toml": ("UTF-8",),  # was UnicodeDecodeError
    "scenario_err_output_nul.toml": ("output",),  # was ValueError: embedded null byte
    "scenario_err_huge_duration.toml": ("samples",),  # was MemoryError / OverflowError
    "scenario_err_diverges.toml": ("diverged", "sigma_0=1e+09"),
    "results_err_truncated.json": ("not a readable results.json",),
    "results_err_no_model.json": ("not a hystdisc results.json",),
    "results_err_unknown_term.json": ("theta^7",),
    # problems of results.py once reported (a RecursionError, an OverflowError, a NaN model
    # accepted, a KeyError), now one-line errors
    "results_err_deep_nesting.json": ("not a readable results.json",),
    "results_err_huge_int.json": ("no usable model",),
    "results_err_nan_string.json": ("no usable model", "not finite"),
    "results_err_no_experiment.json": ("not a hystdisc results.json",),
    "results_err_deep_object.json": ("not a hystdisc results.json",),
}


def _corpus_files() -> list[str]:
    return sorted(p.name for p in CORPUS_DIR.iterdir() if p.is_file() and p.suffix != ".rig")


def _read_corpus(path: Path):
    kind = path.name.split("_", 1)[0]
    if kind in ("csv", "mat"):
        return load(path)
    if kind == "table":
        return load(path, rig=path.with_suffix(".rig"))
    if kind == "rig":
        return load(CORPUS_DIR / "table_ok_10mm1Hz0x5A.txt", rig=read_rig(path))
    if kind == "scenario":
        return generate_from_scenario(load_scenario(path))
    if kind == "results":
        res = Results.load(path)
        assert res.experiment in EXPERIMENTS
        tm = res.term_model()
        coefs = [*tm.torque.values(), *tm.hysteresis.values(), tm.n, tm.J]
        assert all(math.isfinite(c) for c in coefs), "non-finite model accepted"
        return res
    raise AssertionError(f"unknown corpus file kind {kind!r}")


def test_corpus_manifest_lists_every_file():
    assert sorted(CORPUS) == _corpus_files()
    size = sum(p.stat().st_size for p in CORPUS_DIR.iterdir())
    assert size < 16_000, f"the corpus should stay small ({size} bytes)"


@pytest.mark.parametrize("name", sorted(CORPUS))
def test_corpus(name):
    path = CORPUS_DIR / name
    expected = CORPUS[name]
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = _read_corpus(path)
        except HystdiscError as exc:
            msg = check_error(exc)
            assert expected != "ok", f"{name} must load, got: {msg}"
            for word in expected:
                assert word in msg, f"{word!r} not in {msg!r}"
            out = None
        else:
            assert expected == "ok", f"{name} must be a one-line error, and it loads"
    assert not [w for w in caught if not issubclass(w.category, HystdiscWarning)]
    if expected == "ok":
        assert out is not None
        if isinstance(out, Dataset):
            check_dataset(out)
