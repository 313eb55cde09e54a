"""hystdisc: discover the hysteresis model of an MR damper from measured data."""

from __future__ import annotations

__version__ = "0.1.0"

from hystdisc.errors import HystdiscError, HystdiscWarning  # noqa: E402

__all__ = ["HystdiscError", "HystdiscWarning", "__version__"]
