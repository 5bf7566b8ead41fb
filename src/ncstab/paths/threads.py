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

import os
import threading
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ThreadPoolExecutor
from contextlib import contextmanager
from itertools import pairwise
from typing import Any

__all__ = ["check_thread_count", "in_shares", "side_by_side", "thread_count", "thread_limit", "using_threads"]

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


def in_shares(work: Callable[[slice], Any], bounds: Sequence[int], name: str) -> None:
    """``work(slice(a, b))`` for each pair of consecutive ``bounds``, on up to
    :func:`thread_count` threads (in the calling thread where one thread, or one
    share, is all there is).  The shares must write apart (numpy releases the GIL in
    its loops, so they run side by side); how they are dealt does not change what
    each one computes.

    Parameters
    ----------
    work
        Called once per share with its slice.
    bounds
        Increasing share boundaries, first to last (``[0, ..., size]``).
    name
        What the threads do, for profilers and debuggers (:func:`side_by_side`).
    """
    shares = [slice(int(a), int(b)) for a, b in pairwise(bounds) if b > a]
    threads = min(thread_count(), len(shares))
    if threads <= 1:
        for share in shares:
            work(share)
        return
    dealt = [shares[t::threads] for t in range(threads)]
    side_by_side([lambda mine=mine: [work(share) for share in mine] for mine in dealt], name)


#: ncstab's threads beside the calling one (:func:`side_by_side`), started once a process.
_POOL: ThreadPoolExecutor | None = None
_POOL_LOCK = threading.Lock()


def _forget_pool() -> None:
    """In a forked child: the parent's threads are not there, so start new ones when asked."""
    global _POOL
    _POOL = None


os.register_at_fork(after_in_child=_forget_pool)


def _pool() -> ThreadPoolExecutor:
    global _POOL
    with _POOL_LOCK:
        if _POOL is None:
            _POOL = ThreadPoolExecutor(max(1, thread_limit() - 1), thread_name_prefix="ncstab")
        return _POOL


#: Set in ncstab's threads while they run a task (:func:`side_by_side` runs nested calls inline).
_IN_POOL = threading.local()


def _named(task: Callable[[], Any], name: str) -> Any:
    threading.current_thread().name = f"ncstab-{name}"
    _IN_POOL.active = True
    try:
        return task()
    finally:
        _IN_POOL.active = False


def side_by_side(tasks: Sequence[Callable[[], Any]], name: str) -> None:
    """Run ``tasks`` at once: the first in the calling thread, the others on ncstab's
    threads (started once a process, not once a call: starting them cost 4 ms of a
    0.12 s study of 4,096 cases).  Returns when all are done; raises the first error.
    Called from one of those threads (a task that shares its own work out), it runs the
    tasks there, one after the other: waiting on the threads it holds could hang.

    Parameters
    ----------
    tasks
        Functions of no argument, writing apart.
    name
        What the threads do: they are named ``ncstab-<name>`` while they do it.
    """
    if getattr(_IN_POOL, "active", False):  # called from one of ncstab's threads: waiting on them could hang
        for task in tasks:
            task()
        return
    futures = [_pool().submit(_named, task, name) for task in tasks[1:]]
    try:
        if tasks:
            tasks[0]()
    finally:
        for future in futures:
            future.result()
