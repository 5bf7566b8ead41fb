"""Shared fixtures.  Hypothesis strategies live in ``strategies.py``.

Tests write nothing outside temporary directories: ncstab's caches
(``NCSTAB_CACHE_DIR``, by default ``~/.cache/ncstab``: the compiled stepper's
loops, the law classes, :mod:`ncstab.cache`) and matplotlib's (``MPLCONFIGDIR``,
by default ``~/.cache/matplotlib``) are in a temporary directory of the session,
made by the controlling process and inherited by pytest-xdist's workers and by
the subprocesses tests start, and nothing is left in the user's home.  Figures,
archives and doc examples write into ``tmp_path``.

Before the tests start (and before pytest-xdist starts its workers), the
controlling process compiles the numba loops (one per form of law, rate or
total) and the kernels of the catalogue laws the tests follow
(:data:`WARM_LAWS`; the compiled stepper is the default engine) into the
session's cache, one process per form, so that no worker compiles them again:
each loop is compiled once per session, not once per worker.  It does
so when the tests run on two pytest-xdist workers or more (a single process
compiles each loop once anyway, on first use); ``NCSTAB_TEST_WARM=0`` skips it
(the tests then compile the loops they need themselves).  The report header
says what was done; a warm-up that fails is reported there, and the tests run
anyway.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
from pathlib import Path

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
_WARMED = pytest.StashKey[str]()


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


# --- compiling the compiled stepper's loops once per session -----------------------------------

#: The catalogue laws the tests follow on the reduced diamond (the compiled
#: stepper is the default there): the first compiles the diamond's loop, and each
#: its kernel (their ``no_tension`` variants compile their own kernels, in a
#: second, where a test first follows them).
WARM_LAWS = ("cundall_strack", "weakly_hypoelastic", "mcnamara", "turco")
#: The general models' loop (:mod:`ncstab.paths.loop_general`), warmed by a column of four
#: links, the kernel of a ring of four grains under a rate law and the Dataset's indicators
#: (:mod:`ncstab.engine_warmup`).
WARM_GENERAL = ("general-total", "general-rate", "dataset")


def warm_compiled_loops(laws: tuple[str, ...], processes: int) -> None:
    """Compile the loops of ``laws`` into the cache of ``$NCSTAB_CACHE_DIR``, in ``processes``
    Python processes at once (:func:`ncstab.engine_warmup.compile_loops`, as ``ncstab cache
    compile`` does).

    Raises
    ------
    RuntimeError
        When a process fails, with the last line it printed.
    """
    from ncstab.engine_warmup import compile_loops

    compile_loops(laws, processes)


def _distributed(config: pytest.Config) -> bool:
    """Whether pytest-xdist runs the tests on two workers or more (each would compile the loops)."""
    workers = getattr(config.option, "numprocesses", None)
    if workers == "auto" or workers == "logical":
        workers = os.cpu_count() or 1
    return isinstance(workers, int) and workers > 1


@pytest.hookimpl(tryfirst=True)
def pytest_sessionstart(session: pytest.Session) -> None:
    """Warm the compiled stepper's cache (:func:`warm_compiled_loops`) in the controlling
    process, before pytest-xdist starts its workers (its ``pytest_sessionstart`` is
    ``trylast``); say so in the report header."""
    config = session.config
    if os.environ.get("PYTEST_XDIST_WORKER") or _MADE not in config.stash or config.option.collectonly:
        return
    directory = Path(os.environ["NCSTAB_CACHE_DIR"]) / "compiled"
    if os.environ.get("NCSTAB_TEST_WARM", "1") == "0":
        config.stash[_WARMED] = "compiled loops not warmed (NCSTAB_TEST_WARM=0): the tests compile them"
        return
    if not _distributed(config):
        return  # one process compiles each loop once, on first use, anyway
    processes = max(1, min(len(WARM_LAWS), os.cpu_count() or 1))
    reporter = config.pluginmanager.get_plugin("terminalreporter")
    if reporter is not None:
        reporter.write_line(f"warming the compiled loops of {len(WARM_LAWS)} laws and of the general models in {processes} processes "
                            "(NCSTAB_TEST_WARM=0 skips it) ...")
    start = time.perf_counter()
    try:
        warm_compiled_loops(WARM_LAWS + WARM_GENERAL, processes)
    except (OSError, RuntimeError, subprocess.SubprocessError) as error:  # the tests run anyway
        line = (f"warming the compiled loops failed ({type(error).__name__}: {error}); "
                "tests compile those they need")
    else:
        line = (f"warmed the compiled loops of {len(WARM_LAWS)} laws and of the general models in {time.perf_counter() - start:.1f} s "
                f"into {directory}")
    config.stash[_WARMED] = line
    if reporter is not None and (config.get_verbosity() < 0 or config.option.no_header):  # no header
        reporter.write_line(line)


def pytest_report_header(config: pytest.Config) -> list[str]:
    """Say once where this session's caches go, and whether the compiled loops were warmed."""
    where = ", ".join(f"{name}={os.environ.get(name)}" for name in SESSION_CACHES)
    lines = [f"caches of this session (removed at the end): {where}"]
    if _WARMED in config.stash:
        lines.append(config.stash[_WARMED])
    return lines
