"""The NetCDF archive of a study: written atomically, verified, read back identical.

:func:`write_dataset` writes to a temporary file beside the destination and
renames it over the destination only once the file is complete, so an
interrupted run never leaves half a file and never spoils a good archive; a
temporary left by a killed process is removed by the next run on that output
(:mod:`ncstab.studies.atomic_files`).  Every variable carries a checksum
(:mod:`ncstab.studies.checksums`).  :func:`open_study` reads an archive fully
into memory, checks the checksums and the archive's invariants
(:mod:`ncstab.studies.verification`) and raises
:class:`~ncstab.studies.errors.ArchiveError` for anything that is not a
readable ncstab archive; the Dataset it gives is identical
(``xarray.testing.assert_identical``) to the one written.
"""

from __future__ import annotations

import contextlib
import os
from collections.abc import Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.studies.atomic_files import atomic_destination
from ncstab.studies.checksums import DIGEST_ATTRIBUTE, format_digests, variable_digest
from ncstab.studies.errors import ArchiveError, write_error

if TYPE_CHECKING:  # pragma: no cover - xarray is imported when an archive is used
    import xarray as xr

__all__ = [
    "COMPRESSION",
    "ENGINE",
    "INTEGER_FILL_VALUE",
    "LOAD_ALIAS",
    "integer_fill_value",
    "normalise_dataset",
    "open_study",
    "open_study_lazily",
    "with_load_level",
    "write_dataset",
]

#: NetCDF library used for reading and writing (NetCDF-4/HDF5 files).
ENGINE = "netcdf4"
#: Encoding of numeric variables: deflate with byte shuffle, level 1 (measured on a
#: 16,384-case archive: 25 % less compression time than level 4 for a file 3 % larger),
#: and HDF5's Fletcher-32 checksum of every chunk, verified by HDF5 when it is read.
COMPRESSION = {"zlib": True, "complevel": 1, "shuffle": True, "fletcher32": True}
#: Numeric variables with fewer elements are stored uncompressed: deflate gains
#: nothing on them and each chunked HDF5 variable costs a few kB of index (a checksum
#: filter would make them chunked too: they carry a digest attribute instead).
MIN_COMPRESSED_SIZE = 64
#: ``_FillValue`` of the integer data variables: -1, which no count (``n_steps``,
#: ``accepted_steps``) or stage index (``stage``, ``<event>_stage``) takes, and
#: which pads ``stage`` past a case's last step and ``<event>_stage`` where the
#: event never occurs.
INTEGER_FILL_VALUE = -1
#: Integer data variables for which -1 is a value (``branch_index``: the branch
#: taken one way): their ``_FillValue`` is netCDF's default for int32, which
#: none of them takes.
NETCDF_DEFAULT_INT_FILL = -2147483647
_MINUS_ONE_IS_A_VALUE = ("branch_index",)


def _normal_attribute(value: Any) -> Any:
    """An attribute value as netCDF gives it back: Python scalars, numpy arrays, str."""
    if isinstance(value, np.ndarray):
        if value.ndim == 0:
            return value.item()
        if value.size == 1 and value.dtype.kind in "biuf":
            return value.reshape(()).item()
        return value
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, (list, tuple)) and value and all(
        isinstance(v, (int, float, np.number)) and not isinstance(v, bool) for v in value
    ):
        return np.asarray(value) if len(value) > 1 else _normal_attribute(np.asarray(value[0]))
    return value


def _normal_attributes(attrs: dict[str, Any]) -> dict[str, Any]:
    return {key: _normal_attribute(value) for key, value in attrs.items()}


def normalise_dataset(dataset: xr.Dataset) -> xr.Dataset:
    """The on-disk representation of a Dataset, as :func:`open_study` returns it.

    Strings of any width or kind (object arrays of ``str``, bytes) become numpy
    unicode arrays; numpy scalar attributes become Python scalars; encodings
    are dropped.  Numbers keep their dtypes (int32 stays int32).

    Returns
    -------
    xarray.Dataset
        A new Dataset; the argument is not modified.
    """
    dataset = dataset.copy(deep=False)
    replacements = {}
    for name, variable in dataset.variables.items():
        if variable.dtype.kind in "OS":
            values = variable.values
            if variable.dtype.kind == "S":
                values = np.char.decode(values, "utf-8")
            else:
                flat = [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in values.ravel()]
                values = np.array(flat, dtype=str).reshape(values.shape) if flat else values.astype(str)
            replacements[name] = variable.copy(data=values)
    if replacements:
        index_names = [name for name in replacements if name in dataset.dims]
        others = {k: v for k, v in replacements.items() if k not in index_names}
        if index_names:
            dataset = dataset.assign_coords({k: replacements[k] for k in index_names})
        for name, variable in others.items():
            if name in dataset.coords:
                dataset = dataset.assign_coords({name: variable})
            else:
                dataset[name] = variable
    dataset.attrs = _normal_attributes(dataset.attrs)
    for variable in dataset.variables.values():
        variable.attrs = _normal_attributes(variable.attrs)
        variable.encoding = {}
    return dataset


