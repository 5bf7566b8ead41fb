"""The motions of a study's dynamic stage on every core (issue 43).

A case's motion depends on its own path only, and integrating it (an adaptive Runge-Kutta
of scipy, the right-hand side in Python) holds the interpreter's lock: threads do not
share the work, processes do.  :func:`study_motions` splits each law's cases into
contiguous ranges, one per worker process (started by ``spawn``: nothing of this process's
threads is copied).  Each worker follows the paths of its range
(:func:`~ncstab.studies.chunked.chunk_path`: a case's path is the same in any batch) and
integrates their motions; the motions come back in order, so the Dataset is the one a
serial run gives, bit for bit (tests/test_motions_on_cores.py).

Processes are used when there are at least :data:`CASES_PER_WORKER` cases for each of
two or more workers (starting one costs 2-4 s: importing ncstab, loading the compiled
engine from its cache, following its cases' paths again).  Where they cannot start (a script run without an
``if __name__ == "__main__":`` guard, a platform without processes) the motions are
integrated here, in order: the same numbers, on one core.
"""

from __future__ import annotations

import concurrent.futures
import multiprocessing
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.result import PathResult
    from ncstab.studies.study import Study

__all__ = ["CASES_PER_WORKER", "study_motions"]

#: The fewest cases per worker for the motions to be spread over processes: starting a
#: worker costs about as much as 10 motions of Ziegler's pendulum over 40 time units
#: (benchmarks/bench_motions_on_cores.py: 32 motions 1.22x on 2 processes, 96 motions 1.75x).
CASES_PER_WORKER = 16


def _range_motions(study: Study, law: str | None, start: int, stop: int) -> list[Any]:
    """The motions of the cases ``start:stop`` of one law (run in a worker process)."""
    from ncstab.dynamics import follow_motions
    from ncstab.studies.chunked import chunk_path

    path = chunk_path(study, law, start, stop)
    return follow_motions(path, path.programme.dynamic)[0]


def worker_count(cases: int, workers: int) -> int:
    """How many processes share ``cases`` motions: 1 (here) unless each gets enough."""
    return max(1, min(workers, cases // CASES_PER_WORKER))


def study_motions(study: Study, path: PathResult, workers: int | None = None) -> list[list[Any]]:
    """Every case's motion (per law, per flat case; ``None`` where its path failed), on up to
    ``workers`` processes (default: the threads the run may use, :func:`~ncstab.paths.threads.thread_count`)."""
    from ncstab.dynamics import follow_motions
    from ncstab.paths.threads import thread_count

    stage = path.programme.dynamic
    size = path.grid.size
    count = worker_count(size, thread_count() if workers is None else workers)
    if count == 1:
        return follow_motions(path, stage)
    bounds = [size * k // count for k in range(count + 1)]
    try:
        context = multiprocessing.get_context("spawn")
        with concurrent.futures.ProcessPoolExecutor(count, mp_context=context) as pool:
            futures = [[pool.submit(_range_motions, study, law, a, b) for a, b in zip(bounds, bounds[1:])]
                       for law in (list(study.laws) or [None])]  # None: a system with its own laws
            return [[motion for future in per_law for motion in future.result()] for per_law in futures]
    except Exception:  # noqa: BLE001 - no processes here (or a study that does not pickle): in order,
        return follow_motions(path, stage)  # the same numbers; an error of the motions themselves recurs here
