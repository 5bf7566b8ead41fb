"""A chunk of cases compressed into the archive's HDF5 chunks, as HDF5's filters would store them.

Whoever computes a chunk of cases (the process itself or a dask worker) also
compresses its part of the archive (:func:`encode_chunk`): each variable with
a ``case`` dimension is cut into the archive's HDF5 chunks
(:func:`variable_chunk`, blocks of :class:`~ncstab.studies.streaming_layout.BlockLayout`
along the sweep), each checksummed, byte-shuffled and deflated
(:func:`deflate_shuffled`).  :class:`ncstab.studies.streaming.ArchiveStream`
copies the bytes into the archive.
"""

from __future__ import annotations

import itertools
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.variables import CASE_DIMENSION
from ncstab.studies.archive import COMPRESSION
from ncstab.studies.checksums import hdf5_chunk
from ncstab.studies.streaming_events import events_met
from ncstab.studies.streaming_layout import BlockLayout, EncodedChunk

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = [
    "BLOCK_CASES",
    "CHUNK_ELEMENTS",
    "FILTER_PIPELINE",
    "INTEGER_PADDING",
    "STEP_CHUNK",
    "deflate_shuffled",
    "encode_chunk",
    "is_encoded",
    "variable_chunk",
    "variable_dims",
]

#: HDF5 filter identifiers, in the pipeline order the encoder follows
#: (:func:`~ncstab.studies.checksums.hdf5_chunk`): Fletcher-32, shuffle, deflate.
FILTER_PIPELINE = (3, 2, 1)

#: States per HDF5 chunk along the (unlimited) ``step`` dimension, at most.
STEP_CHUNK = 64
#: Target number of elements per HDF5 chunk (512 KiB of float64).
CHUNK_ELEMENTS = 65536
#: Cases per block (per HDF5 chunk along the swept dimensions), at most.
BLOCK_CASES = 1024
#: Padding of integer variables past a case's last step (as in a whole run's Dataset).
INTEGER_PADDING = -1


def is_encoded(variable: Any) -> bool:
    """Whether a chunk variable goes in as compressed HDF5 chunks (numbers with a ``case`` dimension)."""
    return CASE_DIMENSION in variable.dims and variable.dtype.kind in "iuf"


def variable_chunk(dims: tuple[str, ...], sizes: dict[str, int], layout: BlockLayout, sweep: tuple[str, ...]) -> tuple[int, ...]:
    """HDF5 chunk shape of an archive variable: one law, a block of the sweep, then
    ``step`` (at most :data:`STEP_CHUNK`) and trailing dimensions filled, from the
    last, up to about :data:`CHUNK_ELEMENTS` elements."""
    swept = dict(zip(sweep, layout.chunk))
    budget = max(1, CHUNK_ELEMENTS // layout.block_cases)
    elements = 1
    out = []
    for name in reversed(dims):
        if name == "law":
            out.append(1)
        elif name in swept:
            out.append(swept[name])
        else:
            size = STEP_CHUNK if name == "step" else sizes[name]
            extent = max(1, min(size, budget // elements))
            elements *= extent
            out.append(extent)
    return tuple(reversed(out))


def deflate_shuffled(values: np.ndarray) -> bytes:
    """One HDF5 chunk as the archive's filters store it: Fletcher-32, byte shuffle, deflate.

    The same bytes HDF5 writes for a variable encoded with
    :data:`~ncstab.studies.archive.COMPRESSION` (``fletcher32``, ``shuffle``
    then ``zlib`` at ``complevel``, :data:`FILTER_PIPELINE`); the reader's
    filters check and undo them.
    """
    return hdf5_chunk(values, COMPRESSION["complevel"])


def _fill(dtype: np.dtype) -> Any:
    return np.nan if dtype.kind == "f" else INTEGER_PADDING


def variable_dims(dims: tuple[str, ...], sweep: tuple[str, ...]) -> tuple[str, ...]:
    """A chunk variable's dimensions in the whole archive: ``case`` becomes the swept parameters."""
    out: list[str] = []
    for name in dims:
        if name == CASE_DIMENSION:
            out.extend(sweep)
        else:
            out.append(name)
    return tuple(out)


def encode_chunk(
    dataset: "xr.Dataset", law: str, start: int, stop: int, layout: BlockLayout, sweep: tuple[str, ...]
) -> EncodedChunk:
    """Compress a chunk's Dataset into the archive's HDF5 chunks (blocks of ``layout``).

    Parameters
    ----------
    dataset
        The chunk's Dataset (:func:`~ncstab.studies.chunked.run_chunk`): ``law``
        of size 1 and ``case`` (``stop - start`` cases) in place of the swept
        parameters ``sweep``.
    law
        The chunk's law.
    start, stop
        The chunk's flat cases: a run of whole blocks of ``layout``.
    """
    if dataset.sizes.get("law") != 1 or dataset.sizes.get(CASE_DIMENSION) != stop - start:
        raise ValueError(
            f"a chunk of cases {start}:{stop} needs dimensions law = 1 and case = {stop - start}, "
            f"got {dict(dataset.sizes)}"
        )
    blocks = layout.blocks(start, stop)
    steps = int(dataset.sizes.get("step", 0))
    sizes = dict(dataset.sizes)
    encoded = EncodedChunk(
        law=law, start=start, stop=stop, steps=steps, template=dataset.isel({CASE_DIMENSION: slice(0, 0)}),
        events_met=events_met(dataset),
    )
    for name, variable in dataset.variables.items():
        if CASE_DIMENSION not in variable.dims or name == CASE_DIMENSION:
            continue
        values = variable.values[0]  # (case, *rest)
        if not is_encoded(variable):
            encoded.strings[str(name)] = values
            continue
        dims = variable_dims(variable.dims, sweep)
        chunk = variable_chunk(dims, sizes, layout, sweep)
        rest_chunk = chunk[1 + len(sweep) :]
        rest_shape = values.shape[1:]
        # Chunk positions along the trailing dimensions (only those that hold steps of this chunk).
        counts = [math.ceil(n / c) for n, c in zip(rest_shape, rest_chunk)]
        fill = _fill(values.dtype)
        for block in blocks:
            padded = np.full(layout.chunk + tuple(k * c for k, c in zip(counts, rest_chunk)), fill, values.dtype)
            box = tuple(slice(0, n) for n in block.shape) + tuple(slice(0, n) for n in rest_shape)
            padded[box] = values[block.start - start : block.stop - start].reshape(block.shape + rest_shape)
            for position in itertools.product(*(range(k) for k in counts)):
                window = tuple(slice(p * c, (p + 1) * c) for p, c in zip(position, rest_chunk))
                piece = padded[(Ellipsis, *window)] if window else padded
                offset = (*block.origin, *(p * c for p, c in zip(position, rest_chunk)))
                encoded.chunks.append((str(name), offset, deflate_shuffled(piece[np.newaxis])))
    return encoded
