"""Writing files: atomic writes that never overwrite without ``force``, and the CSV writer.

Every output of the package goes through :func:`atomic_write_bytes`: the data goes to a
temporary file in the same folder and is renamed over the target, so a reader sees the old
file or the complete new one, never half a file (not even after Ctrl-C).
"""

from __future__ import annotations

import io
import os
import secrets
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc.data.dataset import Dataset, Run, as_vector, extra_column
from hystdisc.errors import input_error

__all__ = ["atomic_write_bytes", "atomic_write_text", "write_csv"]


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes, force: bool = False) -> Path:
    """Write ``data`` to ``path`` atomically, refusing to overwrite without ``force``.

    The data goes to a temporary file in the same folder, is flushed to disk and then
    renamed over ``path`` (``os.replace``), so readers see either the old file or the
    complete new one. Missing parent folders are created.

    Returns
    -------
    pathlib.Path
        The path written.
    """
    target = Path(path)
    source = str(path)
    if target.is_dir():
        raise input_error(source, "is a directory", "choose a file name with -o")
    if target.exists() and not force:
        raise input_error(
            source, "already exists", "pass --force to overwrite or choose another -o"
        )
    parent = target.parent
    try:
        parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise input_error(
            source, f"cannot create its folder ({exc.strerror or exc})", "choose another -o"
        ) from None
    tmp = parent / f".{target.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp"
    try:
        fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
        try:
            with os.fdopen(fd, "wb") as fh:
                fh.write(data)
                fh.flush()
                os.fsync(fh.fileno())
        except BaseException:
            tmp.unlink(missing_ok=True)
            raise
        os.replace(tmp, target)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise input_error(
            source,
            f"cannot be written ({exc.strerror or exc})",
            "choose a writable location with -o",
        ) from None
    except BaseException:  # Ctrl-C (KeyboardInterrupt) between the write and the rename
        tmp.unlink(missing_ok=True)
        raise
    return target


def atomic_write_text(path: str | os.PathLike[str], text: str, force: bool = False) -> Path:
    """Write ``text`` (UTF-8, ``\\n`` line ends) atomically; see :func:`atomic_write_bytes`.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = atomic_write_text(pathlib.Path(d, "out.json"), "{}\\n")
    ...     atomic_write_text(p, "{}\\n")
    Traceback (most recent call last):
    ...
    hystdisc.errors.HystdiscError: .../out.json: already exists; fix: pass --force to overwrite or choose another -o
    """
    return atomic_write_bytes(path, text.encode("utf-8"), force=force)


def _csv_name(name: str) -> str:
    if any(c in name for c in ',"\n\r') or name != name.strip():
        return '"' + name.replace('"', '""') + '"'
    return name


def write_csv(
    dataset: Dataset,
    path: str | os.PathLike[str],
    predictions: Mapping[str, Sequence[np.ndarray]] | Sequence[np.ndarray] | None = None,
    force: bool = False,
) -> Path:
    """Write a dataset as long-format CSV (SI units), atomically.

    Columns: ``run,t,theta,current`` plus ``torque`` (driven) or ``input`` (forced), plus
    ``theta_dot`` when every run has it, plus prediction columns. Numbers use ``%.10g``.

    Parameters
    ----------
    dataset : Dataset
        The runs to write.
    path : path-like
        Output file; an existing file is only replaced with ``force=True``.
    predictions : sequence of arrays or dict, optional
        Model output to write beside the data: one array per run (column
        ``<measured>_model``, e.g. ``theta_model``), or a dict ``column name -> one array
        per run``.
    force : bool
        Overwrite an existing file.

    Returns
    -------
    pathlib.Path
        The path written.

    Examples
    --------
    >>> import tempfile, pathlib, numpy as np
    >>> t = np.arange(30) * 0.01
    >>> ds = Dataset([Run("a", t, np.sin(t), 0.5, torque=np.cos(t))], "driven", "mem")
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = write_csv(ds, pathlib.Path(d, "out.csv"))
    ...     print(p.read_text().splitlines()[:2])
    ['run,t,theta,current,torque', 'a,0,0,0.5,1']
    """
    if not isinstance(dataset, Dataset):
        raise input_error(
            str(path), f"expected a Dataset, got {type(dataset).__name__}", "pass a Dataset"
        )
    if Path(path).exists() and not force:  # fail before formatting a large file
        raise input_error(
            str(path), "already exists", "pass --force to overwrite or choose another -o"
        )
    extra = extra_column(dataset.experiment)
    keys = ["t", "theta"]
    names = ["run", "t", "theta", "current"]
    if extra:
        keys.append(extra)
        names.append(extra)
    if dataset.runs and all(r.theta_dot is not None for r in dataset.runs):
        keys.append("theta_dot")
        names.append("theta_dot")
    pred_cols = _prediction_columns(dataset, predictions, names, str(path))
    names += list(pred_cols)
    buf = io.StringIO()
    buf.write(",".join(names) + "\n")
    for i, run in enumerate(dataset.runs):
        arrs = [run.t, run.theta, np.full(run.n, run.current)]
        arrs += [getattr(run, k) for k in keys[2:]]
        arrs += [pred_cols[c][i] for c in pred_cols]
        body = io.StringIO()
        np.savetxt(body, np.column_stack(arrs), fmt="%.10g", delimiter=",")
        head = f"{_csv_name(run.name)},"
        buf.write("".join(head + line + "\n" for line in body.getvalue().splitlines()))
    return atomic_write_text(path, buf.getvalue(), force=force)


def _prediction_columns(
    dataset: Dataset,
    predictions: Mapping[str, Sequence[np.ndarray]] | Sequence[np.ndarray] | None,
    names: list[str],
    source: str,
) -> dict[str, list[np.ndarray]]:
    """Column name -> one checked prediction vector per run."""
    pred_cols: dict[str, list[np.ndarray]] = {}
    if predictions is None:
        return pred_cols
    if isinstance(predictions, Mapping):
        items = dict(predictions)
    else:
        items = {f"{dataset.measured()}_model": predictions}
    for col, per_run in items.items():
        col = str(col)
        if col in names or col in pred_cols or not col or any(c in col for c in ',"\n'):
            raise input_error(
                source,
                f"prediction column name {col!r} is not allowed",
                "choose another name",
            )
        arrays = list(per_run.values()) if isinstance(per_run, Mapping) else list(per_run)
        if len(arrays) != len(dataset.runs):
            raise input_error(
                source,
                f"prediction {col!r} has {len(arrays)} arrays for {len(dataset.runs)} runs",
                "give one prediction array per run",
            )
        pred_cols[col] = [
            _prediction(run, arr, col, source)
            for run, arr in zip(dataset.runs, arrays, strict=True)
        ]
    return pred_cols


def _prediction(run: Run, arr: Any, col: str, source: str) -> np.ndarray:
    a = as_vector(arr, col, run.name, source)
    if a.size != run.n:
        raise input_error(
            source,
            f"prediction {col!r} has {a.size} samples but the run has {run.n}",
            "give one predicted value per sample",
            run=run.name,
        )
    return a
