"""How many threads the compiled stepper runs a study's cases on.

The compiled stepper (:mod:`ncstab.paths.compiled_stages`) shares the cases
of a stage out over threads that run the compiled loop without the GIL: every
core by default, fewer where ``NUMBA_NUM_THREADS`` (numba's convention, read
once, when numba starts) or :func:`using_threads` (``ncstab run --threads
N``) says so.  A case's arithmetic does not depend on
the thread that runs it, so results are bit for bit the same whatever the
count.  The workers of a local dask cluster run one thread each
(:mod:`ncstab.studies.cluster`): there the processes share the cores.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator
from concurrent.futures import Executor, Future, ThreadPoolExecutor
from contextlib import contextmanager
from typing import Any

__all__ = ["check_thread_count", "side_thread", "thread_count", "thread_limit", "using_threads"]

#: The count chosen by :func:`using_threads`, per calling thread.
_CHOSEN = threading.local()


def thread_limit() -> int:
    """The most threads numba can run: ``NUMBA_NUM_THREADS`` if set, else the number of cores."""
    import numba

    return int(numba.config.NUMBA_NUM_THREADS)


def check_thread_count(count: int) -> int:
    """``count`` if it is a thread count numba can run, else a ValueError saying why.

    Parameters
    ----------
    count
        Threads asked for (``--threads``).
    """
    if isinstance(count, bool) or not isinstance(count, int) or count < 1:
        raise ValueError(f"--threads must be a positive whole number, got {count!r}")
    limit = thread_limit()
    if count > limit:
        raise ValueError(
            f"--threads {count} is more than the {limit} threads numba started with "
            "(the number of cores, or NUMBA_NUM_THREADS if set)"
        )
    return count


def thread_count() -> int:
    """Threads the compiled stepper runs a stage's cases on, when called from this
    thread: the count of the innermost :func:`using_threads`, else :func:`thread_limit`."""
    count = getattr(_CHOSEN, "count", None)
    return thread_limit() if count is None else count


@contextmanager
def using_threads(count: int | None) -> Iterator[None]:
    """Within the block, the compiled stepper of this thread runs on ``count`` threads
    (``None``: the current count, unchanged).

    Raises
    ------
    ValueError
        When ``count`` is not between 1 and :func:`thread_limit`.
    """
    if count is None:
        yield
        return
    check_thread_count(count)
    previous = getattr(_CHOSEN, "count", None)
    _CHOSEN.count = count
    try:
        yield
    finally:
        _CHOSEN.count = previous


class _Inline(Executor):
    """An executor that runs what it is given at once, in the calling thread."""

    def submit(self, function: Callable[..., Any], /, *args: Any, **kwargs: Any) -> Future:
        done: Future = Future()
        done.set_result(function(*args, **kwargs))
        return done


def side_thread() -> Executor:
    """One more thread for work beside the calling thread's (numpy releases the GIL in
    its loops), where :func:`thread_count` allows two; else an executor that runs the
    work at once in the calling thread.  Use it as a context manager."""
    return ThreadPoolExecutor(1, thread_name_prefix="ncstab-side") if thread_count() > 1 else _Inline()
