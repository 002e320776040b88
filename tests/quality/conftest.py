"""Fixtures for the grasp-quality tests (helpers live in quality_support.py)."""

from __future__ import annotations

import numpy as np
import pytest


@pytest.fixture
def rng() -> np.random.Generator:
    """A fixed-seed generator: every test is reproducible."""
    return np.random.default_rng(20261122)
