"""Fuzzing of every reader with hypothesis (issue 8).

Every input, however malformed, must end in one of two ways:

* it loads, and the result satisfies its invariants (a :class:`Dataset` of float64 1-D,
  finite, equally long signals with strictly increasing time; a rig or scenario dict of
  checked types; a finite :class:`TermModel`), or
* it raises :class:`HystdiscError` whose message is one line and says ``fix:``.

Any other exception, a NaN that slips through, or a stray ``RuntimeWarning`` (overflow
noise printed at the user) fails the test. The runs are reproducible and bounded
(``derandomize=True``, no example database, a fixed ``max_examples`` per reader); the
number of inputs tried per reader is printed at the end of each module (``-s`` or the
terminal summary) and appended to ``$HYSTDISC_FUZZ_COUNTS`` when that is set.

The fuzz tests live beside the tests of what they fuzz (``tests/data/test_fuzz_*.py``,
``tests/simulation/test_fuzz_scenarios.py``, ``tests/results/test_fuzz_results.py``,
``tests/cli/test_fuzz_predict.py``); this package holds what they share: the checks, the
counts, the value pools and the document mutations. The nasty inputs found are kept in
``tests/end_to_end/fuzz_corpus/`` and replayed by ``tests/end_to_end/test_fuzz_corpus.py``
with the outcome expected of each (see its ``CORPUS``).
"""

from __future__ import annotations

import contextlib
import math
import os
import re
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from hystdisc.data import EXPERIMENTS, MIN_SAMPLES, Dataset, validate
from hystdisc.errors import HystdiscError, HystdiscWarning
from hystdisc.registry import get_experiment

#: inputs tried, per reader, and outcomes: COUNTS[reader], COUNTS[reader, "ok" | "error"].
#: Readers named "a>b" are a later stage fed with what reader "a" accepted (not new inputs).
COUNTS: Counter = Counter()
#: error messages seen, per reader (numbers blanked); listed with HYSTDISC_FUZZ_VERBOSE=1
KINDS: Counter = Counter()


def fuzz_settings(n: int) -> settings:
    return settings(
        max_examples=n,
        deadline=None,
        derandomize=True,
        database=None,
        suppress_health_check=list(HealthCheck),
    )


# ----------------------------------------------------------------------------- checks


def check_error(exc: BaseException) -> str:
    """A user error: one non-empty line that names the fix."""
    msg = str(exc)
    assert msg.strip(), "empty error message"
    assert msg == " ".join(msg.split()), f"message is not one clean line: {msg!r}"
    assert len(msg.splitlines()) == 1, f"message spans lines: {msg!r}"
    assert "fix:" in msg, f"message without a fix: {msg!r}"
    assert "Traceback" not in msg
    return msg


def check_dataset(ds: Dataset) -> None:
    """The invariants of a loaded Dataset."""
    assert isinstance(ds, Dataset)
    assert ds.experiment in EXPERIMENTS
    assert len(ds.runs) >= 1
    names = [r.name for r in ds.runs]
    assert len(set(names)) == len(names), names
    extra = get_experiment(ds.experiment).extra_column
    for r in ds.runs:
        assert isinstance(r.name, str)
        assert isinstance(r.current, float) and math.isfinite(r.current)
        for key in ("t", "theta", "torque", "input", "theta_dot"):
            a = getattr(r, key)
            if a is None:
                assert key not in ("t", "theta") and key != extra, key
                continue
            assert isinstance(a, np.ndarray), key
            assert a.dtype == np.float64, (key, a.dtype)
            assert a.ndim == 1, (key, a.shape)
            assert a.size == r.t.size, (key, a.size, r.t.size)
            assert np.all(np.isfinite(a)), key
        assert r.n >= MIN_SAMPLES
        dt_ = np.diff(r.t)
        assert np.all(dt_ > 0), "time not strictly increasing"
        assert np.all(np.isfinite(dt_)), "infinite time step"
        assert math.isfinite(r.fs) and r.fs > 0
        assert np.ptp(r.theta) > 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", HystdiscWarning)  # already checked by attempt()
        validate(ds)  # idempotent: a loaded dataset passes its own check again


def attempt(reader: str, fn, *args, **kwargs):
    """Call ``fn``; return its result, or None after a well-formed HystdiscError.

    Counts the input under ``reader``; any exception other than HystdiscError and any
    warning other than a HystdiscWarning propagate as test failures.
    """
    COUNTS[reader] += 1
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = fn(*args, **kwargs)
        except HystdiscError as exc:
            msg = check_error(exc)
            COUNTS[reader, "error"] += 1
            KINDS[reader, re.sub(r"[-+.\w]*\d[-+.\w]*", "#", msg.split(": ", 1)[-1])[:60]] += 1
            out = None
    stray = [w for w in caught if not issubclass(w.category, HystdiscWarning)]
    assert not stray, f"stray warnings: {[f'{w.category.__name__}: {w.message}' for w in stray]}"
    for w in caught:
        check_warning(w.message)
    if out is not None:
        COUNTS[reader, "ok"] += 1
    return out


def check_warning(message) -> None:
    msg = str(message)
    assert msg == " ".join(msg.split()), f"warning is not one clean line: {msg!r}"


def report_counts(request) -> None:
    """Print the inputs tried per reader after a module, and clear them for the next.

    Called by the fixture ``fuzz_counts`` (``tests/conftest.py``) when a module ends.
    """
    readers = sorted(k for k in COUNTS if isinstance(k, str))
    total = sum(COUNTS[k] for k in readers if ">" not in k)
    lines = [f"fuzz inputs tried: {total} ({request.module.__name__})"]
    for k in readers:
        lines.append(
            f"  {k:<22}{COUNTS[k]:>6}  (accepted {COUNTS[k, 'ok']}, "
            f"one-line error {COUNTS[k, 'error']})"
        )
    if os.environ.get("HYSTDISC_FUZZ_VERBOSE"):
        for (reader, kind), n in sorted(KINDS.items()):
            lines.append(f"    {reader}: {n} x {kind}")
    text = "\n".join(lines)
    tr = request.config.pluginmanager.get_plugin("terminalreporter")
    capman = request.config.pluginmanager.get_plugin("capturemanager")
    if tr is not None:
        ctx = capman.global_and_fixture_disabled() if capman else contextlib.nullcontext()
        with ctx:
            tr.write_line("")
            for line in lines:
                tr.write_line(line)
    out = os.environ.get("HYSTDISC_FUZZ_COUNTS")
    if out:
        with Path(out).open("a", encoding="utf-8") as fh:
            fh.write(text + "\n")
    COUNTS.clear()
    KINDS.clear()


# ----------------------------------------------------------------------------- value pools

BAD_CELLS = [
    "",
    " ",
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-Infinity",
    "abc",
    "1,5",
    "1e400",
    "-1e400",
    "1e-400",
    "0x10",
    "１２",
    "٣",
    "∞",
    "1_0",
    '"1"',
    "None",
    "null",
    "TRUE",
    "9" * 400,
    "1e308",
    "-1.7976931348623157e308",
    "5e-324",
    "\u00a0",
    "1.0.0",
    "--1",
    "+-1",
    "1e",
    "e5",
    ".",
    "#",
]

UNICODE_TEXT = st.text(
    alphabet=st.characters(codec="utf-8", exclude_characters="\x00"), min_size=0, max_size=12
)


def fmt(x: float) -> str:
    return f"{x:.10g}"
