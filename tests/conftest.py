"""Shared test set-up: a non-interactive matplotlib backend and the measured-data folder."""

from __future__ import annotations

import os
from pathlib import Path

import matplotlib
import pytest

matplotlib.use("Agg")


@pytest.fixture(scope="session")
def data_dir() -> Path:
    """The measured data folder (``../shared/data``), found through ``HYSTDISC_DATA``."""
    value = os.environ.get("HYSTDISC_DATA")
    if not value:
        pytest.skip("HYSTDISC_DATA is not set; measured-data tests need ../shared/data")
    path = Path(value)
    if not path.is_dir():
        pytest.skip(
            f"HYSTDISC_DATA={value} is not a folder; measured-data tests need ../shared/data"
        )
    return path
