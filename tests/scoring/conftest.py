"""Fixtures of the scoring tests (helpers live in scoring_helpers.py: importable by name)."""

import numpy as np
import pytest


@pytest.fixture
def rng():
    return np.random.default_rng(20240607)
