"""numba's on-disk cache, made to treat a damaged entry as a miss.

numba keeps compiled machine code beside each generated module
(``__pycache__/*.nbi`` index, ``*.nbc`` data; :mod:`ncstab.generated_modules`).
A file damaged on disk (a bad sector, a copy cut short, a stray write) makes
numba raise ``UnpicklingError`` (or ``EOFError``, ...) where it reads the
entry, and every run that needs that function would fail.
:func:`harden_numba_cache` wraps numba's loading so that an entry that cannot
be read is a cache miss: the function is compiled again and its entry
rewritten (numba's own save replaces the index and the data).

A miss of one of ncstab's own functions means compiling, which takes 40-90 s
a kind of model the first time on a machine (a small study runs its loop as plain
Python instead, :mod:`ncstab.paths.loop_route`): :func:`harden_numba_cache` also has the
first miss of a process say so on a terminal (:func:`announce_compilation`),
so that a new user does not wait in silence.
"""

from __future__ import annotations

import functools
import sys
from typing import Any, Callable

__all__ = ["announce_compilation", "harden_numba_cache"]

_MARK = "_ncstab_damaged_entries_are_misses"
#: What a terminal is told at the first compilation of a process.
COMPILING_NOTICE = ("ncstab: compiling the engine for this machine (once: 40-90 s a kind of model; "
                    "the machine code is kept in the cache, `ncstab cache` shows where)")
_announced = False


def announce_compilation(py_func: Any) -> bool:
    """Say on stderr, once a process and only on a terminal, that ncstab compiles its engine:
    ``py_func`` is a function numba found no cached code for.  Returns whether it said so."""
    global _announced
    module = str(getattr(py_func, "__module__", "") or "")
    stream = sys.stderr
    if _announced or not module.startswith("ncstab") or not getattr(stream, "isatty", lambda: False)():
        return False
    _announced = True
    print(COMPILING_NOTICE, file=stream, flush=True)
    return True


def _miss_on_error(method: Callable[..., Any], miss: Callable[[], Any]) -> Callable[..., Any]:
    @functools.wraps(method)
    def guarded(*args: Any, **kwargs: Any) -> Any:
        try:
            return method(*args, **kwargs)
        except Exception:  # noqa: BLE001 - any entry that cannot be read back is compiled again
            return miss()

    return guarded


def harden_numba_cache() -> None:
    """Make numba treat an index or data file that cannot be read as a cache miss (idempotent).

    Wrapped: ``IndexDataCacheFile._load_index`` (a damaged ``.nbi`` is an
    empty index: the next save writes a new one), ``IndexDataCacheFile.load``
    and ``Cache.load_overload`` (a damaged ``.nbc``, or data that cannot be
    rebuilt, is no cached code).
    """
    from numba.core import caching

    if getattr(caching, _MARK, False):
        return
    index_file = caching.IndexDataCacheFile
    index_file._load_index = _miss_on_error(index_file._load_index, dict)
    index_file.load = _miss_on_error(index_file.load, lambda: None)
    load_overload = _miss_on_error(caching.Cache.load_overload, lambda: None)

    @functools.wraps(load_overload)
    def announced(self: Any, *args: Any, **kwargs: Any) -> Any:
        data = load_overload(self, *args, **kwargs)
        if data is None:  # a miss: numba compiles next
            announce_compilation(getattr(self, "_py_func", None))
        return data

    caching.Cache.load_overload = announced
    setattr(caching, _MARK, True)
