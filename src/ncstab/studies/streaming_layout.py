"""The layout of a streamed archive: blocks of cases that are boxes of the sweep, and a
chunk of cases encoded for it (:mod:`ncstab.studies.streaming` writes them)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = ["Block", "BlockLayout", "EncodedChunk"]


@dataclass(frozen=True)
class Block:
    """Flat cases ``start:stop`` of the sweep, which are also the box ``origin + shape``."""

    start: int
    stop: int
    origin: tuple[int, ...]
    shape: tuple[int, ...]


@dataclass(frozen=True)
class BlockLayout:
    """How the swept dimensions of an archive are cut into HDF5 chunks.

    A chunk spans ``extent`` values of the swept dimension ``axis``, every value
    of the dimensions after it and one value of those before it, so that its
    cases are consecutive in flat (C) order: a block.  Blocks tile the sweep in
    order; the last block along ``axis`` may be shorter.

    Parameters
    ----------
    shape
        Sizes of the swept dimensions (``()`` for a single case).
    axis, extent
        The dimension the blocks cut, and the values of it per block.
    """

    shape: tuple[int, ...]
    axis: int
    extent: int

    @classmethod
    def for_grid(cls, shape: tuple[int, ...], max_cases: int) -> "BlockLayout":
        """The layout of the largest blocks of at most ``max_cases`` cases (at least one value)."""
        shape = tuple(int(n) for n in shape)
        if not shape:
            return cls((), 0, 1)
        tail = 1
        for axis in reversed(range(len(shape))):
            extent = min(shape[axis], max(1, int(max_cases) // tail))
            if extent < shape[axis] or axis == 0:
                return cls(shape, axis, extent)
            tail *= shape[axis]
        raise AssertionError("unreachable")  # pragma: no cover

    @property
    def tail(self) -> int:
        """Cases per value of ``axis`` (the product of the later swept sizes)."""
        return math.prod(self.shape[self.axis + 1 :])

    @property
    def chunk(self) -> tuple[int, ...]:
        """The HDF5 chunk shape along the swept dimensions."""
        if not self.shape:
            return ()
        return (1,) * self.axis + (self.extent,) + self.shape[self.axis + 1 :]

    @property
    def block_cases(self) -> int:
        """Cases of a whole block."""
        return self.extent * self.tail

    def blocks(self, start: int, stop: int) -> list[Block]:
        """The blocks that make up the flat cases ``start:stop``.

        Raises
        ------
        ValueError
            ``start:stop`` is not a run of whole blocks.
        """
        size = math.prod(self.shape)
        if not 0 <= start <= stop <= size:
            raise ValueError(f"cases {start}:{stop} are not within a sweep of shape {self.shape}")
        out = []
        position = start
        while position < stop:
            index = tuple(int(i) for i in np.unravel_index(position, self.shape)) if self.shape else ()
            if self.shape and (index[self.axis] % self.extent or any(index[self.axis + 1 :])):
                raise ValueError(
                    f"cases {start}:{stop} do not start on a block of {self.block_cases} cases "
                    f"(the archive's chunks along the sweep {self.shape} are {self.chunk})"
                )
            rows = min(self.extent, self.shape[self.axis] - index[self.axis]) if self.shape else 1
            shape = (1,) * self.axis + (rows,) + self.shape[self.axis + 1 :] if self.shape else ()
            out.append(Block(position, position + rows * self.tail, index, shape))
            position += rows * self.tail
        if position != stop:
            raise ValueError(f"cases {start}:{stop} do not end on a block of {self.block_cases} cases")
        return out

    def runs(self, max_cases: int) -> list[tuple[int, int]]:
        """The sweep cut into runs of whole blocks of at most ``max_cases`` cases (at least one block)."""
        every = self.blocks(0, math.prod(self.shape))
        runs: list[tuple[int, int]] = []
        for block in every:
            if runs and block.stop - runs[-1][0] <= max_cases:
                runs[-1] = (runs[-1][0], block.stop)
            else:
                runs.append((block.start, block.stop))
        return runs


@dataclass
class EncodedChunk:
    """A chunk of cases of one law, ready to be copied into the archive.

    Attributes
    ----------
    law, start, stop
        The law and the flat cases ``start:stop``.
    steps
        Length of the chunk's ``step`` dimension (its longest case).
    template
        The chunk's Dataset without its cases (``case`` of size 0): the
        variables, their dimensions, attributes and the values of those
        without a ``case`` dimension.
    chunks
        ``(variable, chunk offset, compressed bytes)`` of every HDF5 chunk of
        the numeric variables (:func:`deflate_shuffled`); the offset is in the
        dimensions after ``law`` (the archive puts the law's index first).
    strings
        The other variables with a ``case`` dimension (text), as arrays of the
        chunk's cases.
    events_met
        The events some case of the chunk meets (an archive holding back the
        tables of unmet events, :mod:`~ncstab.studies.streaming_events`, needs it).
    """

    law: str
    start: int
    stop: int
    steps: int
    template: "xr.Dataset"
    chunks: list[tuple[str, tuple[int, ...], bytes]] = field(default_factory=list)
    strings: dict[str, np.ndarray] = field(default_factory=dict)
    events_met: tuple[str, ...] = ()
