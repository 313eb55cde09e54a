"""The single entry point :func:`load`: files or folders, dispatched on the extension.

``.csv`` -> :func:`~hystdisc.data.read_csv`, ``.mat`` -> :func:`~hystdisc.data.read_mat`,
anything else -> :func:`~hystdisc.data.read_table` (which needs a rig description). The
datasets read are joined into one, checked with :func:`~hystdisc.data.validate`.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from hystdisc.data.columns import DATA_SUFFIXES, check_column_map, infer_experiment
from hystdisc.data.csvfile import read_csv
from hystdisc.data.dataset import Dataset, Run, check_experiment
from hystdisc.data.mat import mat_lookup, read_mat
from hystdisc.data.plausibility import ImplausibleUnitsWarning
from hystdisc.data.rigs import normalize_rig, read_rig
from hystdisc.data.table import read_table
from hystdisc.data.validation import validate
from hystdisc.errors import input_error

__all__ = ["load"]


@dataclasses.dataclass
class _Options:
    """How to read every file: the rig's settings overridden by the arguments of load()."""

    experiment: str | None
    columns: dict[str, Any]
    units: dict[str, str]
    current: float | None
    fs: float | None
    rig: dict[str, Any]


def _expand(paths: Any) -> tuple[list[Path], Path | None, str]:
    """Files to read, the rig.toml found in a given folder, and a source label."""
    items = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if not items:
        raise input_error(None, "no input files given", "pass a data file or a folder")
    files: list[Path] = []
    rig_file: Path | None = None
    for item in items:
        p = Path(item)
        if not p.exists():
            raise input_error(str(item), "file does not exist", "check the path")
        if p.is_dir():
            found = sorted(
                (q for q in p.iterdir() if q.is_file() and q.suffix.lower() in DATA_SUFFIXES),
                key=lambda q: q.name,
            )
            if not found:
                raise input_error(
                    str(item),
                    f"folder holds no data files ({', '.join('*' + s for s in DATA_SUFFIXES)})",
                    "point to the folder with the measured runs",
                )
            files.extend(found)
            if (p / "rig.toml").is_file() and rig_file is None:
                rig_file = p / "rig.toml"
        else:
            files.append(p)
    if len(items) == 1:
        label = str(items[0])
    elif len(files) <= 3:
        label = ", ".join(str(f) for f in files)
    else:
        label = f"{files[0]} and {len(files) - 1} more files"
    return files, rig_file, label


def load(
    paths: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    experiment: str | None = None,
    rig: str | os.PathLike[str] | Mapping[str, Any] | None = None,
    columns: Mapping[str, str | int] | None = None,
    units: Mapping[str, str] | None = None,
    *,
    current: float | None = None,
    fs: float | None = None,
) -> Dataset:
    """Load one or several data files (or folders) into one checked Dataset.

    Dispatches on the extension: ``.csv`` -> :func:`read_csv`, ``.mat`` -> :func:`read_mat`,
    anything else -> :func:`read_table`, which needs a rig description (``rig=``, or a
    ``rig.toml`` inside a folder given as input). A folder means all its ``*.txt, *.dat,
    *.csv, *.mat`` files, sorted by name. Several files are concatenated; when run names
    collide every run is renamed ``<file stem>:<run>``. All files must hold the same
    experiment type. Several ``.mat`` files that each lack ``theta`` are merged into one run
    (input and output saved separately).

    Parameters
    ----------
    paths : path-like or list of path-likes
        Files and/or folders.
    experiment : {"release", "driven", "forced"}, optional
        Overrides the rig description and the inference from columns.
    rig : path-like or dict, optional
        Rig description (see :func:`read_rig`).
    columns, units : dict, optional
        Override (per key) the rig's ``[columns]`` and ``[units]``.
    current : float, optional
        Coil current for files that do not record it (overrides the rig's ``value``).
    fs : float, optional
        Sampling rate for files without a time column/variable.

    Returns
    -------
    Dataset
        Checked with ``validate(dataset, need_currents=1)``.
    """
    files, found_rig, label = _expand(paths)
    if rig is None and found_rig is not None:
        rig = found_rig
    if rig is None:
        settings = normalize_rig({}, label)
    elif isinstance(rig, Mapping):
        settings = normalize_rig(rig, "rig description")
    else:
        settings = read_rig(rig)
    exp = check_experiment(experiment, label) if experiment is not None else settings["experiment"]
    colmap = dict(settings["columns"])
    colmap.update(check_column_map(columns, label))
    unit_map = dict(settings["units"])
    unit_map.update(dict(units or {}))
    opts = _Options(
        experiment=exp,
        columns=colmap,
        units=unit_map,
        current=current if current is not None else settings["current"]["value"],
        fs=fs if fs is not None else settings["fs"],
        rig=settings,
    )
    mats = [f for f in files if f.suffix.lower() == ".mat"]
    merge_mats = len(mats) > 1 and _mats_split_signals(mats, colmap)
    datasets: list[tuple[Path, Dataset]] = []
    done_mats = False
    reads = len(files) - (len(mats) - 1 if merge_mats else 0)
    with warnings.catch_warnings():
        if reads > 1:  # units are judged once, on all files together (_join)
            warnings.simplefilter("ignore", ImplausibleUnitsWarning)
        for f in files:
            if merge_mats and f.suffix.lower() == ".mat":
                if not done_mats:  # all .mat files are read at the first one, as one record
                    datasets.append((f, _read_mat(mats, opts)))
                done_mats = True
                continue
            datasets.append((f, _read_file(f, opts)))
    out = _join(datasets, label)
    out.filter = settings["filter"]
    return out


