"""A study's archive written chunk by chunk: memory bounded by one chunk, whatever the sweep.

A large sweep is followed in chunks of flat cases (:mod:`ncstab.studies.chunked`).
Each chunk's Dataset (dimension ``case`` in place of the swept parameters, see
:class:`ncstab.paths.api.CaseRange`) is appended to the archive as soon as it
is computed, into the hyperslabs its cases occupy, so the whole archive is never
held in memory.  The ``step`` dimension is a NetCDF *unlimited* dimension: the
longest path is known only once every chunk is in.  Floating-point variables
read NaN past each case's last written step (their ``_FillValue``, as in an
archive written at once); integer ones (``stage``) are padded with -1 when the
archive is closed.  The archive reads back (:func:`~ncstab.studies.open_study`)
identical to the one :func:`~ncstab.studies.write_dataset` writes for the whole
run.
"""

from __future__ import annotations

import datetime as _dt
import math
import os
from collections.abc import Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.result import parameter_attributes
from ncstab.paths.variables import CASE_DIMENSION
from ncstab.studies.archive import COMPRESSION, MIN_COMPRESSED_SIZE

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.api import ParameterGrid

__all__ = ["ArchiveStream", "hyperslabs"]

#: States per HDF5 chunk along the (unlimited) ``step`` dimension.
STEP_CHUNK = 64
#: Target number of elements per HDF5 chunk (512 KiB of float64).
CHUNK_ELEMENTS = 65536
#: HDF5 chunk cache per variable, bytes: a few chunks, so that memory stays
#: bounded (about 100 variables) while a chunk of cases is written.
VARIABLE_CACHE_BYTES = 2 * 2**20


def hyperslabs(start: int, stop: int, shape: tuple[int, ...]) -> Iterator[tuple[int, tuple[slice, ...]]]:
    """Cover the flat (C order) cases ``start:stop`` of an array of ``shape`` with boxes.

    Yields
    ------
    (int, tuple of slice)
        The flat index of the box's first case, and the box as one slice per
        dimension.  The boxes are in flat order, disjoint, and their cases are
        exactly ``start:stop``; there are at most ``2 len(shape) - 1`` of them.
    """
    if not 0 <= start <= stop <= math.prod(shape):
        raise ValueError(f"cases {start}:{stop} are not within an array of shape {shape}")
    if start == stop:
        return
    if not shape:
        yield start, ()
        return
    inner = math.prod(shape[1:])
    position = start
    while position < stop:
        row, offset = divmod(position, inner)
        if offset == 0 and stop - position >= inner:
            rows = (stop - position) // inner
            yield position, (slice(row, row + rows),) + tuple(slice(0, n) for n in shape[1:])
            position += rows * inner
        else:
            end = min(inner, stop - row * inner)
            for first, box in hyperslabs(offset, end, shape[1:]):
                yield row * inner + first, (slice(row, row + 1),) + box
            position = row * inner + end


def _box_shape(box: tuple[slice, ...]) -> tuple[int, ...]:
    return tuple(s.stop - s.start for s in box)


