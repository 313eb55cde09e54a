"""Current laws: every law parameter against the current, with its intervals and its law."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc, new_axes

#: How each law's curve is written in the legend.
LAW_TEXT = {
    "linear": "a + b i",
    "quadratic": "a + b i + q i²",
    "saturating": "a + b i0 tanh(i/i0)",
}


def _laws_table(current_laws: Any) -> Mapping[str, Mapping]:
    """The ``laws`` table from a ``current_laws`` dict, a Results or a StagedFit."""
    if hasattr(current_laws, "current_laws"):  # Results
        current_laws = current_laws.current_laws or {}
    elif hasattr(current_laws, "levels"):  # StagedFit
        current_laws = current_laws.to_dict()
    if "current_laws" in current_laws:  # a results.json dict
        current_laws = current_laws["current_laws"] or {}
    return current_laws.get("laws", current_laws)


def _curve(law: str, coefs: Sequence[float], i: np.ndarray) -> np.ndarray:
    a, b = coefs[0], coefs[1]
    if law == "quadratic":
        return a + b * i + coefs[2] * i * i
    if law == "saturating":
        return a + b * coefs[2] * np.tanh(i / coefs[2])
    return a + b * i


@fill_doc
def plot_current_laws(current_laws: Any, axes: Axes | Sequence[Axes] | None = None) -> Figure:
    """Each law parameter against the current: per-level values with their 95 % intervals,
    the chosen law's curve and (dashed) the linear law fitted to the same levels.

    Parameters
    ----------
    current_laws : dict, Results or StagedFit
        The ``current_laws`` table of ``results.json`` (or its ``laws`` part), a
        :class:`~hystdisc.results.Results` holding one, or a
        :class:`~hystdisc.fitting.StagedFit`.
    axes : Axes or sequence of Axes, optional
        One per law parameter (a single Axes draws them all); a new figure when omitted.

    %(returns)s

    Examples
    --------
    >>> laws = {"alpha": {"parameter": "alpha_1", "currents": [0, 0.5, 1],
    ...                   "values": [0.5, 1.3, 1.4], "ci95": [[0.49, 0.51]] * 3,
    ...                   "law": "saturating",
    ...                   "coefficients": {"alpha_1": 0.5, "alpha_2": 3.0, "alpha_i0": 0.3},
    ...                   "heldout": {}}}
    >>> fig = plot_current_laws(laws)
    >>> fig.axes[0].get_xlabel(), [t.get_text()[:10] for t in fig.axes[0].get_legend().get_texts()]
    ('current [A]', ['saturating', 'linear', 'alpha_1 pe'])
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    laws = dict(_laws_table(current_laws))
    if axes is None:
        axs = new_axes(1, max(len(laws), 1), figsize=(4.2 * max(len(laws), 1), 3.4))
    elif isinstance(axes, Axes):
        axs = [axes] * len(laws)
    else:
        axs = list(axes)
    for ax, (key, d) in zip(axs, laws.items(), strict=False):
        i = np.asarray(d["currents"], dtype=float)
        v = np.asarray(d["values"], dtype=float)
        ci = np.asarray(d["ci95"], dtype=float).reshape(-1, 2)
        err = np.abs(np.vstack([v - ci[:, 0], ci[:, 1] - v]))
        ax.errorbar(i, v, yerr=err, fmt="o", capsize=3, label=f"{d['parameter']} per level")
        grid = np.linspace(min(0.0, i.min()), i.max() * 1.05 if i.max() > 0 else 1.0, 200)
        coefs = list(d["coefficients"].values())
        held = (d.get("heldout") or {}).get(d["law"]) or {}
        extra = f", held-out z {held['z']:.3g}" if "z" in held else ""
        ax.plot(
            grid, _curve(d["law"], coefs, grid), label=f"{d['law']}: {LAW_TEXT[d['law']]}{extra}"
        )
        if d["law"] != "linear":
            b, a = np.polyfit(i, v, 1, w=1.0 / np.maximum(err.mean(axis=0), 1e-300))
            lin = (d.get("heldout") or {}).get("linear") or {}
            lx = f" (held-out z {lin['z']:.3g})" if "z" in lin else ""
            ax.plot(grid, a + b * grid, "--", color="0.5", label=f"linear{lx}")
        ax.set_xlabel("current [A]")
        ax.set_ylabel(d["parameter"])
        ax.set_title(f"{key}: {d['law']} law")
        ax.legend(fontsize="small")
    return axs[0].figure