def _mats_split_signals(mats: list[Path], colmap: Mapping[str, Any]) -> bool:
    """True when some ``.mat`` file lacks theta: input and output saved separately."""
    theta_name = colmap.get("theta", "theta")
    if not isinstance(theta_name, str):
        return False
    import scipy.io

    def has_theta(f: Path) -> bool:
        try:
            names = [w[0] for w in scipy.io.whosmat(str(f))]
        except Exception:
            return True  # let read_mat report the problem
        return mat_lookup(dict.fromkeys(names), theta_name) is not None

    return not all(has_theta(f) for f in mats)


def _read_mat(path: Path | list[Path], opts: _Options) -> Dataset:
    return read_mat(
        path,
        opts.experiment,
        opts.columns or None,
        opts.units or None,
        current=opts.current,
        fs=opts.fs,
    )


def _read_file(f: Path, opts: _Options) -> Dataset:
    """One file, read by the reader its extension names."""
    suffix = f.suffix.lower()
    if suffix == ".csv":
        return read_csv(f, opts.experiment, opts.columns or None, opts.units or None)
    if suffix == ".mat":
        return _read_mat(f, opts)
    if not opts.columns:
        raise input_error(
            str(f),
            "is a table without header and no rig description says what its columns are",
            "describe the columns in a rig.toml (experiment, [columns], [units], [current]) "
            "and pass --rig rig.toml, or put it in the data folder",
        )
    table_exp = opts.experiment
    if table_exp is None:
        table_exp = infer_experiment(list(opts.columns), str(f))
    current_rule = opts.rig["current"]
    return read_table(
        f,
        opts.columns,
        table_exp,
        units=opts.units or None,
        current=opts.current,
        current_from_name=current_rule["from_name"],
        skip_rows=opts.rig["skip_rows"],
        decimal=current_rule["decimal"],
        fs=opts.fs,
    )


def _join(datasets: list[tuple[Path, Dataset]], label: str) -> Dataset:
    """One dataset of all runs; colliding run names get the file stem as a prefix."""
    if len(datasets) == 1:
        ds = datasets[0][1]
        ds.source = label
        return ds
    kinds = {ds.experiment for _, ds in datasets}
    if len(kinds) > 1:
        shown = "; ".join(f"{f.name}: {ds.experiment}" for f, ds in datasets[:6])
        raise input_error(
            label,
            f"the files hold different experiment types ({shown})",
            "load them separately, or pass --experiment to read them all the same way",
        )
    runs = [r for _, ds in datasets for r in ds.runs]
    names = [r.name for r in runs]
    if len(set(names)) != len(names):
        runs = _prefixed_runs(datasets)
    out = Dataset(runs, kinds.pop(), label)
    validate(out, need_currents=1)
    return out


def _prefixed_runs(datasets: list[tuple[Path, Dataset]]) -> list[Run]:
    """Runs renamed ``<file stem>:<run>`` (and ``#2``, ``#3``... if still not unique)."""
    renamed = []
    for f, ds in datasets:
        for r in ds.runs:
            renamed.append(dataclasses.replace(r, name=f"{f.stem}:{r.name}"))
    count: dict[str, int] = {}
    runs = []
    for r in renamed:
        count[r.name] = count.get(r.name, 0) + 1
        runs.append(
            r if count[r.name] == 1 else dataclasses.replace(r, name=f"{r.name}#{count[r.name]}")
        )
    return runs
