"""The NetCDF archive of a study: written atomically, read back identical.

:func:`write_dataset` writes to a temporary file beside the destination and
renames it over the destination only once the file is complete, so an
interrupted run never leaves half a file and never spoils a good archive.
:func:`open_study` reads an archive fully into memory; the Dataset it gives is
identical (``xarray.testing.assert_identical``) to the one written.
"""

from __future__ import annotations

from collections.abc import Iterator

import contextlib
import os
import tempfile
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:  # pragma: no cover - xarray is imported when an archive is used
    import xarray as xr

__all__ = [
    "atomic_destination",
    "COMPRESSION",
    "ENGINE",
    "normalise_dataset",
    "open_study",
    "open_study_lazily",
    "write_dataset",
]

#: NetCDF library used for reading and writing (NetCDF-4/HDF5 files).
ENGINE = "netcdf4"
#: Encoding of numeric variables: deflate with byte shuffle, level 1 (measured on a
#: 16,384-case archive: 25 % less compression time than level 4 for a file 3 % larger).
COMPRESSION = {"zlib": True, "complevel": 1, "shuffle": True}
#: Numeric variables with fewer elements are stored uncompressed: deflate gains
#: nothing on them and each chunked HDF5 variable costs a few kB of index.
MIN_COMPRESSED_SIZE = 64


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


def _encoding(dataset: xr.Dataset) -> dict[str, dict[str, Any]]:
    """Compression for numeric arrays; strings stay NetCDF strings, readable with ncdump.

    Coordinate variables (``gamma``, ``step``...) get no ``_FillValue``: CF
    forbids missing values in them.
    """
    encoding: dict[str, dict[str, Any]] = {}
    for name, variable in dataset.variables.items():
        if variable.dtype.kind not in "biuf":
            continue
        if variable.ndim > 0 and variable.size >= MIN_COMPRESSED_SIZE:
            encoding[name] = dict(COMPRESSION)
        if name in dataset.dims:
            encoding.setdefault(name, {})["_FillValue"] = None
    return encoding


def _default_mode() -> int:
    """File mode a plain ``open(..., "w")`` would give: 0o666 less the umask."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def write_dataset(dataset: xr.Dataset, path: str | os.PathLike[str]) -> FilePath:
    """Write a study's Dataset to a NetCDF-4 archive, atomically.

    The file is written to a temporary name in the destination's directory
    (created if needed) and renamed to ``path`` once complete
    (:func:`os.replace`).  If anything fails, the temporary file is removed and
    the error re-raised: no half-written archive is left and an existing
    archive at ``path`` is untouched.

    Numeric arrays are compressed (zlib with shuffle, level 1; arrays of fewer than
    :data:`MIN_COMPRESSED_SIZE` elements are stored plain); string variables
    (``status``, ``message``, the ``law`` and ``law_class`` coordinates) are
    NetCDF strings, readable with ``ncdump``.

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
    """
    destination = FilePath(path)
    destination.parent.mkdir(parents=True, exist_ok=True)
    on_disk = normalise_dataset(dataset)
    encoding = _encoding(on_disk)
    with atomic_destination(destination, ".nc.tmp") as temporary:
        on_disk.to_netcdf(temporary, mode="w", format="NETCDF4", engine=ENGINE, encoding=encoding)
    return destination


@contextlib.contextmanager
def atomic_destination(destination: FilePath, suffix: str = ".tmp") -> Iterator[FilePath]:
    """Yield a temporary path beside ``destination``; on success it replaces it.

    The temporary is synced to disk, given the default file mode and renamed
    over ``destination`` (:func:`os.replace`, atomic on one file system).  If
    anything fails -- an exception or an interrupt -- the temporary is removed
    and ``destination`` is left as it was: never a half-written file.
    """
    descriptor, name = tempfile.mkstemp(dir=destination.parent, prefix=f".{destination.stem}.", suffix=suffix)
    os.close(descriptor)
    temporary = FilePath(name)
    try:
        yield temporary
        with open(temporary, "rb+") as written:
            os.fsync(written.fileno())
        os.chmod(temporary, _default_mode())
        os.replace(temporary, destination)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def open_study(path: str | os.PathLike[str]) -> xr.Dataset:
    """Read an archive written by :func:`write_dataset` fully into memory.

    The file is closed on return.  The Dataset is identical
    (``xarray.testing.assert_identical``) to the one written: same variables,
    dtypes, coordinates (string ones included), statuses, events and attributes.

    Parameters
    ----------
    path
        A ``.nc`` archive.

    Returns
    -------
    xarray.Dataset
    """
    import xarray as xr

    with xr.open_dataset(path, engine=ENGINE) as dataset:
        dataset.load()
        return normalise_dataset(dataset)


@contextlib.contextmanager
def open_study_lazily(path: str | os.PathLike[str]) -> Iterator[xr.Dataset]:
    """An archive open for reading, its arrays loaded only when used; closed on exit.

    For archives too large to hold in memory (a big sweep): a figure that
    needs a few variables reads only those.  The Dataset is in the
    representation :func:`open_study` gives (string variables are read at once).

    Yields
    ------
    xarray.Dataset
        Valid inside the ``with`` block only.
    """
    import xarray as xr

    with xr.open_dataset(path, engine=ENGINE) as dataset:
        yield normalise_dataset(dataset)
