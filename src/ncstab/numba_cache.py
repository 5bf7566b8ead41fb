"""numba's on-disk cache, made to treat a damaged entry as a miss.

numba keeps compiled machine code beside each generated module
(``__pycache__/*.nbi`` index, ``*.nbc`` data; :mod:`ncstab.generated_modules`).
A file damaged on disk (a bad sector, a copy cut short, a stray write) makes
numba raise ``UnpicklingError`` (or ``EOFError``, ...) where it reads the
entry, and every run that needs that function would fail.
:func:`harden_numba_cache` wraps numba's loading so that an entry that cannot
be read is a cache miss: the function is compiled again and its entry
rewritten (numba's own save replaces the index and the data).
"""

from __future__ import annotations

import functools
from typing import Any, Callable

__all__ = ["harden_numba_cache"]

_MARK = "_ncstab_damaged_entries_are_misses"


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
    caching.Cache.load_overload = _miss_on_error(caching.Cache.load_overload, lambda: None)
    setattr(caching, _MARK, True)
