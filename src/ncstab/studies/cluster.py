"""dask clusters for chunked runs: a local cluster or an existing scheduler, reached or refused.

:func:`cluster_client` gives a ``distributed.Client`` on a new local cluster
(``--workers``) or on an existing scheduler (``--scheduler``), after checking
the address (:func:`scheduler_address`) and that the scheduler answers within
a deadline; :func:`on_cluster` runs chunks on it, a bounded number in flight.
A cluster that cannot be reached, or is lost during the run, is a
:class:`~ncstab.studies.errors.ClusterError` (exit code 3), never a hang.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextlib
import logging
import multiprocessing
import re
import tempfile
from collections.abc import Callable, Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

from ncstab.studies.errors import ClusterError, SchedulerAddressError, write_error
from ncstab.studies.streaming import BlockLayout, EncodedChunk
from ncstab.studies.study import Study

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.studies.chunked import Chunk

__all__ = [
    "DEFAULT_SCHEDULER_TIMEOUT",
    "DISTRIBUTED_MISSING",
    "cluster_client",
    "distributed_module",
    "on_cluster",
    "scheduler_address",
]

#: Chunks in flight per worker on a dask cluster: one computing, one waiting
#: (bounds the memory of finished chunks not yet appended).
IN_FLIGHT_PER_WORKER = 2
#: Modules a local cluster's forkserver imports before starting workers (the last
#: one makes the workers ignore SIGINT: a Ctrl-C stops the run, which closes them).
WORKER_PRELOAD = ("distributed", "xarray", "ncstab.studies.chunked", "ncstab.studies.worker_process")
#: Seconds to wait for a dask scheduler to answer (``--scheduler-timeout``).
DEFAULT_SCHEDULER_TIMEOUT = 30.0
#: A scheduler address: [protocol://]host:port.
_ADDRESS = re.compile(
    r"(?:(?P<protocol>tcp|tls|ws|wss|ucx)://)?(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9](?:[A-Za-z0-9._-]*[A-Za-z0-9])?)"
    r":(?P<port>[0-9]{1,5})/?"
)
#: Message of the error raised when dask.distributed is needed but missing.
DISTRIBUTED_MISSING = (
    "running on a dask cluster (--workers / --scheduler) needs dask.distributed: "
    "pip install ncstab[distributed]"
)


def distributed_module() -> Any:
    """The ``distributed`` module, or an ImportError saying how to install it."""
    try:
        import distributed
    except ImportError as error:
        raise ImportError(DISTRIBUTED_MISSING) from error
    return distributed




def _worker_start_method() -> str:
    """How a local cluster starts its worker processes: ``forkserver`` where the
    platform has it, from a server that has imported ncstab once (its workers
    start with every module loaded: measured, about 2 s less per run on 2
    workers, and no import in each worker), else ``spawn``.

    The server is a fresh single-threaded process, so forking it is safe,
    unlike forking this one (``fork``).  If a forkserver is already running in
    this process it is used as it is.
    """
    if "forkserver" not in multiprocessing.get_all_start_methods():
        return "spawn"
    from multiprocessing import forkserver

    multiprocessing.get_context("forkserver").set_forkserver_preload(list(WORKER_PRELOAD))
    forkserver.ensure_running()
    return "forkserver"


def scheduler_address(address: str) -> str:
    """A dask scheduler address checked: ``[protocol://]host:port``, with ``tcp://`` when no protocol is given.

    Raises
    ------
    SchedulerAddressError
        Anything else (exit code 2: nothing is run).
    """
    match = _ADDRESS.fullmatch(str(address).strip())
    if match is None or not 1 <= int(match["port"]) <= 65535:
        raise SchedulerAddressError(
            f"--scheduler {address!r} is not a dask scheduler address: give PROTOCOL://HOST:PORT, "
            "e.g. tcp://127.0.0.1:8786"
        )
    return f"{match['protocol'] or 'tcp'}://{match['host']}:{int(match['port'])}"


def _reach_scheduler(address: str, timeout: float) -> None:
    """Connect to the scheduler and exchange dask's handshake within ``timeout`` seconds.

    ``distributed.Client`` bounds the connection but not the handshake, so a
    server that accepts connections and never answers would hang it: the
    handshake is tried here first, in a thread of its own, with a deadline.

    Raises
    ------
    ClusterError
        Nothing answered in time (exit code 3).
    """
    from distributed.comm import connect

    async def handshake() -> None:
        comm = await connect(address, timeout=timeout)
        await comm.close()

    with concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="ncstab-scheduler-probe") as pool:
        try:
            pool.submit(asyncio.run, asyncio.wait_for(handshake(), timeout + 1.0)).result()
        except (OSError, TimeoutError) as error:
            reason = "it does not answer" if isinstance(error, TimeoutError) else f"{error}"
            raise ClusterError(
                f"cannot reach the dask scheduler at {address} within {timeout:g} s: {reason}"
            ) from None


@contextlib.contextmanager
def cluster_client(workers: int | None, scheduler: str | None, timeout: float = DEFAULT_SCHEDULER_TIMEOUT) -> Iterator[Any]:
    """A dask.distributed Client: on a new local cluster of ``workers`` processes, or on ``scheduler``.

    Raises
    ------
    ClusterError
        The local cluster does not start, or the scheduler cannot be reached.
    """
    distributed = distributed_module()
    with contextlib.ExitStack() as stack:
        address: Any = scheduler
        if scheduler is None:
            # Workers' scratch space in a directory of its own, removed with the cluster.
            scratch = stack.enter_context(tempfile.TemporaryDirectory(prefix="ncstab-dask-"))
            import dask

            stack.enter_context(
                dask.config.set(
                    {
                        "temporary-directory": scratch,
                        "distributed.worker.multiprocessing-method": _worker_start_method(),
                        # The statistical profiler samples every worker's stack each 10 ms
                        # (for the dashboard): measured, about 10 % of a chunk's time.
                        "distributed.worker.profile.enabled": False,
                    }
                )
            )
            try:
                address = stack.enter_context(
                    distributed.LocalCluster(
                        n_workers=int(workers),  # type: ignore[arg-type]
                        threads_per_worker=1,
                        # the processes share the cores: one compiled-stepper thread each
                        env={"NUMBA_NUM_THREADS": "1"},
                        processes=True,
                        dashboard_address=":0",  # a free port: never "port 8787 is in use"
                        local_directory=scratch,
                        silence_logs=logging.CRITICAL,  # failures are raised here, not logged
                    )
                )
            except (OSError, RuntimeError, TimeoutError) as error:
                raise ClusterError(f"could not start a local dask cluster of {workers} workers: {error}") from None
        else:
            _reach_scheduler(scheduler, timeout)
        try:
            client = stack.enter_context(distributed.Client(address, timeout=timeout))
        except (OSError, TimeoutError) as error:
            raise ClusterError(f"cannot connect to the dask scheduler at {address}: {error}") from None
        yield client


def _cluster_failure(error: BaseException, future: Any, chunk: "Chunk", directory: FilePath) -> BaseException:
    """The error to raise for a chunk's future that did not give a result.

    The chunk's own error (raised on the worker: a write in the shared parts
    directory, a bug) is raised as such, a failed write as its named error;
    a cancelled or lost future, a dead worker, is the cluster lost.
    """
    if type(error).__name__ == "KilledWorker":
        return ClusterError(f"dask workers died while running chunk {chunk.file_name} (out of memory?)")
    if getattr(future, "status", None) == "error":
        return write_error(error, directory / chunk.file_name) or error
    return ClusterError(f"lost the dask cluster while running chunk {chunk.file_name} ({type(error).__name__})")


def on_cluster(
    client: Any, task: Callable[..., Any], study: Study, chunks: list["Chunk"], layout: BlockLayout,
    directory: FilePath, digest: str, shared: bool,
) -> Iterator[tuple["Chunk", EncodedChunk | None]]:
    """Run the chunks on a dask cluster, a bounded number in flight; yield each as it finishes.

    ``task(study, chunk, layout, directory or None, digest)`` runs a chunk on a
    worker (:func:`ncstab.studies.chunked.compute_part`); ``shared``: the
    workers see ``directory`` and write the parts themselves.
    """
    distributed = distributed_module()
    slots = max(1, IN_FLIGHT_PER_WORKER * sum(client.nthreads().values()))
    pending = iter(chunks)
    futures: dict[Any, Chunk] = {}
    where = str(directory) if shared else None

    def submit() -> Any:
        """Submit the next chunk; its future, or None when every chunk is submitted."""
        chunk = next(pending, None)
        if chunk is None:
            return None
        future = client.submit(task, study, chunk, layout, where, digest, pure=False)
        futures[future] = chunk
        return future

    queue = distributed.as_completed([f for f in (submit() for _ in range(slots)) if f is not None])
    for future in queue:
        chunk = futures.pop(future)
        following = submit()
        if following is not None:
            queue.add(following)
        try:
            result = future.result()
        except Exception as error:
            raise _cluster_failure(error, future, chunk, directory) from error
        future.release()
        del future
        yield chunk, result
        del result  # not held while the next chunk is awaited
