"""Large sweeps: a study run in chunks of bounded size, resumable, optionally on dask.

The cases of each law (flat, C order over the sweep, as in
:class:`ncstab.paths.api.ParameterGrid`) are split into chunks of at most
``chunk_cases`` cases.  Each chunk is followed by :func:`run_chunk`, a pure
function of ``(study, law, start, stop)`` (so dask can ship it to a worker),
and written atomically, as soon as it finishes, to a part file
``<archive>.parts/<law>_<k>.npz``.  A killed run keeps the finished parts;
``resume=True`` computes only the missing ones.  When every part exists, the
per-law :class:`~ncstab.paths.engine.CaseResult` objects are rebuilt from the
parts and the archive is assembled by the same code as the in-process run
(:meth:`ncstab.paths.Path.to_dataset`), written with
:func:`~ncstab.studies.write_dataset` (atomic), and the parts are removed.

Memory: computing is bounded by the chunk size (one chunk per worker at a
time); the final assembly loads every part, so it needs the memory of the
whole archive (as the in-process run does).
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.api import ParameterGrid, case_batch
from ncstab.paths.engine import CaseResult, follow_cases
from ncstab.paths.result import Path
from ncstab.studies.archive import atomic_destination, open_study, write_dataset
from ncstab.studies.run import study_dataset
from ncstab.studies.study import Study
from ncstab.systems import SYSTEMS

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = [
    "DEFAULT_CHUNK_CASES",
    "Chunk",
    "ResumeError",
    "parts_directory",
    "plan_chunks",
    "run_chunk",
    "run_study_chunked",
    "study_digest",
]

#: Cases per chunk when none is given: a few tens of MB of states per chunk.
DEFAULT_CHUNK_CASES = 4096
#: Version of the part-file layout (stored in the manifest).
PARTS_FORMAT = 1
MANIFEST = "manifest.json"
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


def plan_chunks(study: Study, chunk_cases: int) -> list[Chunk]:
    """The chunks of a study: each law's cases cut into runs of at most ``chunk_cases``.

    Returns
    -------
    list of Chunk
        Law after law, cases in order; together they cover every case once.
    """
    if int(chunk_cases) < 1:
        raise ValueError(f"chunk_cases must be at least 1, got {chunk_cases}")
    size = ParameterGrid.from_mapping(study.parameters).size
    chunks = []
    for law in study.laws:
        for index, start in enumerate(range(0, size, int(chunk_cases))):
            chunks.append(Chunk(law, index, start, min(start + int(chunk_cases), size)))
    return chunks


def _chunk_values(grid: ParameterGrid, start: int, stop: int) -> dict[str, np.ndarray]:
    """``ParameterGrid.case_values()[name][start:stop]`` without building the whole grid."""
    size = stop - start
    values: dict[str, np.ndarray] = {}
    if grid.sweep:
        positions = np.unravel_index(np.arange(start, stop), grid.shape)
        values.update({name: sweep[k] for (name, sweep), k in zip(grid.sweep.items(), positions)})
    values.update({name: np.full(size, value) for name, value in grid.fixed.items()})
    return values


def _flatten(result: CaseResult) -> dict[str, np.ndarray]:
    """A CaseResult as ``"group/key" -> array`` (an ``.npz`` holds no nested dicts)."""
    flat = {"n_steps": result.n_steps, "status": result.status, "message": result.message}
    flat.update({f"steps/{k}": v for k, v in result.steps.items()})
    flat.update({f"counters/{k}": v for k, v in result.counters.items()})
    flat.update({f"cycles/{k}": v for k, v in result.cycles.items()})
    for event, table in result.events.items():
        flat.update({f"events/{event}/{k}": v for k, v in table.items()})
    return flat


def _unflatten(flat: dict[str, np.ndarray]) -> CaseResult:
    groups: dict[str, dict[str, np.ndarray]] = {"steps": {}, "counters": {}, "cycles": {}}
    events: dict[str, dict[str, np.ndarray]] = {}
    for key, value in flat.items():
        parts = key.split("/")
        if parts[0] == "events":
            events.setdefault(parts[1], {})[parts[2]] = value
        elif parts[0] in groups:
            groups[parts[0]][parts[1]] = value
    return CaseResult(
        steps=groups["steps"],
        n_steps=flat["n_steps"],
        status=flat["status"],
        message=flat["message"],
        events=events,
        counters=groups["counters"],
        cycles=groups["cycles"],
    )


def run_chunk(study: Study, law: str, start: int, stop: int) -> dict[str, np.ndarray]:
    """Follow the cases ``start:stop`` of one law of a study.

    A pure function of its arguments (picklable in and out), so that it runs
    alike in process and on a dask worker.  Each case is followed
    independently of the others in its batch, so a chunk gives exactly the
    numbers the whole-law batch gives for the same cases.

    Returns
    -------
    dict of numpy.ndarray
        The :class:`~ncstab.paths.engine.CaseResult` of the chunk, flattened to
        ``"group/key" -> array`` (``steps`` arrays ``(stop - start, n_steps_max, ...)``).
    """
    grid = ParameterGrid.from_mapping(study.parameters)
    values = _chunk_values(grid, start, stop)
    batch = case_batch(law, study.system, values, stop - start)
    result = follow_cases(batch, study.programme, values, study.options, study.system.secondary_contacts)
    return _flatten(result)


def _pad_steps(array: np.ndarray, length: int) -> np.ndarray:
    """Pad the step axis (1) to ``length`` as the engine does: -1 for integers, NaN otherwise."""
    pad = length - array.shape[1]
    if not pad:
        return array
    fill = -1 if array.dtype.kind == "i" else np.nan
    return np.concatenate([array, np.full((array.shape[0], pad) + array.shape[2:], fill, dtype=array.dtype)], 1)


def _merge(parts: list[CaseResult]) -> CaseResult:
    """One law's CaseResult from its chunks, in case order (steps padded to the longest)."""
    length = max(int(p.steps["s"].shape[1]) for p in parts)
    steps = {key: np.concatenate([_pad_steps(p.steps[key], length) for p in parts]) for key in parts[0].steps}
    cycles = {
        key: parts[0].cycles[key] if key == "stage" else np.concatenate([p.cycles[key] for p in parts])
        for key in parts[0].cycles
    }
    return CaseResult(
        steps=steps,
        n_steps=np.concatenate([p.n_steps for p in parts]),
        status=np.concatenate([p.status for p in parts]),
        message=np.concatenate([p.message for p in parts]),
        events={
            event: {key: np.concatenate([p.events[event][key] for p in parts]) for key in table}
            for event, table in parts[0].events.items()
        },
        counters={key: np.concatenate([p.counters[key] for p in parts]) for key in parts[0].counters},
        cycles=cycles,
    )


