"""The chunks of a large sweep: which cases each holds, and how many a chunk has by default.

The cases of each law (flat, C order over the sweep, as in
:class:`ncstab.paths.api.ParameterGrid`) are cut into chunks of at most
``chunk_cases`` cases, runs of whole blocks of the archive's layout
(:class:`~ncstab.studies.streaming.BlockLayout`), so that each HDF5 chunk of
the archive belongs to one chunk of cases.  :mod:`ncstab.studies.chunked`
runs them.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ncstab.paths.api import ParameterGrid
from ncstab.studies.streaming_encode import BLOCK_CASES
from ncstab.studies.streaming_layout import BlockLayout
from ncstab.studies.study import Study

__all__ = [
    "CHUNKS_PER_WORKER",
    "DEFAULT_CHUNK_CASES",
    "MIN_DEFAULT_CHUNK_CASES",
    "Chunk",
    "archive_layout",
    "default_chunk_cases",
    "plan_chunks",
    "study_cases",
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
    """The blocks of a chunked run's archive: at most :data:`~ncstab.studies.streaming_encode.BLOCK_CASES`
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