def integer_fill_value(name: str) -> int:
    """The ``_FillValue`` an integer data variable is written with (CF: the value that
    means "no value"): :data:`INTEGER_FILL_VALUE` but where -1 is a value."""
    return NETCDF_DEFAULT_INT_FILL if name in _MINUS_ONE_IS_A_VALUE else INTEGER_FILL_VALUE


def _is_compressed(variable: Any) -> bool:
    """Whether :func:`write_dataset` compresses (and checksums with Fletcher-32) a variable."""
    return variable.dtype.kind in "biuf" and variable.ndim > 0 and variable.size >= MIN_COMPRESSED_SIZE


def _encoding(dataset: xr.Dataset) -> dict[str, dict[str, Any]]:
    """Compression for numeric arrays; strings stay NetCDF strings, readable with ncdump.

    Coordinate variables (``gamma``, ``step``...) get no ``_FillValue``: CF
    forbids missing values in them.  Integer data variables get
    :func:`integer_fill_value` (floating-point ones get NaN from xarray).
    """
    encoding: dict[str, dict[str, Any]] = {}
    for name, variable in dataset.variables.items():
        if variable.dtype.kind not in "biuf":
            continue
        if _is_compressed(variable):
            encoding[name] = dict(COMPRESSION)
        if name in dataset.dims:
            encoding.setdefault(name, {})["_FillValue"] = None
        elif name in dataset.data_vars and variable.dtype.kind in "iu":
            encoding.setdefault(name, {})["_FillValue"] = variable.dtype.type(integer_fill_value(str(name)))
    return encoding


def _with_digests(dataset: xr.Dataset) -> xr.Dataset:
    """``dataset`` with the SHA-256 of every variable HDF5 does not checksum, as one attribute.

    Those are the strings and the numeric variables too small to be compressed
    (:data:`MIN_COMPRESSED_SIZE`); the others carry HDF5's Fletcher-32 filter.
    The digests go in one global attribute
    (:data:`~ncstab.studies.checksums.DIGEST_ATTRIBUTE`, measured: an attribute
    on each variable would make a 0.5 MB archive 26 % larger).  The argument is
    not modified.
    """
    digests = {
        str(name): variable_digest(variable.values)
        for name, variable in dataset.variables.items()
        if not _is_compressed(variable)
    }
    dataset = dataset.copy(deep=False)
    dataset.attrs = {**dataset.attrs, DIGEST_ATTRIBUTE: format_digests(digests)}
    return dataset


def write_dataset(dataset: xr.Dataset, path: str | os.PathLike[str]) -> FilePath:
    """Write a study's Dataset to a NetCDF-4 archive, atomically.

    The file is written to a temporary name in the destination's directory
    (created if needed) and renamed to ``path`` once complete
    (:func:`os.replace`).  If anything fails, the temporary file is removed and
    the error re-raised: no half-written archive is left and an existing
    archive at ``path`` is untouched.

    Numeric arrays are compressed (zlib with shuffle, level 1, and HDF5's
    Fletcher-32 checksum; arrays of fewer than :data:`MIN_COMPRESSED_SIZE`
    elements are stored plain); string variables (``status``, ``message``, the
    ``law`` and ``law_class`` coordinates) are NetCDF strings, readable with
    ``ncdump``.  The SHA-256 of each variable without the checksum filter is
    kept in the attribute :data:`~ncstab.studies.checksums.DIGEST_ATTRIBUTE`,
    which :func:`open_study` checks and removes.

    Parameters
    ----------
    dataset
        Typically the result of :func:`ncstab.studies.run_study`.
    path
        Destination archive (``.nc``).

    Returns
    -------
    pathlib.Path
        The archive written.

    Raises
    ------
    ncstab.studies.errors.DiskFullError, OutputNotWritableError, WriteError
        The file system refused the write (the error it raised is the cause).
    """
    destination = FilePath(path)
    on_disk = normalise_dataset(dataset)
    encoding = _encoding(on_disk)
    on_disk = _with_digests(on_disk)
    try:
        destination.parent.mkdir(parents=True, exist_ok=True)
        with atomic_destination(destination, ".tmp") as temporary:
            on_disk.to_netcdf(temporary, mode="w", format="NETCDF4", engine=ENGINE, encoding=encoding)
    except (OSError, RuntimeError) as error:
        named = write_error(error, destination)
        if named is None:
            raise
        raise named from error
    return destination


