"""Shared fixtures.  Hypothesis strategies live in ``strategies.py``.

Tests write nothing outside temporary directories: ncstab's caches
(``NCSTAB_CACHE_DIR``, by default ``~/.cache/ncstab``: the compiled stepper's
loops, the law classes, :mod:`ncstab.cache`) and matplotlib's (``MPLCONFIGDIR``,
by default ``~/.cache/matplotlib``) are in a temporary directory of the session,
made by the controlling process and inherited by pytest-xdist's workers and by
the subprocesses tests start, and nothing is left in the user's home.  Figures,
archives and doc examples write into ``tmp_path``.
"""

from __future__ import annotations

import os
import shutil
import tempfile

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


#: Caches that would otherwise go to the user's home: variable -> subdirectory of the session's.
SESSION_CACHES = {"NCSTAB_CACHE_DIR": "ncstab", "MPLCONFIGDIR": "matplotlib"}
_SAVED = pytest.StashKey[dict[str, str | None]]()
_MADE = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """Point the caches of :data:`SESSION_CACHES` at a temporary directory of this session.

    The controlling process makes it (before pytest-xdist starts its workers,
    which inherit the environment); a worker finds the variables set and keeps
    them.  What the variables held before is restored at the end.
    """
    if os.environ.get("PYTEST_XDIST_WORKER"):
        return
    directory = tempfile.mkdtemp(prefix="ncstab-test-session-")
    config.stash[_MADE] = directory
    config.stash[_SAVED] = {name: os.environ.get(name) for name in SESSION_CACHES}
    for name, subdirectory in SESSION_CACHES.items():
        os.environ[name] = os.path.join(directory, subdirectory)


def pytest_unconfigure(config: pytest.Config) -> None:
    """Remove the session's cache directory and restore the variables."""
    if _MADE not in config.stash:
        return
    shutil.rmtree(config.stash[_MADE], ignore_errors=True)
    for name, saved in config.stash[_SAVED].items():
        if saved is None:
            os.environ.pop(name, None)
        else:
            os.environ[name] = saved


def pytest_report_header(config: pytest.Config) -> str:
    """Say once where this session's caches go."""
    where = ", ".join(f"{name}={os.environ.get(name)}" for name in SESSION_CACHES)
    return f"caches of this session (removed at the end): {where}"
