"""Shared fixtures.  Hypothesis strategies live in ``strategies.py``."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import settings

from ncstab.systems import DiamondChain

# Defaults for every property test; each test still states its own
# ``max_examples`` so that its cost is visible where it is written.  No deadline:
# the first example of a test may compile a law with sympy (about a second).
settings.register_profile("ncstab", deadline=None, max_examples=50)
settings.load_profile("ncstab")


@pytest.fixture
def rng() -> np.random.Generator:
    """A seeded generator: random matrices are reproducible run to run."""
    return np.random.default_rng(20220712)


@pytest.fixture
def diamond() -> DiamondChain:
    """The seed's paradigmatic configuration, alpha0 = pi/4."""
    return DiamondChain(alpha0=np.pi / 4)
