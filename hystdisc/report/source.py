"""What the report draws, kept beside ``results.json``: the report without a refit.

``results.json`` holds the numbers of a fit (families, parameters, effects, residual), not
the signals the report draws: the measured runs, every fit's simulated output, the
hysteresis loops, the residuals and the stage-1 path. :func:`report_data` collects them
from a fitted :class:`~hystdisc.Discovery`; :meth:`ReportData.save` writes them to
``results.report.npz`` beside ``results.json`` (``hystdisc discover`` does, whenever it
writes ``results.json``), and :func:`load_report_data` reads both back. The report is
rendered from a :class:`ReportData` only, with its ``results`` read back from the JSON
text, so ``hystdisc report results.json`` writes the same report, byte for byte, as
``hystdisc report DATA`` with the fit's options.

The file is a NumPy ``.npz`` (compressed, read without pickle): the arrays, and one JSON
text (``__meta__``) with the structure that names them. Signals are kept as drawn, in
single precision: series decimated to at most :data:`~hystdisc.report.markup.MAX_POINTS`
samples, except the residuals, whose spectrum needs every sample (about 1.5 MB for five
runs of 6000 samples and seven fits).

Examples
--------
>>> import tempfile, pathlib
>>> from hystdisc.estimator import Discovery
>>> from hystdisc.simulation.synth import generate
>>> data = generate("dahl", currents=(0, 1), duration=1.0, seed=1)
>>> disc = Discovery(families=["dahl"], heldout=False, close_loop=False).fit(data)
>>> rd = report_data(disc, data)
>>> with tempfile.TemporaryDirectory() as d:
...     _ = disc.results_.save(pathlib.Path(d, "results.json"))
...     _ = rd.save(report_data_path(pathlib.Path(d, "results.json")))
...     back = load_report_data(pathlib.Path(d, "results.json"))
>>> back.equations == rd.equations, back.fits == rd.fits, back.results.family
(True, True, 'dahl')
"""

from __future__ import annotations

import io
import json
import os
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np

from hystdisc.data import Dataset, atomic_write_bytes
from hystdisc.errors import HystdiscError
from hystdisc.report.markup import thin
from hystdisc.report.signals import (
    check_fitted,
    final_fit,
    fit_data,
    fit_label,
    fit_sampling_rate,
    fit_signals,
    fits_of,
    masked_residuals,
    model_loops,
)
from hystdisc.results import Results

__all__ = ["FORMAT", "ReportData", "load_report_data", "report_data", "report_data_path"]

#: Version of the ``.report.npz`` layout (a reader refuses another).
FORMAT = 1
#: Suffix of the file beside ``results.json`` (``results.json`` -> ``results.report.npz``).
SUFFIX = ".report.npz"


def report_data_path(results_path: str | os.PathLike[str]) -> Path:
    """The report data kept beside a results file.

    Examples
    --------
    >>> report_data_path("out/results.json").as_posix()
    'out/results.report.npz'
    >>> report_data_path("bw.results.json").name
    'bw.results.report.npz'
    """
    p = Path(results_path)
    return p.with_name(p.stem + SUFFIX)


