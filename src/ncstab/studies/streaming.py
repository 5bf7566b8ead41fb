"""A study's archive written chunk by chunk: memory bounded by one chunk, whatever the sweep.

A large sweep is followed in chunks of flat cases (:mod:`ncstab.studies.chunked`).
The archive's HDF5 chunks are laid out so that every chunk of the archive
belongs to exactly one chunk of cases (:class:`BlockLayout`): its cases form a
*block*, a run of the flat cases that is also a box of the swept dimensions.
Whoever computes a chunk of cases (the process itself or a dask worker)
therefore also compresses its part of the archive, Fletcher-32 checksum,
byte-shuffle then deflate as the HDF5 filters would (:func:`encode_chunk`,
:func:`~ncstab.studies.checksums.hdf5_chunk`), and the process that owns the
archive only copies the compressed bytes in (:meth:`ArchiveStream.append`,
HDF5's direct chunk write through h5py).  Compression, the dearest part of
writing, is spread over the workers.  The variables HDF5 does not checksum
(strings, small coordinates) get their digest when the archive is closed, as
in an archive written at once.

The ``step`` dimension is a NetCDF *unlimited* dimension: the longest path is
known only once every chunk is in.  Floating-point variables read NaN past
each case's last step (their ``_FillValue``, as in an archive written at
once); integer ones (``stage``) are padded with -1, in the chunks that hold a
case's last steps by the encoder and in the chunks past them when the archive
is closed.  The archive reads back (:func:`~ncstab.studies.open_study`)
identical to the one :func:`~ncstab.studies.write_dataset` writes for the
whole run.
"""

from __future__ import annotations

import datetime as _dt
import itertools
import math
import os
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.dataset import parameter_attributes
from ncstab.paths.variables import CASE_DIMENSION
from ncstab.studies.archive import COMPRESSION, MIN_COMPRESSED_SIZE, integer_fill_value
from ncstab.studies.checksums import DIGEST_ATTRIBUTE, format_digests, variable_digest
from ncstab.studies.streaming_encode import (
    FILTER_PIPELINE,
    INTEGER_PADDING,
    STEP_CHUNK,
    deflate_shuffled,
    encode_chunk,
    is_encoded,
    variable_chunk,
    variable_dims,
)
from ncstab.studies.streaming_events import HeldEventTables
from ncstab.studies.streaming_layout import Block, BlockLayout, EncodedChunk

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.api import ParameterGrid

