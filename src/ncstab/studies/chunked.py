"""Large sweeps: a study run in chunks of bounded size, streamed to its archive, resumable, on dask.

The cases of each law (flat, C order over the sweep, as in
:class:`ncstab.paths.api.ParameterGrid`) are split into chunks of at most
``chunk_cases`` cases.  Chunks are runs of whole blocks of the archive's layout
(:class:`~ncstab.studies.streaming.BlockLayout`), so that each HDF5 chunk of the
archive belongs to one chunk of cases.  Each chunk is followed and turned into
its own Dataset by :func:`run_chunk`, a pure function of ``(study, law, start,
stop)`` (so dask can ship it to a worker), compressed into the archive's HDF5
chunks (:func:`~ncstab.studies.streaming.encode_chunk`, on the worker), then

1. kept, atomically, as a part file ``<archive>.parts/<law>_<k>.npz`` (the
   compressed chunks, and a JSON header of names and attributes), so that a
   killed run keeps its finished chunks and ``resume=True`` computes only the
   missing ones;
2. copied at once into the archive being written
   (:class:`~ncstab.studies.streaming.ArchiveStream`, a temporary file in the
   parts directory).

When every chunk is in, the archive is closed and moved into place
(:func:`os.replace`), and the parts are removed.  The archive is identical
(after :func:`~ncstab.studies.open_study`, but for the ``created`` time stamp)
to the one the in-process run writes (:func:`~ncstab.studies.run_study` and
:func:`~ncstab.studies.write_dataset`): each case gets the same floating-point
operations whatever its batch.

Memory is bounded by the chunk size whatever the sweep size: the process holds
one chunk's Dataset at a time, and on dask at most two chunks per worker are in
flight.
"""

from __future__ import annotations

import contextlib
import gc
import hashlib
import json
import math
import multiprocessing
import os
import shutil
import tempfile
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.api import CaseRange, ParameterGrid, case_batch
from ncstab.paths.engine import follow_cases
from ncstab.paths.result import Path
from ncstab.studies.archive import atomic_destination, open_study
from ncstab.studies.run import study_dataset
from ncstab.studies.streaming import (
    BLOCK_CASES,
    ArchiveStream,
    BlockLayout,
    EncodedChunk,
    encode_chunk,
)
from ncstab.studies.study import Study
from ncstab.systems import SYSTEMS

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = [
    "DEFAULT_CHUNK_CASES",
    "Chunk",
    "ResumeError",
    "archive_layout",
    "default_chunk_cases",
    "parts_directory",
    "plan_chunks",
    "run_chunk",
    "run_study_chunked",
    "study_cases",
    "study_digest",
]

#: Cases per chunk when none is given (and the most a default chunk has on a
#: dask cluster): about 200 MB per chunk for a two-stage study of ~100 stored
#: states per case.  Measured on the 65,536-case diagram study: a case costs
#: 10-15 % less in chunks of 8,192 than of 4,096, and 1.7x more in chunks of 1,024
#: (the engine's per-step work is shared by the batch).
DEFAULT_CHUNK_CASES = 8192
#: Smallest default chunk on a dask cluster (smaller ones cost more in
#: per-chunk overhead than they gain in balance).
MIN_DEFAULT_CHUNK_CASES = 256
#: Chunks per worker a default chunk size aims at on a dask cluster (balance).
CHUNKS_PER_WORKER = 4
#: Chunks in flight per worker on a dask cluster: one computing, one waiting
#: (bounds the memory of finished chunks not yet appended).
IN_FLIGHT_PER_WORKER = 2
#: Version of the part-file layout (stored in the manifest).
PARTS_FORMAT = 3
#: Modules a local cluster's forkserver imports before starting workers.
WORKER_PRELOAD = ("distributed", "xarray", "ncstab.studies.chunked")
MANIFEST = "manifest.json"
#: The archive being written, inside the parts directory until it is complete.
ARCHIVE_IN_PROGRESS = "archive.nc.tmp"
#: Message of the error raised when dask.distributed is needed but missing.
DISTRIBUTED_MISSING = (
    "running on a dask cluster (--workers / --scheduler) needs dask.distributed: "
    "pip install ncstab[distributed]"
)


