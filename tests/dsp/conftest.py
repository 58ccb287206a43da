"""Fixtures and markers of the DSP tests."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).parent))  # the helper modules _dsp_exact, _dsp_apy


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers",
        "apytypes_1e6: bit-exact cross-check against APyTypes on ≥ 1e6 vectors (runs by default; "
        "deselect with -m 'not apytypes_1e6' for a quick loop)",
    )


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh, seeded generator per test."""
    return np.random.default_rng(20240613)