__all__ = ["ArchiveStream", "Block", "BlockLayout", "EncodedChunk", "encode_chunk"]



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
    layout
        The blocks of the archive's chunks (:class:`BlockLayout` of the grid's shape).
    unmet_events_left_out
        Events whose tables are written only if some case meets them (the lean
        default, :class:`~ncstab.studies.streaming_events.HeldEventTables`).

    Notes
    -----
    The file is created with netCDF4 at the first :meth:`append` (the chunk's
    template gives the variables, their attributes and the dimensions other
    than ``law``, the swept parameters and ``step``), then filled with h5py,
    whose direct chunk writes copy the encoded chunks in as they are; the law
    classes and the digests of the variables HDF5 does not checksum are
    written with netCDF4 again at :meth:`close`.
    """

    def __init__(
        self, path: str | os.PathLike[str], laws: tuple[str, ...], grid: "ParameterGrid", layout: BlockLayout,
        unmet_events_left_out: tuple[str, ...] = (),
    ) -> None:
        if tuple(layout.shape) != tuple(grid.shape):
            raise ValueError(f"a block layout of shape {layout.shape} does not fit a sweep of shape {grid.shape}")
        self.path = FilePath(path)
        self.laws = tuple(laws)
        self.grid = grid
        self.layout = layout
        self._file: Any = None  # the h5py File once created
        self._written: list[tuple[int, int, int, int]] = []  # (law index, start, stop, steps)
        self._step_variables: dict[str, int] = {}  # name: axis of step
        self._step_integers: dict[str, tuple[int, ...]] = {}  # name: chunk shape
        self._classes: dict[str, str] = {}
        #: Per law, the engines its chunks report (each chunk's ``engine`` attribute).
        self._engines: dict[str, list[str]] = {}
        self._direct: list[str] = []  # variables filled by direct chunk writes
        self._length = 0
        self._held = HeldEventTables(tuple(unmet_events_left_out))
        self._sizes: dict[str, int] = {}

    @property
    def sweep(self) -> tuple[str, ...]:
        return tuple(self.grid.sweep)

    # -- creation -------------------------------------------------------------------------
    def _create(self, template: "xr.Dataset") -> None:
        import h5py
        import netCDF4

        handle = netCDF4.Dataset(self.path, "w", format="NETCDF4")
        try:
            self._define_all(handle, template)
        finally:
            handle.close()
        self._file = h5py.File(self.path, "r+")
        self._check_pipelines()

    def _check_pipelines(self) -> None:
        """The encoder writes chunks for :data:`FILTER_PIPELINE`: refuse a netCDF library that set others."""
        for name in self._direct:
            plist = self._file[name].id.get_create_plist()
            filters = tuple(plist.get_filter(i)[0] for i in range(plist.get_nfilters()))
            if filters != FILTER_PIPELINE:
                import netCDF4

                raise RuntimeError(
                    f"{self.path}: netCDF-C {netCDF4.__netcdf4libversion__} gave variable {name!r} the HDF5 "
                    f"filters {filters}, not {FILTER_PIPELINE} (Fletcher-32, shuffle, deflate) that chunked "
                    "runs write; run without chunks or with another netCDF4 version"
                )

    def _define_all(self, handle: Any, template: "xr.Dataset") -> None:
        sizes = {"law": len(self.laws), **{name: values.size for name, values in self.grid.sweep.items()}}
        handle.createDimension("law", len(self.laws))
        for name, values in self.grid.sweep.items():
            handle.createDimension(name, values.size)
        for name, size in template.sizes.items():
            if name in ("law", CASE_DIMENSION):
                continue
            handle.createDimension(name, None if name == "step" else size)
            sizes[name] = size
        attrs = dict(template.attrs)
        attrs["created"] = _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds")
        handle.setncatts(attrs)

        index_names = set(template.dims) | set(self.grid.sweep) | {"law"}
        auxiliary = [name for name in template.coords if name not in index_names]
        attached: set[str] = set()
        for name, variable in template.variables.items():
            if name == CASE_DIMENSION:
                continue
            dims = variable_dims(variable.dims, self.sweep)
            attrs = dict(variable.attrs)
            if name in template.data_vars:
                coordinates = [c for c in auxiliary if set(template[c].dims) <= set(variable.dims)]
                attached.update(coordinates)
                if coordinates:
                    attrs["coordinates"] = " ".join(coordinates)
            chunk = variable_chunk(dims, sizes, self.layout, self.sweep) if is_encoded(variable) else None
            fill = integer_fill_value(str(name)) if name in template.data_vars and variable.dtype.kind in "iu" else None
            if chunk is not None and self._held.holds(str(name)):
                self._held.define_later(str(name), variable.dtype, dims, attrs, chunk, fill)
                continue
            if chunk is not None:
                self._direct.append(str(name))
            self._define(handle, str(name), variable.dtype, dims, attrs, name in index_names, sizes, chunk, fill)
            if "step" in dims:
                self._step_variables[str(name)] = dims.index("step")
                if chunk is not None and variable.dtype.kind in "iu":
                    self._step_integers[str(name)] = chunk
            if "law" not in dims and name != "step":
                handle.variables[name][:] = variable.values.astype(object) if variable.dtype.kind == "U" else variable.values
        self._sizes = sizes
        unattached = [c for c in auxiliary if c not in attached]
        if unattached:
            handle.setncattr("coordinates", " ".join(unattached))
        for name, values in self.grid.sweep.items():
            self._define(handle, name, values.dtype, (name,), parameter_attributes(name), True, sizes, None)
            handle.variables[name][:] = values
        handle.variables["law"][:] = np.array(self.laws, dtype=object)

    @staticmethod
    def _define(
        handle: Any, name: str, dtype: np.dtype, dims: tuple[str, ...], attrs: dict[str, Any], is_index: bool,
        sizes: dict[str, int], chunk: tuple[int, ...] | None, integer_fill: int | None = None,
    ) -> None:
        numeric = dtype.kind in "biuf"
        options: dict[str, Any] = {}
        if chunk is not None:
            options.update(COMPRESSION, chunksizes=list(chunk))
        elif numeric and dims and math.prod(STEP_CHUNK if d == "step" else sizes[d] for d in dims) >= MIN_COMPRESSED_SIZE:
            options.update(COMPRESSION)
        if dtype.kind == "f" and not is_index:
            options["fill_value"] = np.nan
        elif integer_fill is not None:
            options["fill_value"] = dtype.type(integer_fill)
        variable = handle.createVariable(name, dtype if numeric else str, dims, **options)
        variable.setncatts(attrs)

    def _extend_steps(self, steps: int) -> None:
        """Grow the ``step`` dimension of every variable that has it to ``steps``."""
        if steps <= self._length:
            return
        for name, axis in self._step_variables.items():
            self._file[name].resize(steps, axis=axis)
        self._length = steps

    # -- filling --------------------------------------------------------------------------
    def append(self, encoded: EncodedChunk) -> None:
        """Copy an encoded chunk of cases (:func:`encode_chunk`) into the archive."""
        if encoded.law not in self.laws:
            raise ValueError(f"law {encoded.law!r} is not one of this archive's laws {self.laws}")
        blocks = self.layout.blocks(encoded.start, encoded.stop)
        if self._file is None:
            self._create(encoded.template)
        k = self.laws.index(encoded.law)
        self._extend_steps(encoded.steps)
        for name, offset, data in encoded.chunks:
            if name in self._held.definitions:
                self._held.keep(name, (k, *offset), data)
            else:
                self._file[name].id.write_direct_chunk((k, *offset), data)
        self._held.record_met(encoded.events_met)
        for name, values in encoded.strings.items():
            for block in blocks:
                box = tuple(slice(o, o + n) for o, n in zip(block.origin, block.shape))
                target = values[block.start - encoded.start : block.stop - encoded.start]
                self._file[name][(slice(k, k + 1), *box)] = target.reshape((1, *block.shape, *values.shape[1:])).astype(object)
        self._classes[encoded.law] = str(encoded.template["law_class"].values[0])
        engine = str(encoded.template.attrs.get("engine", "")).partition(": ")[2]
        engines = self._engines.setdefault(encoded.law, [])
        if engine and engine not in engines:
            engines.append(engine)
        self._written.append((k, encoded.start, encoded.stop, encoded.steps))

    def _pad_integers(self) -> None:
        """Write the chunks of integer step variables past each chunk's last step, as -1."""
        for name, chunk in self._step_integers.items():
            dataset = self._file[name]
            after_sweep = 1 + len(self.sweep)
            step_axis = self._step_variables[name] - after_sweep
            rest_shape, rest_chunk = dataset.shape[after_sweep:], chunk[after_sweep:]
            padding = deflate_shuffled(np.full(chunk, INTEGER_PADDING, dataset.dtype))
            for k, start, stop, steps in self._written:
                free = math.ceil(steps / rest_chunk[step_axis]) * rest_chunk[step_axis]
                ranges = [range(0, n, c) for n, c in zip(rest_shape, rest_chunk)]
                ranges[step_axis] = range(free, self._length, rest_chunk[step_axis])
                for block in self.layout.blocks(start, stop):
                    for position in itertools.product(*ranges):
                        dataset.id.write_direct_chunk((k, *block.origin, *position), padding)

    def close(self) -> None:
        """Write the ``step`` coordinate, pad integer step variables with -1, write the
        law classes and the digests, close the file."""
        if self._file is None:
            raise ValueError(f"{self.path}: no chunk was appended; an archive needs at least one")
        missing = [law for law in self.laws if law not in self._classes]
        if missing:
            raise ValueError(f"{self.path}: no chunk of law(s) {', '.join(missing)} was appended")
        if "step" in self._file:
            self._file["step"][:] = np.arange(self._length, dtype=self._file["step"].dtype)
        self._pad_integers()
        self._file.close()
        self._file = None
        import h5py
        import netCDF4

        # The tables of the held-back events some case met (the lean default); their filters checked.
        written = self._held.write(self.path, self._define, self._sizes)
        if written:
            self._file, self._direct = h5py.File(self.path, "r"), written
            try:
                self._check_pipelines()
            finally:
                self._file.close()
                self._file = None

        with netCDF4.Dataset(self.path, "a") as handle:
            # As in a whole run's Dataset (ncstab.paths.PathResult.to_dataset): every law's class.
            handle.variables["law_class"][:] = np.array([self._classes[law] for law in self.laws], dtype=object)
            handle.setncattr("law_class", "; ".join(f"{law}: {self._classes[law]}" for law in self.laws))
            if any(self._engines.values()):
                handle.setncattr(
                    "engine", "; ".join(f"{law}: {' / '.join(self._engines.get(law, []))}" for law in self.laws)
                )
        digests = self._digests()
        with netCDF4.Dataset(self.path, "a") as handle:
            handle.setncattr(DIGEST_ATTRIBUTE, format_digests(digests))

    def _digests(self) -> dict[str, str]:
        """SHA-256 of each variable without HDF5's checksum filter, as the archive's reader sees it."""
        from ncstab.studies.archive import normalise_dataset
        from ncstab.studies.verification import open_undecoded_fill

        with open_undecoded_fill(self.path) as dataset:
            names = [name for name, variable in dataset.variables.items() if not variable.encoding.get("fletcher32")]
            on_disk = normalise_dataset(dataset[names] if names else dataset)
            return {str(name): variable_digest(on_disk.variables[name].values) for name in names}

    def abort(self) -> None:
        """Close the file without completing it (the caller removes it)."""
        if self._file is not None:
            self._file.close()
            self._file = None
