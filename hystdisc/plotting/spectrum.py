"""The residual spectrum (Welch, averaged over runs) against the noise level."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from hystdisc.plotting.base import fill_doc, new_axes


@fill_doc
def plot_residual_spectrum(
    residuals: np.ndarray | Sequence[np.ndarray],
    fs: float,
    ax: Axes | None = None,
    noise_std: float | None = None,
    dominant_hz: float | None = None,
    label: str | None = None,
    **style: Any,
) -> Figure:
    """Welch spectrum of the output-error residual, averaged over runs.

    Parameters
    ----------
    residuals : array or list of arrays
        The residual of one run or of each run (:func:`hystdisc.closing.diagnostics.residual_spectrum`).
    fs : float
        Sampling rate in Hz.
    %(ax)s
    noise_std : float, optional
        Estimated measurement noise: its white level ``2 noise_std**2 / fs`` is drawn.
    dominant_hz : float, optional
        A frequency to mark (the dominant frequency of a structured residual).
    label : str, optional
        Legend label of the spectrum.
    **style
        Passed to ``Axes.loglog``.

    %(returns)s

    Examples
    --------
    >>> import numpy as np
    >>> rng = np.random.default_rng(0)
    >>> fig = plot_residual_spectrum([rng.normal(0, 1e-3, 2000)], 1000.0, noise_std=1e-3)
    >>> len(fig.axes[0].lines), fig.axes[0].get_xscale()
    (2, 'log')
    >>> import matplotlib.pyplot as plt; plt.close(fig)
    """
    from hystdisc.closing.diagnostics import residual_spectrum

    if isinstance(residuals, np.ndarray) and residuals.ndim == 1:
        residuals = [residuals]
    f, p, _ = residual_spectrum([np.asarray(r, dtype=float) for r in residuals], fs)
    if ax is None:
        ax = new_axes(figsize=(7, 3.5))[0]
    sel = (f > 0) & (p > 0)
    ax.loglog(f[sel], p[sel], lw=0.9, label=label, **style)
    if noise_std is not None and noise_std > 0:
        ax.axhline(
            2.0 * noise_std**2 / fs,
            color="0.4",
            lw=0.8,
            ls="--",
            label=f"white noise, std {noise_std:.3g}",
        )
    if dominant_hz is not None and np.isfinite(dominant_hz):
        ax.axvline(dominant_hz, color="tab:red", lw=0.8, ls=":", label=f"{dominant_hz:.3g} Hz")
    ax.set_xlabel("frequency [Hz]")
    ax.set_ylabel("PSD [unit^2/Hz]")
    if ax.get_legend_handles_labels()[1]:
        ax.legend(fontsize="x-small")
    return ax.figure
