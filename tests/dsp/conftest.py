"""Fixtures of the DSP tests (the oracles live in _dsp_exact and _dsp_apy)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    """A fresh, seeded generator per test."""
    return np.random.default_rng(20240613)