@dataclass
class ReportData:
    """The signals of a fit the report draws, and the fit's results.

    Attributes
    ----------
    results : Results
        The fit's record, as ``results.json`` holds it.
    equations : str
        The discovered equations (``Discovery.equations()``).
    noise_std : float or None
        The estimated measurement noise, data units.
    input : str
        The ``input`` of the results it belongs to.
    source, experiment, measured : str
        The dataset's source, experiment type and measured signal (``theta``/``torque``).
    raw : list of dict
        Each run as read: ``name, current, n`` (samples), ``t`` and ``y`` (decimated).
    runs : dict
        The runs as fitted: ``names, currents`` and, per run, ``t, y``, ``mask`` (the
        samples in the fit) and ``theta`` (the angle or imposed motion, for the residual
        map; absent from reports written before it).
    fits : dict
        Each fit drawn (families, ``discovered``, ``final``): ``label`` and ``rms``.
    signals : list of dict
        Per fitted run: ``name, current``, ``t``, ``measured`` and ``predictions`` (fit
        -> simulated output), decimated.
    loops : list of dict
        The hysteresis loops of data and fits (:func:`~hystdisc.report.model_loops`),
        decimated.
    final : bool
        Effects were accepted (the fit ``final`` is drawn).
    spectrum : dict
        ``fs``, ``after`` and (with effects) ``before``: ``label, key`` and the residual of
        every run, for the residual spectrum.
    stage1 : dict
        ``rows`` of the shapes compared, ``selected`` (the discovered shape), ``path`` and
        ``inclusion`` of the discovered one.
    """

    results: Results
    equations: str = ""
    noise_std: float | None = None
    input: str = ""
    source: str = ""
    experiment: str = ""
    measured: str = "theta"
    raw: list[dict[str, Any]] = field(default_factory=list)
    runs: dict[str, Any] = field(default_factory=dict)
    fits: dict[str, dict[str, Any]] = field(default_factory=dict)
    signals: list[dict[str, Any]] = field(default_factory=list)
    loops: list[dict[str, Any]] = field(default_factory=list)
    final: bool = False
    spectrum: dict[str, Any] = field(default_factory=dict)
    stage1: dict[str, Any] = field(default_factory=dict)

    def save(self, path: str | os.PathLike[str], force: bool = False) -> Path:
        """Write the signals (not ``results``) as a compressed ``.npz``, atomically.

        Parameters
        ----------
        path : path-like
            The file (:func:`report_data_path` of the results file).
        force : bool
            Replace an existing file.

        Returns
        -------
        pathlib.Path
            The file written.
        """
        arrays: list[np.ndarray] = []
        meta = {
            f.name: _pack(getattr(self, f.name), arrays)
            for f in fields(self)
            if f.name != "results"
        }
        meta["format"] = FORMAT
        buf = io.BytesIO()
        named = {f"a{k}": a for k, a in enumerate(arrays)}
        np.savez_compressed(buf, __meta__=np.array(json.dumps(meta)), **named)
        return atomic_write_bytes(path, buf.getvalue(), force=force)


def _pack(obj: Any, arrays: list[np.ndarray]) -> Any:
    """``obj`` as JSON, each array replaced by a reference into ``arrays``."""
    if isinstance(obj, np.ndarray):
        arrays.append(obj)
        return {"__array__": len(arrays) - 1}
    if isinstance(obj, dict):
        return {str(k): _pack(v, arrays) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_pack(v, arrays) for v in obj]
    if isinstance(obj, np.generic):
        return obj.item()
    return obj


def _unpack(obj: Any, store) -> Any:
    if isinstance(obj, dict):
        if set(obj) == {"__array__"}:
            return store[f"a{obj['__array__']}"]
        return {k: _unpack(v, store) for k, v in obj.items()}
    if isinstance(obj, list):
        return [_unpack(v, store) for v in obj]
    return obj


def _as_results(res: Results) -> Results:
    """``res`` as ``results.json`` gives it back (floats rounded as the reader rounds)."""
    return Results.from_json(res.to_json())


def load_report_data(results_path: str | os.PathLike[str]) -> ReportData:
    """Read ``results.json`` and the report data beside it.

    Parameters
    ----------
    results_path : path-like
        The ``results.json`` written by ``hystdisc discover``.

    Returns
    -------
    ReportData

    Raises
    ------
    HystdiscError
        One line naming the file and the fix: a missing or foreign file, report data
        missing, damaged or of another fit.
    """
    path = Path(results_path)
    res = Results.load(path)
    side = report_data_path(path)
    if not side.is_file():
        raise HystdiscError(
            f"{path}: the report data beside it ({side.name}) is missing, so the report "
            "cannot be drawn without a refit; fix: rerun hystdisc discover (it writes both "
            "files), or give the data: hystdisc report DATA"
        )
    try:
        with np.load(side, allow_pickle=False) as store:
            meta = json.loads(str(store["__meta__"]))
            if meta.pop("format", None) != FORMAT:
                raise ValueError(f"not report data of format {FORMAT}")
            body = _unpack(meta, store)
    except (OSError, ValueError, KeyError, json.JSONDecodeError) as exc:
        raise HystdiscError(
            f"{side}: not readable report data ({exc}); fix: rerun hystdisc discover"
        ) from None
    names = {f.name for f in fields(ReportData)}
    rd = ReportData(results=res, **{k: v for k, v in body.items() if k in names})
    if rd.stage1.get("family", res.family) != res.family or rd.input != res.input:
        raise HystdiscError(
            f"{side}: holds the signals of another fit than {path.name} (family "
            f"{rd.stage1.get('family')}, input {rd.input}); fix: rerun hystdisc discover"
        )
    return rd


