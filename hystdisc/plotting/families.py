"""Family comparison: output-error RMS, held-out RMS and BIC differences."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc, new_axes


def _family_rows(families: Any) -> dict[str, dict[str, Any]]:
    """``{name: {rms, bic, heldout_rms}}`` from any of the accepted forms."""
    if isinstance(getattr(families, "families", None), Mapping):  # a Results
        families = families.families
    if isinstance(families, Mapping) and "families" in families:  # a results.json dict
        families = families["families"]
    rows = {}
    for name, f in dict(families).items():
        get = f.get if isinstance(f, Mapping) else lambda k, d=None, f=f: getattr(f, k, d)
        rows[name] = {"rms": get("rms"), "bic": get("bic"), "heldout_rms": get("heldout_rms")}
    return rows


@fill_doc
def plot_family_comparison(
    families: Any,
    ax: Axes | Sequence[Axes] | None = None,
    noise_std: float | None = None,
    selected: str | None = None,
) -> Figure:
    """Output-error RMS (and held-out RMS) of every family, and their BIC differences.

    Parameters
    ----------
    families : dict, Results or results dict
        Family name -> entry with ``rms``, ``bic`` and ``heldout_rms`` (a dict of
        ``results.json``, the :class:`~hystdisc.results.FamilyResult` records of
        ``Results.families`` or the ``OEFit`` objects of ``Discovery.family_fits_``), or a
        :class:`~hystdisc.results.Results` / ``results.json`` dict holding ``families``.
    ax : Axes or pair of Axes, optional
        A pair gives RMS bars and BIC-difference bars; a single Axes the RMS bars with the
        BIC differences written above them; None a new two-panel figure.
    noise_std : float, optional
        The noise level, drawn as a line on the RMS panel (a perfect model reaches it).
    selected : str, optional
        Family to highlight.

    %(returns)s

    Examples
    --------
    >>> fams = {"dahl": {"rms": 1.0e-3, "bic": -500.0, "heldout_rms": 1.1e-3},
    ...         "bingham": {"rms": 1.4e-2, "bic": -300.0, "heldout_rms": None}}
    >>> fig = plot_family_comparison(fams, noise_std=1e-3, selected="dahl")
    >>> len(fig.axes), [t.get_text() for t in fig.axes[1].get_xticklabels()]
    (2, ['dahl', 'bingham'])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    rows = _family_rows(families)
    if not rows:
        raise ValueError("no families to compare")
    names = list(rows)
    rms = np.array([float(rows[n]["rms"]) for n in names])
    ho = np.array(
        [np.nan if rows[n]["heldout_rms"] is None else float(rows[n]["heldout_rms"]) for n in names]
    )
    bic = np.array([float(rows[n]["bic"]) for n in names])
    dbic = bic - np.nanmin(bic)
    if ax is None:
        ax_r, ax_b = new_axes(1, 2, figsize=(10, 3.8))
    elif isinstance(ax, Axes):
        ax_r, ax_b = ax, None
    else:
        ax_r, ax_b = list(ax)
    x = np.arange(len(names))
    has_ho = bool(np.any(np.isfinite(ho)))
    w = 0.38 if has_ho else 0.6
    edge = ["tab:red" if n == selected else "none" for n in names]
    ax_r.bar(x - (w / 2 if has_ho else 0), rms, w, label="RMS (fit)", edgecolor=edge, lw=1.5)
    if has_ho:
        ax_r.bar(x + w / 2, np.nan_to_num(ho), w, label="held-out RMS", color="tab:orange")
    if noise_std is not None and noise_std > 0:
        ax_r.axhline(noise_std, color="0.3", ls="--", lw=0.8, label="noise")
    ax_r.set_yscale("log")
    ax_r.set_xticks(x, names)
    ax_r.set_ylabel("output-error RMS")
    ax_r.legend(fontsize="x-small")
    if ax_b is None:
        for xi, r, d in zip(x, rms, dbic, strict=True):
            ax_r.annotate(
                f"ΔBIC {d:.0f}",
                (xi, r),
                textcoords="offset points",
                xytext=(0, 3),
                ha="center",
                fontsize="x-small",
            )
    else:
        colors = ["tab:red" if n == selected else "tab:blue" for n in names]
        ax_b.bar(x, np.maximum(dbic, 0.5), 0.6, color=colors)
        ax_b.set_yscale("log")
        ax_b.set_xticks(x, names)
        ax_b.set_ylabel("BIC - min BIC (0 shown as 0.5)")
        ax_b.axhline(6.0, color="0.3", ls=":", lw=0.8)
    for a in (ax_r, ax_b):
        if a is not None:
            for lab in a.get_xticklabels():
                lab.set_rotation(20)
    return ax_r.figure