def _chunk_sizes(dims: tuple[str, ...], sizes: dict[str, int]) -> list[int]:
    """HDF5 chunk shape: trailing dimensions whole, ``step`` by :data:`STEP_CHUNK`, then
    as many of the last swept values as fit in :data:`CHUNK_ELEMENTS`; one law per chunk."""
    out = [1] * len(dims)
    elements = 1
    for position in reversed(range(len(dims))):
        name = dims[position]
        if name == "law":
            continue
        size = STEP_CHUNK if name == "step" else sizes[name]
        out[position] = max(1, min(size, CHUNK_ELEMENTS // elements))
        elements *= out[position]
    return out


class ArchiveStream:
    """A NetCDF-4 archive filled chunk by chunk of cases.

    Parameters
    ----------
    path
        The file to create (a temporary: the caller moves it into place once
        :meth:`close` has returned).
    laws
        The study's laws, in order (the ``law`` dimension).
    grid
        The study's parameter grid (the swept dimensions after ``law``).

    Notes
    -----
    The file is created at the first :meth:`append`: the chunk's Dataset
    gives the variables, their attributes and the dimensions other than
    ``law``, the swept parameters and ``step``.
    """

    def __init__(self, path: str | os.PathLike[str], laws: tuple[str, ...], grid: "ParameterGrid") -> None:
        self.path = FilePath(path)
        self.laws = tuple(laws)
        self.grid = grid
        self._file: Any = None
        self._written: list[tuple[int, int, int, int]] = []  # (law index, start, stop, steps)
        self._step_integers: list[str] = []
        self._classes: dict[str, str] = {}

    # -- creation -------------------------------------------------------------------------
    def _full_dims(self, dims: tuple[str, ...]) -> tuple[str, ...]:
        """A chunk variable's dimensions in the whole archive: ``case`` becomes the swept parameters."""
        out: list[str] = []
        for name in dims:
            if name == CASE_DIMENSION:
                out.extend(self.grid.sweep)
            else:
                out.append(name)
        return tuple(out)

    def _create(self, chunk: "xr.Dataset") -> None:
        import netCDF4

        handle = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        self._file = handle
        sizes = {"law": len(self.laws), **{name: values.size for name, values in self.grid.sweep.items()}}
        handle.createDimension("law", len(self.laws))
        for name, values in self.grid.sweep.items():
            handle.createDimension(name, values.size)
        for name, size in chunk.sizes.items():
            if name in ("law", CASE_DIMENSION):
                continue
            handle.createDimension(name, None if name == "step" else size)
            sizes[name] = size
        attrs = dict(chunk.attrs)
        attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        handle.setncatts(attrs)

        index_names = set(chunk.dims) | set(self.grid.sweep) | {"law"}
        auxiliary = [name for name in chunk.coords if name not in index_names]
        attached: set[str] = set()
        for name, variable in chunk.variables.items():
            if name == CASE_DIMENSION:
                continue
            dims = self._full_dims(variable.dims)
            attrs = dict(variable.attrs)
            if name in chunk.data_vars:
                coordinates = [c for c in auxiliary if set(chunk[c].dims) <= set(variable.dims)]
                attached.update(coordinates)
                if coordinates:
                    attrs["coordinates"] = " ".join(coordinates)
            self._define(name, variable.dtype, dims, attrs, is_index=name in index_names, sizes=sizes)
            if "step" in dims and "law" in dims and variable.dtype.kind in "iu":
                self._step_integers.append(name)
            if "law" not in dims and name != "step":
                self._put(name, (), variable.values)
        unattached = [c for c in auxiliary if c not in attached]
        if unattached:
            handle.setncattr("coordinates", " ".join(unattached))
        for name, values in self.grid.sweep.items():
            self._define(name, values.dtype, (name,), parameter_attributes(name), is_index=True, sizes=sizes)
            self._put(name, (), values)
        self._put("law", (), np.array(self.laws, dtype=object))

    def _define(
        self, name: str, dtype: np.dtype, dims: tuple[str, ...], attrs: dict[str, Any], is_index: bool,
        sizes: dict[str, int],
    ) -> None:
        numeric = dtype.kind in "biuf"
        options: dict[str, Any] = {}
        if numeric and dims and math.prod(STEP_CHUNK if d == "step" else sizes[d] for d in dims) >= MIN_COMPRESSED_SIZE:
            options.update(COMPRESSION, chunksizes=_chunk_sizes(dims, sizes))
        if dtype.kind == "f" and not is_index:
            options["fill_value"] = np.nan
        variable = self._file.createVariable(name, dtype if numeric else str, dims, **options)
        if "chunksizes" in options:
            variable.set_var_chunk_cache(size=VARIABLE_CACHE_BYTES)
        variable.setncatts(attrs)

    def _put(self, name: str, index: tuple, values: np.ndarray) -> None:
        target = self._file.variables[name]
        if values.dtype.kind == "U":
            values = values.astype(object)
        target[index if index else slice(None)] = values

    # -- filling --------------------------------------------------------------------------
    def append(self, chunk: "xr.Dataset", law: str, start: int, stop: int) -> None:
        """Write the Dataset of the cases ``start:stop`` of ``law`` into their hyperslabs.

        Parameters
        ----------
        chunk
            The chunk's Dataset: dimensions ``law`` (of size 1) and ``case``
            (``stop - start`` cases) in place of the swept parameters.
        """
        if chunk.sizes.get("law") != 1 or chunk.sizes.get(CASE_DIMENSION) != stop - start:
            raise ValueError(
                f"a chunk of cases {start}:{stop} needs dimensions law = 1 and case = {stop - start}, "
                f"got {dict(chunk.sizes)}"
            )
        if self._file is None:
            self._create(chunk)
        k = self.laws.index(law)
        steps = int(chunk.sizes.get("step", 0))
        boxes = list(hyperslabs(start, stop, self.grid.shape))
        for name, variable in chunk.variables.items():
            if CASE_DIMENSION not in variable.dims or name == CASE_DIMENSION:
                continue
            values = variable.values[0]
            trailing = tuple(slice(0, steps) if d == "step" else slice(None) for d in variable.dims[2:])
            for first, box in boxes:
                block = values[first - start : first - start + math.prod(_box_shape(box))]
                # The law as a slice: every block is an array (netCDF strings refuse 0-d ones).
                shape = (1, *_box_shape(box), *values.shape[1:])
                self._put(name, (slice(k, k + 1), *box, *trailing), block.reshape(shape))
        self._classes[law] = str(chunk["law_class"].values[0])
        self._put("law_class", (slice(k, k + 1),), chunk["law_class"].values[:1])
        self._written.append((k, start, stop, steps))

    def close(self) -> None:
        """Write the ``step`` coordinate, pad integer step variables with -1, close the file."""
        if self._file is None:
            raise ValueError(f"{self.path}: no chunk was appended; an archive needs at least one")
        missing = [law for law in self.laws if law not in self._classes]
        if missing:
            raise ValueError(f"{self.path}: no chunk of law(s) {', '.join(missing)} was appended")
        # As in a whole run's Dataset (ncstab.paths.Path.to_dataset): every law's class.
        self._file.setncattr("law_class", "; ".join(f"{law}: {self._classes[law]}" for law in self.laws))
        length = max(steps for *_, steps in self._written)
        self._put("step", (), np.arange(length, dtype=self._file.variables["step"].dtype))
        for k, start, stop, steps in self._written:
            if steps == length:
                continue
            for name in self._step_integers:
                variable = self._file.variables[name]
                after = variable.dimensions[variable.dimensions.index("step") + 1 :]
                for _, box in hyperslabs(start, stop, self.grid.shape):
                    index = (k, *box, slice(steps, length), *(slice(None) for _ in after))
                    variable[index] = np.full(_box_shape(box) + (length - steps,) + variable.shape[len(box) + 2 :], -1)
        self._file.close()
        self._file = None

    def abort(self) -> None:
        """Close the file without completing it (the caller removes it)."""
        if self._file is not None:
            self._file.close()
            self._file = None