class ResumeError(ValueError):
    """The parts of an interrupted run do not belong to this study or chunking.

    Attributes
    ----------
    field
        What differs (``"study"``, ``"chunk_cases"``, ``"format"``, ``"part"``).
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field


@dataclass(frozen=True)
class Chunk:
    """Cases ``start:stop`` (flat, C order over the sweep) of the law ``law``."""

    law: str
    index: int
    start: int
    stop: int

    @property
    def file_name(self) -> str:
        """Part file name, ``<law>_<index>.npz``."""
        return f"{self.law}_{self.index:06d}.npz"

    @property
    def size(self) -> int:
        return self.stop - self.start


def archive_layout(study: Study, chunk_cases: int) -> BlockLayout:
    """The blocks of a chunked run's archive: at most :data:`~ncstab.studies.streaming.BLOCK_CASES`
    cases, and no more than ``chunk_cases``, so that chunks are made of whole blocks."""
    if int(chunk_cases) < 1:
        raise ValueError(f"chunk_cases must be at least 1, got {chunk_cases}")
    shape = ParameterGrid.from_mapping(study.parameters).shape
    return BlockLayout.for_grid(shape, min(BLOCK_CASES, int(chunk_cases)))


def plan_chunks(study: Study, chunk_cases: int) -> list[Chunk]:
    """The chunks of a study: each law's cases cut into runs of whole blocks
    (:func:`archive_layout`) of at most ``chunk_cases`` cases.

    Returns
    -------
    list of Chunk
        Law after law, cases in order; together they cover every case once.
    """
    runs = archive_layout(study, chunk_cases).runs(int(chunk_cases))
    return [Chunk(law, index, start, stop) for law in study.laws for index, (start, stop) in enumerate(runs)]


def study_digest(study: Study) -> str:
    """SHA-256 of the study text: parts are only ever combined for the same study."""
    return hashlib.sha256(study.text.encode("utf-8")).hexdigest()


def parts_directory(output: str | os.PathLike[str]) -> FilePath:
    """Where the parts of the archive ``output`` are kept while it is computed: ``<output>.parts``."""
    output = FilePath(output)
    return output.with_name(output.name + ".parts")


def _prepare_parts(directory: FilePath, study: Study, chunk_cases: int | None, resume: bool) -> int:
    """Create (or, on resume, check) the parts directory; the chunk size to use."""
    manifest_path = directory / MANIFEST
    if resume and manifest_path.exists():
        manifest = json.loads(manifest_path.read_text())
        if manifest.get("format") != PARTS_FORMAT:
            raise ResumeError("format", f"{directory}: parts of another ncstab version; remove the directory")
        if manifest.get("study_sha256") != study_digest(study):
            raise ResumeError(
                "study",
                f"{directory}: the parts belong to another version of study {manifest.get('study_name')!r}; "
                "run without --resume to start over",
            )
        if chunk_cases is not None and chunk_cases != manifest["chunk_cases"]:
            raise ResumeError(
                "chunk_cases",
                f"{directory}: the parts were written with chunk_cases = {manifest['chunk_cases']}, "
                f"not {chunk_cases}; resume with the same chunk size (or none)",
            )
        for stale in [*directory.glob(".*"), directory / ARCHIVE_IN_PROGRESS]:
            stale.unlink(missing_ok=True)  # temporaries of the killed run
        return int(manifest["chunk_cases"])
    chunk_cases = DEFAULT_CHUNK_CASES if chunk_cases is None else int(chunk_cases)
    if chunk_cases < 1:
        raise ValueError(f"chunk_cases must be at least 1, got {chunk_cases}")
    if directory.exists():
        shutil.rmtree(directory)
    directory.mkdir(parents=True)
    manifest = {
        "format": PARTS_FORMAT,
        "study_name": study.name,
        "study_sha256": study_digest(study),
        "chunk_cases": chunk_cases,
    }
    with atomic_destination(directory / MANIFEST, ".part") as temporary:
        temporary.write_text(json.dumps(manifest, indent=1))
    return chunk_cases


def _distributed() -> Any:
    """The ``distributed`` module, or an ImportError saying how to install it."""
    try:
        import distributed
    except ImportError as error:
        raise ImportError(DISTRIBUTED_MISSING) from error
    return distributed




def study_cases(study: Study) -> int:
    """Cases per law of a study (the size of its parameter grid)."""
    return ParameterGrid.from_mapping(study.parameters).size


def default_chunk_cases(study: Study, workers: int | None = None) -> int:
    """Chunk size when none is given.

    In process, :data:`DEFAULT_CHUNK_CASES`.  On ``workers`` dask workers,
    small enough to give each worker about :data:`CHUNKS_PER_WORKER` chunks
    (load balance: laws and parameter regions differ in cost), but at least
    :data:`MIN_DEFAULT_CHUNK_CASES` and at most :data:`DEFAULT_CHUNK_CASES`.
    """
    if not workers:
        return DEFAULT_CHUNK_CASES
    total = ParameterGrid.from_mapping(study.parameters).size * len(study.laws)
    balanced = math.ceil(total / (CHUNKS_PER_WORKER * int(workers)))
    return max(MIN_DEFAULT_CHUNK_CASES, min(DEFAULT_CHUNK_CASES, balanced))


def run_chunk(study: Study, law: str, start: int, stop: int) -> "xr.Dataset":
    """Follow the cases ``start:stop`` of one law of a study; their Dataset.

    A pure function of its arguments (picklable in and out), so that it runs
    alike in process and on a dask worker.  Each case is followed
    independently of the others in its batch, so a chunk gives exactly the
    numbers the whole-law batch gives for the same cases.

    Returns
    -------
    xarray.Dataset
        The study's Dataset (:func:`~ncstab.studies.run.study_dataset`) for
        these cases: dimension ``law`` of size 1, and ``case`` (flat indices
        ``start:stop``) in place of the swept parameters.
    """
    grid = CaseRange(ParameterGrid.from_mapping(study.parameters), start, stop)
    values = grid.case_values()
    definition = study.law_definition(law)
    batch = case_batch(definition, study.system, values, grid.size)
    result = follow_cases(batch, study.programme, values, study.options, study.system.secondary_contacts)
    system_class = SYSTEMS[study.system.name]
    path = Path(
        laws=(law,),
        grid=grid,  # type: ignore[arg-type]  # a ParameterGrid in all that Path uses
        system=study.system,
        programme=study.programme,
        options=study.options,
        results=(result,),
        dof_names=system_class.dof_names,  # type: ignore[attr-defined]
        force_names=system_class.force_names,  # type: ignore[attr-defined]
        study_text=study.text,
        definitions=(definition,),
    )
    return study_dataset(study, path)


def _json_attribute(value: Any) -> Any:
    if isinstance(value, np.ndarray):
        return {"__ndarray__": value.tolist(), "dtype": value.dtype.str}
    return value


def _attribute_from_json(value: Any) -> Any:
    if isinstance(value, dict) and "__ndarray__" in value:
        return np.asarray(value["__ndarray__"], dtype=value["dtype"])
    return value


def _write_part(directory: FilePath, chunk: Chunk, digest: str, encoded: EncodedChunk) -> None:
    """Keep an encoded chunk as ``directory/<law>_<k>.npz``, atomically.

    The compressed HDF5 chunks as one byte array, the text variables and the
    template's arrays as they are (no pickle); names, offsets, dimensions and
    attributes in a JSON header.  Parts are only ncstab's own scratch, read
    back by :func:`_read_part`.
    """
    template = encoded.template
    header = {
        "study_sha256": digest,
        "law": encoded.law,
        "start": encoded.start,
        "stop": encoded.stop,
        "steps": encoded.steps,
        "chunks": [[name, list(offset), len(data)] for name, offset, data in encoded.chunks],
        "strings": list(encoded.strings),
        "attrs": {k: _json_attribute(v) for k, v in template.attrs.items()},
        "variables": {
            name: {
                "dims": list(variable.dims),
                "attrs": {k: _json_attribute(v) for k, v in variable.attrs.items()},
                "coordinate": name in template.coords,
            }
            for name, variable in template.variables.items()
        },
    }
    arrays = {f"variable_{k}": variable.values for k, variable in enumerate(template.variables.values())}
    arrays.update({f"string_{k}": values for k, values in enumerate(encoded.strings.values())})
    blob = np.frombuffer(b"".join(data for _, _, data in encoded.chunks), dtype=np.uint8)
    with atomic_destination(directory / chunk.file_name, ".part") as temporary, open(temporary, "wb") as handle:
        np.savez(handle, header=np.array(json.dumps(header)), chunks=blob, **arrays)


def _read_part(directory: FilePath, chunk: Chunk, digest: str) -> EncodedChunk:
    import xarray as xr

    path = directory / chunk.file_name
    with np.load(path, allow_pickle=False) as stored:
        header = json.loads(str(stored["header"]))
        if header["study_sha256"] != digest:
            raise ResumeError("part", f"{path} belongs to another study")
        if (header["law"], header["start"], header["stop"]) != (chunk.law, chunk.start, chunk.stop):
            raise ResumeError(
                "part",
                f"{path} holds cases {header['start']}:{header['stop']} of {header['law']}, "
                f"expected {chunk.start}:{chunk.stop} of {chunk.law}",
            )
        variables = {
            name: xr.Variable(
                spec["dims"],
                stored[f"variable_{k}"],
                {key: _attribute_from_json(v) for key, v in spec["attrs"].items()},
            )
            for k, (name, spec) in enumerate(header["variables"].items())
        }
        strings = {name: stored[f"string_{k}"] for k, name in enumerate(header["strings"])}
        blob = stored["chunks"].tobytes()
    coordinates = {name: v for name, v in variables.items() if header["variables"][name]["coordinate"]}
    data = {name: v for name, v in variables.items() if name not in coordinates}
    attrs = {key: _attribute_from_json(v) for key, v in header["attrs"].items()}
    chunks = []
    position = 0
    for name, offset, length in header["chunks"]:
        chunks.append((name, tuple(offset), blob[position : position + length]))
        position += length
    return EncodedChunk(
        law=header["law"], start=header["start"], stop=header["stop"], steps=header["steps"],
        template=xr.Dataset(data, coords=coordinates, attrs=attrs),
        chunks=chunks, strings=strings,
    )


def encode_study_chunk(study: Study, chunk: Chunk, layout: BlockLayout, dataset: "xr.Dataset") -> EncodedChunk:
    """A chunk's Dataset (:func:`run_chunk`) compressed into the archive's HDF5 chunks."""
    sweep = tuple(ParameterGrid.from_mapping(study.parameters).sweep)
    return encode_chunk(dataset, chunk.law, chunk.start, chunk.stop, layout, sweep)


def compute_part(
    study: Study, chunk: Chunk, layout: BlockLayout, directory: str | None, digest: str
) -> EncodedChunk | None:
    """Run and encode a chunk; keep it as a part file in ``directory`` if given (returns None), else return it.

    On a local dask cluster the workers share the parts directory and write
    their parts themselves (nothing large travels back); on an existing
    cluster (``--scheduler``), which may not see the directory, the encoded
    chunk is returned and the client writes the part.
    """
    encoded = encode_study_chunk(study, chunk, layout, run_chunk(study, chunk.law, chunk.start, chunk.stop))
    if directory is None:
        return encoded
    _write_part(FilePath(directory), chunk, digest, encoded)
    return None


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


@contextlib.contextmanager
def _cluster_client(workers: int | None, scheduler: str | None) -> Iterator[Any]:
    """A dask.distributed Client: on a new local cluster of ``workers`` processes, or on ``scheduler``."""
    distributed = _distributed()
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
            address = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=int(workers),  # type: ignore[arg-type]
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",  # a free port: never "port 8787 is in use"
                    local_directory=scratch,
                )
            )
        yield stack.enter_context(distributed.Client(address))


def _on_cluster(
    client: Any, study: Study, chunks: list[Chunk], layout: BlockLayout, directory: FilePath, digest: str,
    shared: bool,
) -> Iterator[tuple[Chunk, EncodedChunk | None]]:
    """Run the chunks on a dask cluster, a bounded number in flight; yield each as it finishes."""
    distributed = _distributed()
    slots = max(1, IN_FLIGHT_PER_WORKER * sum(client.nthreads().values()))
    pending = iter(chunks)
    futures: dict[Any, Chunk] = {}
    where = str(directory) if shared else None

    def submit() -> Any:
        """Submit the next chunk; its future, or None when every chunk is submitted."""
        chunk = next(pending, None)
        if chunk is None:
            return None
        future = client.submit(compute_part, study, chunk, layout, where, digest, pure=False)
        futures[future] = chunk
        return future

    queue = distributed.as_completed([f for f in (submit() for _ in range(slots)) if f is not None])
    for future in queue:
        chunk = futures.pop(future)
        following = submit()
        if following is not None:
            queue.add(following)
        result = future.result()
        future.release()
        del future
        yield chunk, result
        del result  # not held while the next chunk is awaited


def run_study_chunked(
    study: Study,
    output: str | os.PathLike[str],
    chunk_cases: int | None = None,
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> FilePath:
    """Run a study in chunks, each kept on disk and appended to the archive as it finishes.

    The archive is identical (``xarray.testing.assert_identical`` after
    :func:`~ncstab.studies.open_study`, but for the ``created`` time stamp) to
    the one :func:`~ncstab.studies.run_study` and
    :func:`~ncstab.studies.write_dataset` give, and the memory used is bounded
    by the chunk size, not by the sweep.

    Parameters
    ----------
    study
        A validated study (:func:`~ncstab.studies.load_study`).
    output
        The archive to write (``.nc``); while it is computed, its chunks and
        the archive in progress are kept in ``<output>.parts``, removed at the end.
    chunk_cases
        At most this many cases per chunk (default :func:`default_chunk_cases`;
        on resume, the interrupted run's).
    resume
        Keep the parts an interrupted run of the same study left, and compute
        only the missing chunks.  Without it, leftover parts are discarded.
    workers
        Run the chunks on a local dask cluster of this many single-threaded
        worker processes (needs ``ncstab[distributed]``).
    scheduler
        Address of an existing dask.distributed scheduler to run the chunks on.
    progress
        Show a progress bar (cases of finished chunks / cases).

    Returns
    -------
    pathlib.Path
        The archive written (open it with :func:`~ncstab.studies.open_study`).

    Raises
    ------
    ResumeError
        ``resume`` with parts of another study or another chunk size.
    ImportError
        ``workers`` or ``scheduler`` given and dask.distributed not installed.
    """
    if workers is not None and scheduler is not None:
        raise ValueError("give workers (a local dask cluster) or scheduler (an existing one), not both")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if workers is not None or scheduler is not None:
        _distributed()
    output = FilePath(output)
    directory = parts_directory(output)
    digest = study_digest(study)
    if resume and not directory.exists() and output.exists():
        finished = open_study(output)
        if finished.attrs.get("study") == study.text:
            return output
    output.parent.mkdir(parents=True, exist_ok=True)
    if chunk_cases is None and not (resume and (directory / MANIFEST).exists()):
        chunk_cases = default_chunk_cases(study, workers)
    chunk_cases = _prepare_parts(directory, study, chunk_cases, resume)
    chunks = plan_chunks(study, chunk_cases)
    layout = archive_layout(study, chunk_cases)
    kept = [chunk for chunk in chunks if (directory / chunk.file_name).exists()]
    missing = [chunk for chunk in chunks if not (directory / chunk.file_name).exists()]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=sum(c.size for c in chunks), unit="case", desc="ncstab", leave=False)
    grid = ParameterGrid.from_mapping(study.parameters)
    archive = ArchiveStream(directory / ARCHIVE_IN_PROGRESS, tuple(study.laws), grid, layout)

    def append(chunk: Chunk, encoded: EncodedChunk) -> None:
        archive.append(encoded)
        # The chunk's objects include reference cycles (engine state, xarray
        # internals): free them now, not at the collector's next whim, so that
        # one chunk at a time is held.
        gc.collect()
        if bar is not None:
            bar.update(chunk.size)

    try:
        for chunk in kept:
            append(chunk, _read_part(directory, chunk, digest))  # (not held after the call)
        if workers is None and scheduler is None:
            for chunk in missing:
                encoded = encode_study_chunk(study, chunk, layout, run_chunk(study, chunk.law, chunk.start, chunk.stop))
                _write_part(directory, chunk, digest, encoded)
                append(chunk, encoded)
                del encoded  # one chunk held at a time: not this one while the next is computed
        elif missing:
            with _cluster_client(workers, scheduler) as client:
                shared = scheduler is None  # a local cluster sees the parts directory
                for chunk, encoded in _on_cluster(client, study, missing, layout, directory, digest, shared):
                    if encoded is None:
                        encoded = _read_part(directory, chunk, digest)
                    else:
                        _write_part(directory, chunk, digest, encoded)
                    append(chunk, encoded)
                    del encoded
        archive.close()
    except BaseException:
        archive.abort()
        (directory / ARCHIVE_IN_PROGRESS).unlink(missing_ok=True)
        raise
    finally:
        if bar is not None:
            bar.close()
    with atomic_destination(output, ".nc.tmp") as temporary:
        os.replace(directory / ARCHIVE_IN_PROGRESS, temporary)
    shutil.rmtree(directory)
    return output