def study_digest(study: Study) -> str:
    """SHA-256 of the study text: parts are only ever combined for the same study."""
    return hashlib.sha256(study.text.encode("utf-8")).hexdigest()


def parts_directory(output: str | os.PathLike[str]) -> FilePath:
    """Where the parts of the archive ``output`` are kept while it is computed: ``<output>.parts``."""
    output = FilePath(output)
    return output.with_name(output.name + ".parts")


def _write_atomically(directory: FilePath, name: str, write: Callable[[Any], None]) -> None:
    with atomic_destination(directory / name, ".part") as temporary, open(temporary, "wb") as handle:
        write(handle)


def _write_part(directory: FilePath, chunk: Chunk, digest: str, flat: dict[str, np.ndarray]) -> None:
    header = {"study_sha256": np.array(digest), "start": np.array(chunk.start), "stop": np.array(chunk.stop)}
    _write_atomically(directory, chunk.file_name, lambda handle: np.savez(handle, **header, **flat))


def _read_part(directory: FilePath, chunk: Chunk, digest: str) -> CaseResult:
    with np.load(directory / chunk.file_name, allow_pickle=False) as stored:
        flat = {key: stored[key] for key in stored.files}
    if str(flat.pop("study_sha256")) != digest:
        raise ResumeError("part", f"{directory / chunk.file_name} belongs to another study")
    start, stop = int(flat.pop("start")), int(flat.pop("stop"))
    if (start, stop) != (chunk.start, chunk.stop):
        raise ResumeError(
            "part", f"{directory / chunk.file_name} holds cases {start}:{stop}, expected {chunk.start}:{chunk.stop}"
        )
    return _unflatten(flat)


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
        for stale in directory.glob(".tmp-*"):
            stale.unlink()
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
    _write_atomically(directory, MANIFEST, lambda handle: handle.write(json.dumps(manifest, indent=1).encode()))
    return chunk_cases


