"""Event tables of a streamed archive written only if some case meets the event (the lean default).

Whether any case of a sweep meets an event is known only once every chunk of
cases is in.  An archive written chunk by chunk
(:class:`~ncstab.studies.streaming.ArchiveStream`) therefore holds back the
tables of the events that may be left out: their definitions and their
compressed HDF5 chunks (a few hundred bytes per chunk of cases and variable:
they have no ``step`` dimension) are kept in memory, and when the archive is
closed the tables of the events some case met are defined and written, the
others are left out and named in the attribute
:data:`~ncstab.studies.archive_selection.EVENTS_LEFT_OUT`, as
:func:`~ncstab.studies.archive_selection.leave_out_unseen_events` does for a
sweep run at once.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ncstab.paths.programme import EVENTS
from ncstab.studies.archive_selection import EVENTS_LEFT_OUT, event_variables

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = ["HeldEventTables", "events_met"]


def events_met(dataset: "xr.Dataset") -> tuple[str, ...]:
    """The events some case of ``dataset`` meets (``<event>_stage`` >= 0 somewhere)."""
    met = []
    for event in EVENTS:
        stage = dataset.get(f"{event}_stage")
        if stage is not None and bool((np.asarray(stage.values) >= 0).any()):
            met.append(event)
    return tuple(met)


@dataclass
class _Definition:
    """How to create one held-back variable: what ``ArchiveStream._define`` takes."""

    dtype: np.dtype
    dims: tuple[str, ...]
    attrs: dict[str, Any]
    chunk: tuple[int, ...]
    integer_fill: int | None


@dataclass
class HeldEventTables:
    """The tables of ``events`` of an archive being streamed, held back until it is closed.

    Parameters
    ----------
    events
        The events whose tables are left out if no case meets them.
    """

    events: tuple[str, ...]
    definitions: dict[str, _Definition] = field(default_factory=dict)
    chunks: list[tuple[str, tuple[int, ...], bytes]] = field(default_factory=list)
    met: set[str] = field(default_factory=set)

    def holds(self, name: str) -> bool:
        """Whether variable ``name`` belongs to a held-back event's table."""
        return any(name.startswith(f"{event}_") for event in self.events)

    def define_later(
        self, name: str, dtype: np.dtype, dims: tuple[str, ...], attrs: dict[str, Any],
        chunk: tuple[int, ...], integer_fill: int | None,
    ) -> None:
        """Remember how to create variable ``name`` (one of :meth:`holds`)."""
        self.definitions[name] = _Definition(dtype, dims, attrs, chunk, integer_fill)

    def keep(self, name: str, offset: tuple[int, ...], data: bytes) -> None:
        """Hold an encoded HDF5 chunk of variable ``name`` at ``offset`` (law index first)."""
        self.chunks.append((name, offset, data))

    def record_met(self, events: tuple[str, ...]) -> None:
        """Events a chunk of cases meets."""
        self.met.update(events)

    @property
    def left_out(self) -> list[str]:
        """The held-back events no case met, in the order of :data:`~ncstab.paths.programme.EVENTS`."""
        return [event for event in EVENTS if event in self.events and event not in self.met]

    def write(self, path: FilePath, define: Callable[..., None], sizes: dict[str, int]) -> list[str]:
        """Create and fill the tables of the events met, name those left out.

        ``define`` is ``ArchiveStream._define``; the file is closed on entry
        and on return.  Returns the variables written by direct chunk writes
        (whose filters the caller checks).
        """
        import h5py
        import netCDF4

        left_out = set(self.left_out)
        written = [name for name in self.definitions if not any(event_variables(e, [name]) for e in left_out)]
        with netCDF4.Dataset(path, "a") as handle:
            for name in written:
                spec = self.definitions[name]
                define(handle, name, spec.dtype, spec.dims, spec.attrs, False, sizes, spec.chunk, spec.integer_fill)
            if left_out:
                handle.setncattr(EVENTS_LEFT_OUT, ", ".join(self.left_out))
        if written:
            with h5py.File(path, "r+") as archive:
                wanted = set(written)
                for name, offset, data in self.chunks:
                    if name in wanted:
                        archive[name].id.write_direct_chunk(offset, data)
        self.chunks.clear()
        return written
