"""Stored states of a batch of cases: padded ``(B, steps, ...)`` arrays that grow."""

from __future__ import annotations

import numpy as np

__all__ = ["Recorder"]


class Recorder:
    """Stores states straight into padded ``(B, capacity, ...)`` arrays.

    Each case's states go to its next free position; the capacity grows
    geometrically, so a sweep costs one scatter per stored state and field
    (no per-step chunks to concatenate and sort at the end).
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.count = np.zeros(size, dtype=int)
        self.arrays: dict[str, np.ndarray] | None = None
        self.capacity = 0

    @staticmethod
    def _blank(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        return np.full(shape, -1 if np.dtype(dtype).kind == "i" else np.nan, dtype=dtype)

    def add(self, case: np.ndarray, **values: np.ndarray) -> None:
        values = {key: np.asarray(value) for key, value in values.items()}
        position = self.count[case]
        needed = int(position.max()) + 1 if case.size else 0
        if self.arrays is None:
            # Created even when no case stores a state (all fail at the first
            # stage start): every field still gets its shape and dtype.
            self.capacity = max(needed, 8)
            self.arrays = {
                key: self._blank((self.size, self.capacity) + value.shape[1:], value.dtype)
                for key, value in values.items()
            }
        else:
            self.reserve(needed)
        self._scatter(case * self.capacity + position, values)
        self.count[case] += 1

    def create(self, fields: dict[str, tuple[tuple[int, ...], np.dtype]]) -> None:
        """Create the arrays (if not yet) for ``fields``: name -> (shape after the case
        and step axes, dtype), for a writer that fills them itself."""
        if self.arrays is None:
            self.capacity = 8
            self.arrays = {
                key: self._blank((self.size, self.capacity) + shape, dtype) for key, (shape, dtype) in fields.items()
            }

    def reserve(self, needed: int, growth: float = 2.0) -> None:
        """Room for ``needed`` states per case; also for a writer that fills the arrays and
        ``count`` itself (:mod:`ncstab.paths.compiled`).

        Parameters
        ----------
        needed
            States per case the arrays must hold.
        growth
            Where they must grow, the least factor of growth: 2 (doubling) where
            ``needed`` is only the next step's, less where it is an estimate of what
            the cases still need (the capacity then stays near the estimate, and a
            short estimate still costs only a few growths).
        """
        assert self.arrays is not None
        if needed > self.capacity:
            capacity = max(needed, int(growth * self.capacity))
            for key, array in self.arrays.items():
                # Each byte written once (fresh pages are costly to touch): the
                # old states, then the padding.
                grown = np.empty((self.size, capacity) + array.shape[2:], array.dtype)
                grown[:, : self.capacity] = array
                grown[:, self.capacity :] = -1 if array.dtype.kind == "i" else np.nan
                self.arrays[key] = grown
            self.capacity = capacity

    def _scatter(self, flat: np.ndarray, values: dict[str, np.ndarray]) -> None:
        """Write ``values`` at the flat (case * capacity + position) indices ``flat``."""
        assert self.arrays is not None
        for key, value in values.items():
            array = self.arrays[key]
            array.reshape((self.size * self.capacity,) + array.shape[2:])[flat] = value

    @property
    def started(self) -> bool:
        return self.arrays is not None

    def assemble(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        assert self.arrays is not None
        length = int(self.count.max()) if self.size else 0
        # Views, not copies: the capacity left over is less than the length
        # (geometric growth), and copying every field cost more than the rest
        # of the bookkeeping together.
        return {key: array[:, :length] for key, array in self.arrays.items()}, self.count
