"""The MATLAB ``.mat`` reader (v4 to v7; not v7.3), with a forked probe that turns a crash
of scipy's compiled reader on a damaged file into a one-line error.
"""

from __future__ import annotations

import os
import signal
import struct
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from hystdisc.data.columns import build_dataset, check_column_map, infer_experiment, valid_rate
from hystdisc.data.dataset import (
    CANONICAL_COLUMNS,
    COLUMN_FLAG,
    Dataset,
    check_experiment,
    extra_column,
    extra_columns,
    needed_columns,
)
from hystdisc.data.text import check_finite, read_bytes
from hystdisc.data.units import apply_units
from hystdisc.data.validation import validate
from hystdisc.errors import input_error

__all__ = ["mat_lookup", "read_mat"]

#: a signal found in the files: the array (None if absent) and its label for messages
_Found = tuple[np.ndarray | None, str]


# --------------------------------------------------------------------------------------
# loading a file safely
# --------------------------------------------------------------------------------------


def _mat_needs_probe(path: str) -> bool:
    """False for files the compiled reader is safe on: v4, v7.3 and all-compressed v5.

    The crashes seen come from uncompressed v5 variables (a damaged class, flag or
    data-type field); compressed variables are checked by zlib first. Walking the
    top-level tags costs microseconds, a fork tens of milliseconds.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(128)
            # scipy: v4 when a zero is among the first 4 bytes; v5 when the major version
            # byte (chosen by the endian indicator 'IM' / 'MI') is 1
            if len(head) < 128 or 0 in head[:4] or head[124 + (head[126] == 0x49)] != 1:
                return False  # v4, too short or not v5: scipy's own checks stop it cleanly
            endian = "<" if head[126:128] == b"IM" else ">"
            size = os.fstat(fh.fileno()).st_size
            pos = 128
            while pos < size:
                fh.seek(pos)
                tag = fh.read(8)
                if len(tag) < 8:
                    return True
                mdtype, nbytes = struct.unpack(endian + "II", tag)
                if mdtype != 15:  # not miCOMPRESSED
                    return True
                pos += 8 + nbytes
    except OSError:
        return False
    return False


def _probe_loadmat(path: str) -> str | None:
    """Try ``scipy.io.loadmat`` in a forked child first; the signal's name if it crashed.

    scipy's compiled MAT reader can kill the interpreter (segmentation fault) on some
    damaged files, e.g. one flipped class or flag byte of a variable (found by fuzzing,
    ``tests/end_to_end/fuzz_corpus/mat_*``). A crash of the child becomes a one-line error
    instead. Python errors are left to the real load. Without ``os.fork`` (Windows) nothing
    is probed.
    """
    if not hasattr(os, "fork") or not _mat_needs_probe(path):
        return None
    import scipy.io

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", DeprecationWarning)  # fork() of a threaded process
        pid = os.fork()
    if pid == 0:  # pragma: no cover - the child (coverage does not follow it)
        code = 0
        try:
            import faulthandler

            faulthandler.disable()  # the crash is expected here: no dump on stderr
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, 1)
            os.dup2(devnull, 2)
            warnings.simplefilter("ignore")
            scipy.io.loadmat(path, squeeze_me=False, mat_dtype=False)
        except BaseException:
            code = 1
        finally:
            os._exit(code)
    _, status = os.waitpid(pid, 0)
    if os.WIFSIGNALED(status):
        sig = os.WTERMSIG(status)
        try:
            return signal.Signals(sig).name
        except ValueError:  # pragma: no cover
            return f"signal {sig}"
    return None


def _load_mat(path: str | os.PathLike[str]) -> dict[str, Any]:
    import scipy.io

    source = str(path)
    data = read_bytes(path)
    if not data:
        raise input_error(source, "file is empty", "point to a file that holds the measured data")
    if data[:128].find(b"MATLAB 7.3") >= 0 or data[:8] == b"\x89HDF\r\n\x1a\n":
        raise input_error(
            source,
            "is a MATLAB v7.3 (HDF5) file, which cannot be read",
            "re-save it in MATLAB with save(name, '-v7')",
        )
    crash = _probe_loadmat(str(path))
    if crash:
        raise input_error(
            source,
            f"is a damaged MATLAB .mat file (the MAT reader crashed on it: {crash})",
            "re-save it in MATLAB with save(name, '-v7'), or export the data as CSV",
        )
    try:
        raw = scipy.io.loadmat(str(path), squeeze_me=False, mat_dtype=False)
    except Exception as exc:  # scipy raises many types for damaged files
        raise input_error(
            source,
            f"is not a readable MATLAB .mat file ({type(exc).__name__}: {exc})",
            "check the file, or re-save it in MATLAB with save(name, '-v7')",
        ) from None
    return {k: v for k, v in raw.items() if not k.startswith("__")}


def mat_lookup(variables: Mapping[str, Any], name: str) -> str | None:
    """The variable called ``name`` (exactly, else the one case-insensitive match)."""
    if name in variables:
        return name
    hits = [k for k in variables if k.lower() == name.lower()]
    return hits[0] if len(hits) == 1 else None


def _mat_numeric(value: Any, name: str, source: str) -> np.ndarray:
    arr = np.asarray(value)
    if arr.dtype.kind not in "biuf":
        kind = "complex" if arr.dtype.kind == "c" else "not a numeric array"
        raise input_error(
            source,
            f"variable {name!r} is {kind} ({arr.dtype})",
            "store the signal as a real numeric vector",
        )
    return arr.astype(np.float64)


# --------------------------------------------------------------------------------------
# the reader
# --------------------------------------------------------------------------------------


def read_mat(
    path: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    experiment: str | None = None,
    columns: Mapping[str, str | int] | None = None,
    units: Mapping[str, str] | None = None,
    current: float | None = None,
    fs: float | None = None,
) -> Dataset:
    """Read a MATLAB ``.mat`` file (v4 to v7; not v7.3).

    Parameters
    ----------
    path : path-like or list of path-likes
        The file. Several files are merged into one set of variables (e.g. input and
        output saved separately, as in the Bouc-Wen benchmark).
    experiment : {"release", "driven", "forced"}, optional
        Inferred when omitted: a ``torque`` variable means driven, ``input`` forced.
    columns : dict, optional
        Canonical name -> variable name (defaults to the canonical names, matched
        case-insensitively), or -> 0-based column index into the single 2-D matrix the file
        holds (``{"matrix": ...}`` is not needed; a ``1 x N`` / ``N x 1`` vector is fine).
    units : dict, optional
        Units of the variables, converted to SI.
    current : float, optional
        Coil current when the file has no ``current`` variable.
    fs : float, optional
        Sampling rate in Hz when the file has no ``t`` variable: ``t = arange(n) / fs``.

    Returns
    -------
    Dataset
        One run named ``"0"``, or several when a per-sample ``run`` variable is present;
        checked with ``validate(dataset, need_currents=1)``.

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np, scipy.io
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = str(pathlib.Path(d, "rig.mat"))
    ...     scipy.io.savemat(p, {"y": np.sin(np.arange(50) / 5.0)[None, :], "u": np.ones(50)})
    ...     ds = read_mat(p, "forced", columns={"theta": "y", "input": "u"}, current=0.0, fs=100.0)
    >>> ds[0].n, ds[0].fs, ds.experiment
    (50, 100.0, 'forced')
    """
    paths = [path] if isinstance(path, (str, os.PathLike)) else list(path)
    source = ", ".join(str(p) for p in paths)
    variables = _merge_variables(paths, source)
    colmap = check_column_map(columns, source)
    matrix = _indexed_matrix(variables, colmap, source)
    found = {c: _fetch(c, colmap, variables, matrix, source) for c in CANONICAL_COLUMNS}
    present = [c for c, (a, _) in found.items() if a is not None]
    exp = (
        check_experiment(experiment, source)
        if experiment is not None
        else infer_experiment(present, source)
    )
    _check_needed(found, variables, exp, source)
    n = found["theta"][0].size  # type: ignore[union-attr]
    cols, run_ids, current = _columns(found, exp, n, current, source)
    if "t" not in cols:
        cols["t"] = _time_from_rate(fs, n, variables, source)
    apply_units(cols, units, source)
    ds = build_dataset(cols, run_ids, None, source, exp, current=current)
    validate(ds, need_currents=1)
    return ds


def _merge_variables(paths: Sequence[str | os.PathLike[str]], source: str) -> dict[str, Any]:
    """The variables of all files; a name in two files is an error."""
    variables: dict[str, Any] = {}
    origin: dict[str, str] = {}
    for p in paths:
        for key, value in _load_mat(p).items():
            if key in variables:
                raise input_error(
                    source,
                    f"variable {key!r} is in both {origin[key]} and {p}",
                    "merge files that hold different variables only",
                )
            variables[key] = value
            origin[key] = str(p)
    if not variables:
        raise input_error(
            source, "holds no variables", "point to a file that holds the measured data"
        )
    return variables


def _indexed_matrix(
    variables: Mapping[str, Any], colmap: Mapping[str, Any], source: str
) -> tuple[str, np.ndarray] | None:
    """The one 2-D matrix a column map with indices refers to (channels as columns)."""
    if not any(isinstance(v, int) for v in colmap.values()):
        return None
    mats = []
    for k, v in variables.items():
        a = np.asarray(v)
        if a.ndim == 2 and min(a.shape) > 1 and a.dtype.kind in "biuf":
            mats.append(k)
    if len(mats) != 1:
        found = ", ".join(mats) if mats else "none"
        raise input_error(
            source,
            f"a column map with indices needs exactly one 2-D matrix in the file (found: {found})",
            "map the columns to variable names instead",
        )
    name = mats[0]
    matrix = _mat_numeric(variables[name], name, source)
    top = max(v for v in colmap.values() if isinstance(v, int))
    if matrix.shape[1] <= top or (matrix.shape[0] < matrix.shape[1] and matrix.shape[0] > top):
        matrix = matrix.T  # channels stored as rows
    if matrix.shape[1] <= top:
        raise input_error(
            source,
            f"column index {top} is out of range for matrix {name!r} of shape {matrix.shape}",
            f"use indices from 0 to {matrix.shape[1] - 1}",
        )
    return name, matrix


def _fetch(
    canon: str,
    colmap: Mapping[str, Any],
    variables: Mapping[str, Any],
    matrix: tuple[str, np.ndarray] | None,
    source: str,
) -> _Found:
    """The signal for column ``canon`` as a vector, and its label (None if absent)."""
    wanted = colmap.get(canon, canon)
    if isinstance(wanted, int):
        assert matrix is not None
        name, values = matrix
        return values[:, wanted], f"{name}[:, {wanted}]"
    key = mat_lookup(variables, wanted)
    if key is None:
        if canon in colmap:
            raise input_error(
                source,
                f"variable {wanted!r} (mapped to {canon}) is not in the file "
                f"(found: {_names(variables)})",
                f"correct the mapping {COLUMN_FLAG} {canon}=NAME",
            )
        return None, wanted
    arr = _mat_numeric(variables[key], key, source)
    if arr.size > 1 and arr.ndim > 1 and arr.size != max(arr.shape):
        raise input_error(
            source,
            f"variable {key!r} has shape {arr.shape}, expected a vector",
            "store each signal as a 1 x N or N x 1 vector, or map matrix columns by index",
        )
    return arr.reshape(-1), key


def _names(variables: Mapping[str, Any]) -> str:
    return ", ".join(sorted(variables)[:12])


def _check_needed(
    found: Mapping[str, _Found], variables: Mapping[str, Any], exp: str, source: str
) -> None:
    """The signals the experiment needs are there (time and current may be given)."""
    for canon in needed_columns(exp):
        if canon in ("t", "current") or found[canon][0] is not None:
            continue
        why = f" (a {exp} experiment needs it)" if canon == extra_column(exp) else ""
        raise input_error(
            source,
            f"variable {canon!r} is missing{why} (found: {_names(variables)})",
            f"add it or map yours with {COLUMN_FLAG} {canon}=NAME",
        )


def _columns(
    found: Mapping[str, _Found], exp: str, n: int, current: float | None, source: str
) -> tuple[dict[str, np.ndarray], list[str] | None, float | None]:
    """The per-sample columns, the run ids and the current (a scalar ``current`` variable)."""
    cols: dict[str, np.ndarray] = {}
    run_ids = None
    others = set(extra_columns()) - {extra_column(exp)}  # another experiment's signal
    for canon in CANONICAL_COLUMNS:
        arr, label = found[canon]
        if arr is None or canon in others:
            continue
        if canon == "current" and arr.size == 1:
            current = float(arr[0])
            continue
        if arr.size != n:
            raise input_error(
                source,
                f"variable {label!r} has {arr.size} samples but theta has {n}",
                "store signals of equal length",
            )
        if canon == "run":
            run_ids = [f"{v:g}" for v in arr]
            continue
        check_finite(arr, source, f"variable {label!r}", lambda k: f"at sample {k}")
        cols[canon] = arr
    return cols, run_ids, current


def _time_from_rate(fs: Any, n: int, variables: Mapping[str, Any], source: str) -> np.ndarray:
    """``t = arange(n) / fs`` for files without a time variable."""
    if fs is None:
        raise input_error(
            source,
            f"no time variable (found: {_names(variables)})",
            f"add a 't' variable, map it with {COLUMN_FLAG} t=NAME, or give the sampling rate fs",
        )
    if not valid_rate(fs):
        raise input_error(source, f"sampling rate fs={fs!r} is invalid", "give fs > 0 in Hz")
    return np.arange(n, dtype=np.float64) / float(fs)
