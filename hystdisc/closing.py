"""Closing the loop: residual -> the catalogued effect the model lacks -> refit (placeholder).

Being written (issue 4); until then the loop only records the residual diagnostics.
"""

from __future__ import annotations


def close_loop(disc, dataset) -> None:
    """Diagnose the residual of ``disc`` (a fitted Discovery) and add effects that help."""
    return None