#: The alias of the variable ``load``: ``ds.load`` is xarray's ``Dataset.load`` method,
#: ``ds.load_level`` the load parameter at every stored state.
LOAD_ALIAS = "load_level"


def with_load_level(dataset: xr.Dataset) -> xr.Dataset:
    """``dataset`` with :data:`LOAD_ALIAS` beside ``load`` (the same values), where it has
    ``load`` and not the alias: written in every new archive, made on reading an older one."""
    if "load" not in dataset.data_vars or LOAD_ALIAS in dataset.variables:
        return dataset
    from ncstab.paths.variables import VARIABLES

    units, long_name, description = VARIABLES[LOAD_ALIAS]
    alias = dataset["load"].variable.copy(deep=False)
    alias.attrs = {"long_name": long_name, "description": description, "units": units}
    alias.encoding = {}
    return dataset.assign({LOAD_ALIAS: alias})


def open_study(path: str | os.PathLike[str], fill_missing_events: bool = False) -> xr.Dataset:
    """Read an archive written by :func:`write_dataset` fully into memory, verified.

    The file is closed on return.  The Dataset is identical
    (``xarray.testing.assert_identical``) to the one written: same variables,
    dtypes, coordinates (string ones included), statuses, events and
    attributes.  Every variable is checked against its checksum (HDF5's
    Fletcher-32, or its digest in an attribute, which is not returned), and the
    archive against its invariants
    (:func:`ncstab.studies.verification.check_archive`).

    Parameters
    ----------
    path
        A ``.nc`` archive.
    fill_missing_events
        Put back the tables of the events a lean archive left out because no
        case meets them (its attribute ``events_left_out``): NaN, their
        ``_stage`` -1, as an archive with every variable holds them
        (:func:`~ncstab.studies.archive_selection.fill_left_out_events`); the
        attribute is then removed.

    Returns
    -------
    xarray.Dataset

    Raises
    ------
    ncstab.studies.errors.ArchiveError
        The file is missing, not NetCDF, damaged (a checksum fails), not
        written by ncstab, or breaks an invariant; the message says which.
    """
    from ncstab.studies.verification import check_archive, opened, verified

    with opened(path) as dataset:
        for name, variable in dataset.variables.items():
            try:
                variable.load()
            except Exception as error:  # HDF5 checksum, truncated file...: say which variable
                raise ArchiveError(path, f"variable {name!r} cannot be read (damaged data?): {error}") from None
        result = verified(normalise_dataset(dataset), path)
    check_archive(result, path)
    result = with_load_level(result)
    if fill_missing_events:
        from ncstab.studies.archive_selection import fill_left_out_events

        result = fill_left_out_events(result)
    return result


@contextlib.contextmanager
def open_study_lazily(path: str | os.PathLike[str]) -> Iterator[xr.Dataset]:
    """An archive open for reading, its arrays loaded only when used; closed on exit.

    For archives too large to hold in memory (a big sweep): a figure that
    needs a few variables reads only those.  The Dataset is in the
    representation :func:`open_study` gives (string variables are read at
    once); the invariants and the digests of the variables that carry one
    (strings and small numeric arrays) are checked on opening, and HDF5 checks
    the Fletcher-32 checksum of each chunk as it is read.

    Yields
    ------
    xarray.Dataset
        Valid inside the ``with`` block only.

    Raises
    ------
    ncstab.studies.errors.ArchiveError
        As :func:`open_study`, for what can be seen on opening.
    """
    from ncstab.studies.verification import check_archive, opened, verified

    with opened(path) as dataset:
        result = verified(normalise_dataset(dataset), path)
        check_archive(result, path)
        yield with_load_level(result)