def _distributed() -> Any:
    """The ``distributed`` module, or an ImportError saying how to install it."""
    try:
        import distributed
    except ImportError as error:
        raise ImportError(DISTRIBUTED_MISSING) from error
    return distributed


def _compute(
    study: Study,
    chunks: list[Chunk],
    done: Callable[[Chunk, dict[str, np.ndarray]], None],
    workers: int | None,
    scheduler: str | None,
) -> None:
    """Run the chunks (in process, or on dask) and call ``done`` as each one finishes."""
    if workers is None and scheduler is None:
        for chunk in chunks:
            done(chunk, run_chunk(study, chunk.law, chunk.start, chunk.stop))
        return
    distributed = _distributed()
    with contextlib.ExitStack() as stack:
        address: Any = scheduler
        if scheduler is None:
            # Workers' scratch space in a directory of its own, removed with the cluster.
            scratch = stack.enter_context(tempfile.TemporaryDirectory(prefix="ncstab-dask-"))
            import dask

            stack.enter_context(dask.config.set({"temporary-directory": scratch}))
            address = stack.enter_context(
                distributed.LocalCluster(
                    n_workers=int(workers),  # type: ignore[arg-type]
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=":0",  # a free port: never "port 8787 is in use"
                    local_directory=scratch,
                )
            )
        client = stack.enter_context(distributed.Client(address))
        futures = {
            client.submit(run_chunk, study, chunk.law, chunk.start, chunk.stop, pure=False): chunk
            for chunk in chunks
        }
        for future in distributed.as_completed(futures):
            done(futures.pop(future), future.result())
            future.release()


def _assemble(study: Study, chunks: list[Chunk], directory: FilePath, digest: str) -> xr.Dataset:
    """The study's Dataset from its parts, exactly as :func:`~ncstab.studies.run_study` builds it."""
    grid = ParameterGrid.from_mapping(study.parameters)
    system_class = SYSTEMS[study.system.name]
    results = tuple(
        _merge([_read_part(directory, chunk, digest) for chunk in chunks if chunk.law == law]) for law in study.laws
    )
    path = Path(
        laws=tuple(study.laws),
        grid=grid,
        system=study.system,
        programme=study.programme,
        options=study.options,
        results=results,
        dof_names=system_class.dof_names,  # type: ignore[attr-defined]
        force_names=system_class.force_names,  # type: ignore[attr-defined]
        study_text=study.text,
    )
    return study_dataset(study, path)


def run_study_chunked(
    study: Study,
    output: str | os.PathLike[str],
    chunk_cases: int | None = None,
    resume: bool = False,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: bool = False,
) -> xr.Dataset:
    """Run a study in chunks, each kept on disk as it finishes, and write its archive.

    The archive is identical (``xarray.testing.assert_identical`` after
    :func:`~ncstab.studies.open_study`, but for the ``created`` time stamp) to
    the one :func:`~ncstab.studies.run_study` and
    :func:`~ncstab.studies.write_dataset` give.

    Parameters
    ----------
    study
        A validated study (:func:`~ncstab.studies.load_study`).
    output
        The archive to write (``.nc``); parts are kept in ``<output>.parts``
        until it is written, then removed.
    chunk_cases
        At most this many cases per chunk (default :data:`DEFAULT_CHUNK_CASES`;
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
    xarray.Dataset
        The archive's Dataset (as :func:`~ncstab.studies.open_study` reads it).

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
            return finished
    output.parent.mkdir(parents=True, exist_ok=True)
    chunk_cases = _prepare_parts(directory, study, chunk_cases, resume)
    chunks = plan_chunks(study, chunk_cases)
    missing = [chunk for chunk in chunks if not (directory / chunk.file_name).exists()]
    bar = None
    if progress:
        from tqdm.auto import tqdm

        bar = tqdm(total=sum(c.size for c in chunks), unit="case", desc="ncstab", leave=False)
        bar.update(sum(c.size for c in chunks) - sum(c.size for c in missing))

    def done(chunk: Chunk, flat: dict[str, np.ndarray]) -> None:
        _write_part(directory, chunk, digest, flat)
        if bar is not None:
            bar.update(chunk.size)

    try:
        _compute(study, missing, done, workers, scheduler)
    finally:
        if bar is not None:
            bar.close()
    dataset = _assemble(study, chunks, directory, digest)
    write_dataset(dataset, output)
    shutil.rmtree(directory)
    return dataset
