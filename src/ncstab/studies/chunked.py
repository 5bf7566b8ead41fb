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

A run holds the output's lock (:func:`~ncstab.studies.outputs.claim_output`)
from start to end; it never discards the finished parts of an earlier run
unless asked (``resume`` keeps them, ``overwrite`` discards them).  What stops
a run is a named error (:mod:`ncstab.studies.errors`) saying what is kept:
a full disk, an unreachable or lost cluster, an interrupt.
"""

from __future__ import annotations

import contextlib
import gc
import os
import shutil
from collections.abc import Callable
from pathlib import Path as FilePath
from typing import TYPE_CHECKING

from ncstab.paths.api import CaseRange, ParameterGrid, case_batch
from ncstab.paths.stepper import follow_cases
from ncstab.paths.result import PathResult
from ncstab.paths.programme import EVENTS
from ncstab.studies.archive import open_study
from ncstab.studies.atomic_files import atomic_destination
from ncstab.studies.archive_selection import archive_selection
from ncstab.studies.chunk_plan import (
    DEFAULT_CHUNK_CASES,
    Chunk,
    archive_layout,
    default_chunk_cases,
    plan_chunks,
    study_cases,
)
from ncstab.studies.cluster import (
    DEFAULT_SCHEDULER_TIMEOUT,
    DISTRIBUTED_MISSING,
    cluster_client,
    distributed_module,
    on_cluster,
    scheduler_address,
)
from ncstab.studies.errors import ArchiveError, ResumeError, RunError, RunInterrupted
from ncstab.studies.outputs import ARCHIVE_IN_PROGRESS, claim_output, finished_parts, parts_directory
from ncstab.studies.parts import (
    MANIFEST,
    PARTS_FORMAT,
    DamagedPart,
    create_parts,
    read_kept_part,
    read_part,
    resumed_chunk_size,
    study_digest,
    write_part,
    writing,
)
from ncstab.studies.run import study_dataset
from ncstab.studies.streaming import (
    ArchiveStream,
    BlockLayout,
    EncodedChunk,
    encode_chunk,
)
from ncstab.studies.study import Study
from ncstab.systems.assembled import is_assembled

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.assembled_result import AssembledPathResult

__all__ = [
    "DEFAULT_CHUNK_CASES",
    "DEFAULT_SCHEDULER_TIMEOUT",
    "DISTRIBUTED_MISSING",
    "MANIFEST",
    "PARTS_FORMAT",
    "Chunk",
    "ResumeError",
    "archive_layout",
    "chunk_path",
    "default_chunk_cases",
    "parts_directory",
    "plan_chunks",
    "run_chunk",
    "run_study_chunked",
    "scheduler_address",
    "study_cases",
    "study_digest",
]

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
    return study_dataset(study, chunk_path(study, law, start, stop))


def chunk_path(study: Study, law: str | None, start: int, stop: int) -> "PathResult | AssembledPathResult":
    """The followed paths of the cases ``start:stop`` of one law (``None``: a system with its own
    laws) (grid: a :class:`CaseRange`), on the engine an in-process run chooses for the system:
    the sparse engine for an assembled system
    (:func:`~ncstab.paths.assembled_result.follow_assembled`), else the compiled batch."""
    whole = ParameterGrid.from_mapping(study.parameters)
    grid = CaseRange(whole, start, stop)
    values = grid.case_values()
    model = study.model(law)
    if is_assembled(model.definition):
        from ncstab.paths.assembled_result import follow_assembled

        return follow_assembled(model, study.programme, grid, values, study.options, study.text)
    batch = case_batch(model.laws[0], model, values, grid.size)
    result = follow_cases(batch, study.programme, values, study.options, model.secondary_contacts,
                          study_cases=whole.size)
    return PathResult(
        model=model,
        grid=grid,
        programme=study.programme,
        options=study.options,
        results=(result,),
        study_text=study.text,
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
    write_part(FilePath(directory), chunk, digest, encoded)
    return None


def _kept(output: FilePath, chunks: list[Chunk]) -> str:
    """What an interrupted run leaves for the next one, in words."""
    done = len(finished_parts(output))
    if done == 0:
        return "no chunk was finished"
    return f"{done} of {len(chunks)} chunks kept in {parts_directory(output)}: rerun with --resume to compute the rest"


def run_study_chunked(
    study: Study,
    output: str | os.PathLike[str],
    chunk_cases: int | None = None,
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
    overwrite: bool = False,
    scheduler_timeout: float = DEFAULT_SCHEDULER_TIMEOUT,
    notify: Callable[[str], None] | None = None,
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
        the archive in progress are kept in ``<output>.parts``, removed at the
        end, and the run holds the lock ``<output>.lock``.
    chunk_cases
        At most this many cases per chunk (default :func:`default_chunk_cases`;
        on resume, the interrupted run's).
    resume
        Keep the parts an interrupted run of the same study left, and compute
        only the missing chunks (a damaged part is computed again).
    workers
        Run the chunks on a local dask cluster of this many single-threaded
        worker processes (needs ``ncstab[distributed]``).
    scheduler
        Address of an existing dask.distributed scheduler to run the chunks on.
    progress
        Show a progress bar (cases of finished chunks / cases).
    overwrite
        Discard the finished parts of an earlier run and start over.  Without
        it (or ``resume``), finished parts are never deleted: the run is refused.
    scheduler_timeout
        Seconds to wait for the scheduler to answer.
    notify
        Called with a line when a stale lock is taken over, temporaries of a
        killed run are removed, or a damaged part is computed again.

    Returns
    -------
    pathlib.Path
        The archive written (open it with :func:`~ncstab.studies.open_study`).

    Raises
    ------
    ResumeError
        ``resume`` with parts of another study or another chunk size.
    PartsExistError
        Finished parts on disk, and neither ``resume`` nor ``overwrite``.
    OutputLockedError
        Another run holds the output's lock.
    SchedulerAddressError, ClusterError
        ``scheduler`` is not an address, or the cluster cannot be reached or is lost.
    DiskFullError, OutputNotWritableError, WriteError
        A write failed (what was kept is in the error's ``kept``).
    RunInterrupted
        SIGINT or SIGTERM (a ``KeyboardInterrupt``), with what was kept.
    ImportError
        ``workers`` or ``scheduler`` given and dask.distributed not installed.
    """
    if workers is not None and scheduler is not None:
        raise ValueError("give workers (a local dask cluster) or scheduler (an existing one), not both")
    if workers is not None and int(workers) < 1:
        raise ValueError(f"workers must be at least 1, got {workers}")
    if chunk_cases is not None and int(chunk_cases) < 1:
        raise ValueError(f"chunk_cases must be at least 1, got {chunk_cases}")
    if scheduler is not None:
        scheduler = scheduler_address(scheduler)
    if workers is not None or scheduler is not None:
        distributed_module()
    output = FilePath(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    with claim_output(output, resume=resume, overwrite=overwrite, notify=notify):
        directory = parts_directory(output)
        if resume and not directory.exists() and output.exists():
            try:
                if open_study(output).attrs.get("study") == study.text:
                    return output  # already complete
            except ArchiveError:
                pass  # a damaged archive: computed again
        stored = resumed_chunk_size(directory, study, chunk_cases) if resume else None
        if stored is None:
            chunk_cases = default_chunk_cases(study, workers) if chunk_cases is None else int(chunk_cases)
        else:
            chunk_cases = stored
        chunks = plan_chunks(study, chunk_cases)
        try:
            _run_chunks(study, output, chunks, chunk_cases, stored is not None, workers, scheduler,
                        scheduler_timeout, progress, notify)
        except RunError as error:
            error.kept = error.kept or _kept(output, chunks)
            raise
        except RunInterrupted as interrupt:
            interrupt.kept = interrupt.kept or _kept(output, chunks)
            raise
        except KeyboardInterrupt:
            raise RunInterrupted("SIGINT", _kept(output, chunks)) from None
    return output


def _run_chunks(
    study: Study, output: FilePath, chunks: list[Chunk], chunk_cases: int, resuming: bool, workers: int | None,
    scheduler: str | None, scheduler_timeout: float, progress: bool, notify: Callable[[str], None] | None,
) -> None:
    """The body of :func:`run_study_chunked`, once the output is claimed and the chunks planned."""
    directory = parts_directory(output)
    digest = study_digest(study)
    layout = archive_layout(study, chunk_cases)
    kept = [chunk for chunk in chunks if resuming and (directory / chunk.file_name).exists()]
    missing = [chunk for chunk in chunks if chunk not in kept]
    wanted = workers is not None or scheduler is not None  # a cluster, when some chunk is missing
    with contextlib.ExitStack() as stack:
        # The cluster first: if it cannot be reached, nothing is written.
        client = (
            stack.enter_context(cluster_client(workers, scheduler, scheduler_timeout)) if missing and wanted else None
        )
        if not resuming:
            with writing(directory):
                create_parts(directory, study, chunk_cases)
        bar = None
        if progress:
            from tqdm.auto import tqdm

            bar = stack.enter_context(tqdm(total=sum(c.size for c in chunks), unit="case", desc="ncstab", leave=False))
        grid = ParameterGrid.from_mapping(study.parameters)
        selection = archive_selection(study)
        held = [e for e in EVENTS if e not in selection.needed_events] if selection.leave_out_unseen_events else []
        archive = ArchiveStream(directory / ARCHIVE_IN_PROGRESS, tuple(study.laws), grid, layout, tuple(held))

        def append(chunk: Chunk, encoded: EncodedChunk) -> None:
            with writing(directory / ARCHIVE_IN_PROGRESS):
                archive.append(encoded)
            # The chunk's objects include reference cycles (engine state, xarray
            # internals): free them now, not at the collector's next whim, so that
            # one chunk at a time is held.
            gc.collect()
            if bar is not None:
                bar.update(chunk.size)

        def keep(chunk: Chunk, encoded: EncodedChunk) -> None:
            with writing(directory / chunk.file_name):
                write_part(directory, chunk, digest, encoded)

        try:
            damaged = []
            for chunk in kept:
                try:
                    append(chunk, read_kept_part(directory, chunk, digest))  # (not held after the call)
                except DamagedPart as error:
                    (directory / chunk.file_name).unlink(missing_ok=True)
                    damaged.append(str(error).split(":")[0])
                    missing.append(chunk)
            if damaged and notify is not None:
                notify(f"{len(damaged)} kept chunk(s) could not be read back ({damaged[0]}...): computing them again")
            if client is None:
                for chunk in missing:
                    encoded = encode_study_chunk(study, chunk, layout, run_chunk(study, chunk.law, chunk.start, chunk.stop))
                    keep(chunk, encoded)
                    append(chunk, encoded)
                    del encoded  # one chunk held at a time: not this one while the next is computed
            else:
                shared = scheduler is None  # a local cluster sees the parts directory
                for chunk, encoded in on_cluster(client, compute_part, study, missing, layout, directory, digest, shared):
                    if encoded is None:
                        encoded = read_part(directory, chunk, digest)
                    else:
                        keep(chunk, encoded)
                    append(chunk, encoded)
                    del encoded
            with writing(directory / ARCHIVE_IN_PROGRESS):
                archive.close()
        except BaseException:
            archive.abort()
            (directory / ARCHIVE_IN_PROGRESS).unlink(missing_ok=True)
            raise
    with writing(output):
        with atomic_destination(output, ".tmp") as temporary:
            os.replace(directory / ARCHIVE_IN_PROGRESS, temporary)
    shutil.rmtree(directory)
