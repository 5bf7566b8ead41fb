"""Stored states of a batch of cases: padded ``(B, steps, ...)`` arrays that grow, within a limit.

The arrays are dense: every case has room for as many states as the longest,
so one case whose path runs long (a contact chattering, a runaway branch)
would make the whole batch ask for more memory than the machine has, and the
system would kill the process with nothing written.  The recorder therefore
has a limit of states per case, :func:`state_limit`: what :data:`STORED_SHARE`
of the memory available when the batch starts holds for every case (the
Dataset built from the states, its indicators and the archive need the rest).
A case whose next step could overfill it fails (``failed:memory``, with a
message saying what to change) while the others go on; the steppers check it
before each step (:meth:`Recorder.fits`).
"""

from __future__ import annotations

import numpy as np

from ncstab.paths.threads import in_shares, thread_count

__all__ = ["MIN_STATE_LIMIT", "STORED_SHARE", "Recorder", "state_limit"]

#: Share of the memory available when a batch starts that its stored states may take.
STORED_SHARE = 0.25
#: The limit of states per case is never below this (a machine short of memory
#: fails later, in numpy, rather than refusing every path).
MIN_STATE_LIMIT = 64


def state_limit(size: int, bytes_per_state: int, available: int | None) -> int | None:
    """Most states per case that ``size`` cases of ``bytes_per_state`` bytes each may store
    in :data:`STORED_SHARE` of ``available`` bytes (at least :data:`MIN_STATE_LIMIT`);
    None where the memory available is unknown."""
    if available is None or size <= 0 or bytes_per_state <= 0:
        return None
    return max(MIN_STATE_LIMIT, int(STORED_SHARE * available) // (size * bytes_per_state))


class Recorder:
    """Stores states straight into padded ``(B, capacity, ...)`` arrays.

    Each case's states go to its next free position; the capacity grows
    geometrically, so a sweep costs one scatter per stored state and field
    (no per-step chunks to concatenate and sort at the end).
    """

    def __init__(self, size: int, limit: int | None = None, available: int | None = None) -> None:
        self.size = size
        self.count = np.zeros(size, dtype=int)
        self.arrays: dict[str, np.ndarray] | None = None
        self.capacity = 0
        #: Most states per case the steppers let a case store (:func:`state_limit`), None: no limit.
        self.limit = limit
        #: The memory available when the batch started, in bytes (for the failure's message).
        self.available = available

    def fits(self, cases: np.ndarray, states: np.ndarray) -> np.ndarray:
        """Whether ``states`` more states of each of ``cases`` stay within the limit."""
        if self.limit is None:
            return np.ones(cases.shape, dtype=bool)
        return self.count[cases] + states <= self.limit

    @staticmethod
    def _blank(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        """A blank array (NaN, or -1 for integers), filled like a grown one (:func:`_grow_into`)."""
        blank = np.empty(shape, dtype=dtype)
        _grow_into(blank, blank[:, :0], 0)
        return blank

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
            wider = int(growth * self.capacity)
            if self.limit is not None:  # room beyond the limit only where it is asked for
                wider = min(wider, self.limit)
            capacity = max(needed, wider)
            for key, array in self.arrays.items():
                grown = np.empty((self.size, capacity) + array.shape[2:], array.dtype)
                _grow_into(grown, array, self.capacity)
                self.arrays[key] = grown
            self.capacity = capacity

    def reserve_within_limit(self, needed: int, growth: float = 2.0) -> None:
        """:meth:`reserve` for ``needed`` states per case, but no more than the limit: a case
        that would need more pauses at it, and its stepper fails it (``failed:memory``)."""
        self.reserve(needed if self.limit is None else min(needed, self.limit), growth=growth)

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


#: Arrays larger than this grow on the study's threads (:func:`_grow_into`).
PARALLEL_GROWTH_BYTES = 1 << 24


def _grow_into(grown: np.ndarray, old: np.ndarray, kept: int) -> None:
    """``grown[:, :kept] = old`` and the rest blank (NaN, or -1 for integers), each byte
    written once: fresh pages are costly to touch (65,536 cases: 0.3 s of first touches
    in 790 MB).  Large arrays are written in shares of the case axis on
    :func:`~ncstab.paths.threads.thread_count` threads (numpy releases the GIL while it
    copies and fills), so the pages are touched on every core; the bytes are the same."""
    blank = -1 if grown.dtype.kind == "i" else np.nan

    def share(rows: slice) -> None:
        grown[rows, :kept] = old[rows]
        grown[rows, kept:] = blank

    threads = thread_count() if grown.nbytes > PARALLEL_GROWTH_BYTES else 1
    in_shares(share, np.linspace(0, grown.shape[0], threads + 1).astype(int), "recorder")
