"""Where numba keeps the compiled stage loop's machine code: ncstab's cache folder, named by the engine's sources.

The stage loop is plain modules of compiled functions (:mod:`ncstab.paths.loop_cases`
and the modules it calls).  Its three entry points (:data:`ENTRY_POINTS`) are
compiled with ``cache=True``, which compiles everything they call into their
machine code.  numba would keep that code beside the entry point's own file and
take it as fresh while that one file is unchanged; but the code also holds
every module the loop calls.  :class:`EngineCacheLocator` (registered by
:func:`register_engine_cache`, before the entry points are decorated) keeps it
instead in the folder ``compiled/engine_<digest>`` of ncstab's cache root
(:mod:`ncstab.cache`), where ``<digest>`` hashes the text of every module the
loop is built from (:data:`ENGINE_MODULES`) and the numba and numpy versions:
a change to any of them is a new folder, compiled anew; ``ncstab cache clear``
removes them all.  Where the cache folder cannot be written, a temporary folder
serves this process only.
"""

from __future__ import annotations

import functools
import hashlib
import tempfile
from pathlib import Path
from typing import Any

from ncstab.plain_python import PLAIN_IMPORTS

__all__ = ["ENGINE_MODULES", "ENTRY_POINTS", "engine_digest", "engine_folder", "register_engine_cache"]

#: The modules the loop's machine code is built from: its compiled functions'
#: (:data:`ncstab.plain_python.PLAIN_IMPORTS`) and those whose records and constants
#: they read (numba freezes a module's globals into the machine code).
ENGINE_MODULES = (
    *PLAIN_IMPORTS, "ncstab.paths.compiled", "ncstab.paths.loop_records", "ncstab.paths.events",
    "ncstab.paths.contacts", "ncstab.paths.domain_edge", "ncstab.paths.over_steps",
)

#: The loop's entry points (module, name): the functions compiled with ``cache=True``.
ENTRY_POINTS = frozenset({
    ("ncstab.paths.loop_cases", "run_cases"), ("ncstab.paths.loop_start", "start"),
    ("ncstab.paths.loop_start", "settle"),
})

_SOURCE_ROOT = Path(__file__).resolve().parent.parent


@functools.cache
def engine_digest() -> str:
    """A hash of the text of :data:`ENGINE_MODULES` and of the numba and numpy versions."""
    import numba
    import numpy as np

    digest = hashlib.sha256(f"{numba.__version__} {np.__version__}".encode())
    for name in ENGINE_MODULES:
        digest.update((_SOURCE_ROOT / (name.replace(".", "/") + ".py")).read_bytes())
    return digest.hexdigest()[:20]


@functools.cache
def engine_folder() -> Path:
    """The folder of the loop's machine code (created): ``<cache root>/compiled/engine_<digest>``,
    or a temporary folder where the cache cannot be written."""
    from ncstab.cache import cache_directory
    from ncstab.generated_modules import CACHE_KIND

    try:
        folder = cache_directory(CACHE_KIND) / f"engine_{engine_digest()}"
        folder.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=folder).close()
    except OSError:  # a read-only home, say
        folder = Path(tempfile.mkdtemp(prefix="ncstab-engine-"))
    return folder


def register_engine_cache() -> None:
    """Have numba keep the machine code of :data:`ENTRY_POINTS` in :func:`engine_folder`
    (idempotent; before the entry points are decorated, as numba picks a function's
    cache folder then)."""
    from numba.core import caching

    from ncstab.numba_cache import harden_numba_cache

    harden_numba_cache()
    implementation = getattr(caching, "CacheImpl", None) or caching._CacheImpl  # (numba < 0.61: private)
    if any(getattr(locator, "ncstab_engine", False) for locator in implementation._locator_classes):
        return

    class EngineCacheLocator(caching._CacheLocator):
        """numba's locator of the loop's entry points (see the module docstring)."""

        ncstab_engine = True

        def __init__(self, py_func: Any, py_file: str) -> None:
            self._py_file = py_file
            self._lineno = py_func.__code__.co_firstlineno

        def get_cache_path(self) -> str:
            return str(engine_folder())

        def get_source_stamp(self) -> str:
            return engine_digest()

        def get_disambiguator(self) -> str:
            return str(self._lineno)

        @classmethod
        def from_function(cls, py_func: Any, py_file: str) -> EngineCacheLocator | None:
            if (py_func.__module__, py_func.__qualname__) not in ENTRY_POINTS:
                return None
            return cls(py_func, py_file)

    implementation._locator_classes.insert(0, EngineCacheLocator)