def _drawn(x: Any) -> np.ndarray:
    """A signal as it is drawn: single precision (a figure shows no more)."""
    return np.asarray(x, dtype=np.float32)


def _thinned(x: Any) -> np.ndarray:
    a = _drawn(x)
    return a[thin(a.size)] if a.ndim == 1 else a


def report_data(disc, dataset: Dataset) -> ReportData:
    """Collect what the report draws from a fitted discovery.

    Parameters
    ----------
    disc : Discovery
        A fitted discovery.
    dataset : Dataset
        The dataset it was fitted on.

    Returns
    -------
    ReportData
        Its ``results`` are ``disc.results_`` as ``results.json`` gives them back.
    """
    check_fitted(disc)
    fd = fit_data(disc)
    res = _as_results(disc.results_)
    fits = fits_of(disc)
    measured = dataset.measured()
    raw = [
        {
            "name": r.name,
            "current": float(r.current),
            "n": int(r.n),
            "t": _thinned(r.t),
            "y": _thinned(getattr(r, measured)),
        }
        for r in dataset.runs
    ]
    runs = {
        "names": [str(n) for n in fd.names],
        "currents": [float(c) for c in fd.currents],
        "t": [np.asarray(t, dtype=float) for t in fd.t],
        "y": [np.asarray(y, dtype=float) for y in fd.y],
        "mask": [np.asarray(m, dtype=bool) for m in fd.mask],
        "theta": [_drawn(x) for x in fd.theta],
    }
    signals = [
        {
            "name": str(s["name"]),
            "current": s["current"],
            "t": _thinned(s["t"]),
            "measured": _thinned(s["measured"]),
            "predictions": {k: _thinned(v) for k, v in s["predictions"].items()},
        }
        for s in fit_signals(disc)
    ]
    loops = []
    for lp in model_loops(disc):
        k = thin(len(lp["t"]))
        item = {q: _drawn(lp[q])[k] for q in ("t", "theta", "theta_dot", "torque")}
        style = {s: v for s, v in lp["style"].items() if v is not None}
        loops.append(
            {
                **item,
                "current": float(lp["current"]),
                "run": int(lp["run"]),
                "kind": str(lp["kind"]),
                "label": str(lp["label"]),
                "style": style,
            }
        )
    base = disc.family_fits_[disc.family_]
    final = final_fit(disc)
    spectrum: dict[str, Any] = {"fs": float(fit_sampling_rate(fd))}
    if final is not None:
        spectrum["before"] = {
            "key": disc.family_,
            "label": f"{disc.family_} (before)",
            "residuals": [_drawn(r) for r in masked_residuals(base, fd)],
        }
        spectrum["after"] = {
            "key": "final",
            "label": fit_label(disc, "final") + " (after)",
            "residuals": [_drawn(r) for r in masked_residuals(final, fd)],
        }
    else:
        spectrum["after"] = {
            "key": disc.family_,
            "label": disc.family_,
            "residuals": [_drawn(r) for r in masked_residuals(base, fd)],
        }
    rows, selected = [], None
    for shape, sf in disc.stage1_.items():
        rows.append(
            {
                "shape": str(shape),
                "terms": [str(t) for t in sf.terms],
                "s": [float(v) for v in np.atleast_1d(sf.s)],
                "bic": None if sf.bic is None else float(sf.bic),
            }
        )
    selected = disc.discovered_shape_
    best = disc.stage1_[selected]
    path = [
        {
            "threshold": float(p["threshold"]),
            "coefs": {str(k): float(v) for k, v in p["coefs"].items()},
            "bic": float(p["bic"]),
        }
        for p in (best.path or [])
    ]
    inclusion = {str(k): float(v) for k, v in (best.inclusion or {}).items()}
    return ReportData(
        results=res,
        equations=disc.equations(),
        noise_std=None if disc.noise_std_ is None else float(disc.noise_std_),
        input=res.input,
        source=str(dataset.source),
        experiment=str(fd.experiment),
        measured=measured,
        raw=raw,
        runs=runs,
        fits={k: {"label": fit_label(disc, k), "rms": float(f.rms)} for k, f in fits.items()},
        signals=signals,
        loops=loops,
        final=final is not None,
        spectrum=spectrum,
        stage1={
            "family": res.family,
            "rows": rows,
            "selected": str(selected),
            "shape": str(best.shape),
            "path": path,
            "inclusion": inclusion,
        },
    )
