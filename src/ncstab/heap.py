"""What the garbage collector scans while a command draws: the objects of its imports kept out.

By the time ``ncstab run`` or ``ncstab plot`` draws its figures, the process
holds some 140,000 objects that live until it ends: the modules, classes and
functions of numpy, xarray, matplotlib, scipy and ncstab.  Drawing allocates
many short-lived objects (matplotlib's artists, transforms, texts), and each
full collection that this triggers scans every one of the long-lived objects
too: a fifth of the drawing time of a figure (measured on 4,096-case archives,
2.6 s for two figures, 2.1 s with those objects frozen).  :func:`settle`
moves the objects alive at that moment into the collector's permanent
generation (:func:`gc.freeze`, the practice its documentation recommends),
which collections no longer scan; :func:`settled_heap` around a command
gives them back to the collector when the command ends (:func:`gc.unfreeze`),
so a process that runs several commands (a test session) frees what each
left behind.

Only the standard library is imported here (``ncstab --version`` stays fast).
"""

from __future__ import annotations

import contextlib
import gc
from collections.abc import Iterator

__all__ = ["settle", "settled_heap"]

_depth = 0  # settled_heap contexts open: settle() freezes only inside one


@contextlib.contextmanager
def settled_heap() -> Iterator[None]:
    """The span of a command: what :func:`settle` froze inside it is unfrozen at its end."""
    global _depth
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if _depth == 0:
            gc.unfreeze()


def settle() -> None:
    """Freeze the objects alive now (:func:`gc.freeze`), inside :func:`settled_heap` only.

    Called by a command after its heavy imports, before it draws.  Outside a
    :func:`settled_heap` (ncstab used as a library) it does nothing: the
    caller's process keeps its collector as it was.
    """
    if _depth > 0:
        gc.freeze()
