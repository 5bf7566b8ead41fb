"""A new machine compiles ncstab's engine once: the first cache miss of a process says so on a
terminal (:func:`ncstab.numba_cache.announce_compilation`), and nowhere else."""

from __future__ import annotations

import io

import pytest

from ncstab import numba_cache
from ncstab.paths import assembled_path


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture
def fresh(monkeypatch):
    monkeypatch.setattr(numba_cache, "_announced", False)


def test_the_first_miss_of_ncstab_code_is_announced_once_on_a_terminal(fresh, monkeypatch):
    terminal = Terminal()
    monkeypatch.setattr("sys.stderr", terminal)
    assert numba_cache.announce_compilation(assembled_path.follow_case)
    assert not numba_cache.announce_compilation(assembled_path.follow_case)  # once a process
    assert terminal.getvalue() == numba_cache.COMPILING_NOTICE + "\n"


def test_no_notice_off_a_terminal_nor_for_code_not_ncstabs(fresh, monkeypatch):
    pipe = io.StringIO()  # a pipe, a log file, a test's capture: not a terminal
    monkeypatch.setattr("sys.stderr", pipe)
    assert not numba_cache.announce_compilation(assembled_path.follow_case)
    monkeypatch.setattr("sys.stderr", Terminal())
    assert not numba_cache.announce_compilation(io.StringIO)  # numba compiling a user's own function
    assert pipe.getvalue() == ""


def test_a_cache_miss_reaches_the_notice(fresh, monkeypatch):
    """numba's Cache.load_overload, once hardened, announces when it finds nothing."""
    from numba.core import caching

    calls = []
    monkeypatch.setattr(numba_cache, "announce_compilation", lambda func: calls.append(func))
    numba_cache.harden_numba_cache()

    class Missing:
        _py_func = staticmethod(assembled_path.follow_case)
        _enabled = False  # numba's own early return: no cached code

        @staticmethod
        def _guard_against_spurious_io_errors():
            import contextlib

            return contextlib.nullcontext()

    class Context:
        def refresh(self):
            pass

    assert caching.Cache.load_overload(Missing(), None, Context()) is None
    assert calls == [assembled_path.follow_case]
