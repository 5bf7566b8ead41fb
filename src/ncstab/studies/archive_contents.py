"""An archive's attributes and small variables, read without xarray, verified as a whole.

``ncstab info`` summarises an archive from its statuses, messages, coordinates
and located events: a few small variables.  :func:`open_archive_contents`
reads them with netCDF4 alone (importing xarray, pandas and dask costs more
than the whole summary of a 16,384-case archive) and checks the archive as
:func:`~ncstab.studies.open_study` does, with the same messages
(:class:`~ncstab.studies.errors.ArchiveError`, exit code 2):

* the file opens (:func:`~ncstab.studies.verification.opened`'s checks);
* the digests of the strings and small variables
  (:func:`~ncstab.studies.verification.check_digests`) and the invariants
  (:func:`~ncstab.studies.verification.check_archive`);
* every compressed chunk of every variable is intact: its deflate stream
  inflates to the chunk's size and zlib's Adler-32 matches
  (:func:`check_compressed_chunks`, on the raw chunks through h5py, in
  threads: about 1 s of CPU for the 435 MB of a 16,384-case archive, where
  reading every variable through HDF5 takes 2 to 3 s and xarray's imports
  alone 1.5 s).

The values are those ``open_study`` gives for these variables (strings as
numpy unicode, floats with NaN where missing); an archive whose small
variables use encodings that this reader does not decode (scale factors,
booleans) is read through xarray instead (:func:`needs_xarray`); a
``_FillValue`` is left undecoded, as ``open_study`` leaves it.
"""

from __future__ import annotations

import contextlib
import os
import zlib
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any

import numpy as np

from ncstab.studies.checksums import DIGEST_ATTRIBUTE
from ncstab.studies.errors import ArchiveError

__all__ = ["ArchiveContents", "StoredVariable", "check_compressed_chunks", "needs_xarray", "open_archive_contents"]

#: Threads inflating chunks (zlib releases the GIL).
INFLATE_THREADS = min(4, os.cpu_count() or 1)
#: Bytes inflated at a time when a chunk is checked.
INFLATE_PIECE = 1 << 18
#: Encoding attributes this reader does not decode (xarray does).
_UNDECODED = ("scale_factor", "add_offset", "calendar")


class StoredVariable:
    """One variable of an open archive: its dimensions, its values read on first use.

    Parameters
    ----------
    variable
        A ``netCDF4.Variable`` (auto-masking off: floats keep their NaN fill).
    """

    def __init__(self, variable: Any) -> None:
        self._variable = variable
        self.dims: tuple[str, ...] = tuple(variable.dimensions)
        self._values: np.ndarray | None = None

    @property
    def values(self) -> np.ndarray:
        """The values as :func:`~ncstab.studies.open_study` gives them (strings as numpy unicode)."""
        if self._values is None:
            values = np.asarray(self._variable[...])
            if values.dtype.kind in "OS":
                flat = [v.decode("utf-8") if isinstance(v, bytes) else str(v) for v in values.ravel()]
                values = np.array(flat, dtype=str).reshape(values.shape) if flat else values.astype(str)
            self._values = values
        return self._values


class ArchiveContents:
    """The parts of an archive a summary reads, with the interface of an ``xarray.Dataset``
    that :func:`~ncstab.studies.verification.check_archive` and
    :mod:`ncstab.studies.summary` use: ``attrs``, ``sizes``, ``variables``, ``coords``,
    ``name in contents`` and ``contents[name]`` (a :class:`StoredVariable`).

    Parameters
    ----------
    dataset
        An open ``netCDF4.Dataset`` (kept open while the contents are used).
    """

    def __init__(self, dataset: Any) -> None:
        self.attrs: dict[str, Any] = {name: _attribute(dataset.getncattr(name)) for name in dataset.ncattrs()}
        self.sizes: dict[str, int] = {name: len(dimension) for name, dimension in dataset.dimensions.items()}
        self.variables: dict[str, StoredVariable] = {
            name: StoredVariable(variable) for name, variable in dataset.variables.items()
        }
        coordinates = {name for name in dataset.variables if name in dataset.dimensions}
        for variable in dataset.variables.values():
            if "coordinates" in variable.ncattrs():
                coordinates.update(str(variable.getncattr("coordinates")).split())
        self.coords: set[str] = coordinates & set(dataset.variables)

    def __contains__(self, name: object) -> bool:
        return name in self.variables

    def __getitem__(self, name: str) -> StoredVariable:
        return self.variables[name]


def _attribute(value: Any) -> Any:
    """An attribute as ``open_study`` gives it: Python scalars, numpy arrays, str."""
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "biuf":
        return value.reshape(()).item()
    if isinstance(value, np.generic):
        return value.item()
    return value


def needs_xarray(dataset: Any) -> bool:
    """Whether a small variable of ``dataset`` (a ``netCDF4.Dataset``) has an encoding that only
    xarray decodes: a scale factor or offset, a calendar, a ``dtype`` attribute (booleans)."""
    for variable in dataset.variables.values():
        attributes = set(variable.ncattrs())
        if attributes & set(_UNDECODED):
            return True
        # A _FillValue is not decoded by open_study either (integer variables stay integers,
        # ncstab.studies.verification.open_undecoded_fill): the raw values are the Dataset's.
        if "dtype" in attributes:  # booleans, enums: stored as integers, decoded by xarray
            return True
    return False


def check_compressed_chunks(path: str | os.PathLike[str]) -> None:
    """Check that every compressed chunk of the archive inflates, intact, to its full size.

    Each chunk's deflate stream is read raw (``h5py`` direct chunk read) and
    inflated in :data:`INFLATE_THREADS` threads: zlib checks its Adler-32, and
    the output must be the chunk's bytes plus the 4 bytes of its Fletcher-32
    where the variable has that filter.  The output is not kept.

    Raises
    ------
    ArchiveError
        ``variable 'u' cannot be read (damaged data?): ...`` for the first damaged chunk.
    """
    import h5py

    try:
        handle = h5py.File(path, "r")
    except OSError as error:
        raise ArchiveError(path, f"netCDF cannot open it ({error})") from None
    with handle, ThreadPoolExecutor(INFLATE_THREADS) as pool:
        for name, dataset in handle.items():
            if not isinstance(dataset, h5py.Dataset) or dataset.compression != "gzip" or dataset.chunks is None:
                continue
            expected = int(np.prod(dataset.chunks)) * dataset.dtype.itemsize + (4 if dataset.fletcher32 else 0)
            try:
                raw = [dataset.id.read_direct_chunk(dataset.id.get_chunk_info(index).chunk_offset)
                       for index in range(dataset.id.get_num_chunks())]
            except Exception as error:  # a damaged chunk index, a truncated file...
                raise ArchiveError(path, f"variable {name!r} cannot be read (damaged data?): {error}") from None
            for (mask, data), problem in zip(raw, pool.map(_inflate_problem, (data for _, data in raw),
                                                            [expected] * len(raw))):
                if problem is None and mask:
                    problem = f"a chunk stored without its filters (mask {mask})"
                if problem is not None:
                    raise ArchiveError(path, f"variable {name!r} cannot be read (damaged data?): {problem}")


def _inflate_problem(data: bytes, expected: int) -> str | None:
    """What is wrong with one deflated chunk, or ``None``.

    Inflated :data:`INFLATE_PIECE` bytes at a time and counted, not kept (a
    quarter less CPU than inflating whole chunks, whose buffers the system must
    map); zlib checks the stream's Adler-32 when it reaches its end.
    """
    inflator = zlib.decompressobj()
    size, pending = 0, data
    try:
        while not inflator.eof:
            piece = inflator.decompress(pending, INFLATE_PIECE)
            size += len(piece)
            pending = inflator.unconsumed_tail
            if not piece and not pending:
                break
    except zlib.error as error:
        return f"a chunk does not inflate ({error})"
    if not inflator.eof:
        return "a chunk ends before its deflate stream does"
    if size != expected:
        return f"a chunk inflates to {size} bytes, not {expected}"
    return None


@contextlib.contextmanager
def open_archive_contents(path: str | os.PathLike[str]) -> Iterator[ArchiveContents]:
    """An archive open for its small variables, verified (see the module); closed on exit.

    Yields
    ------
    ArchiveContents
        Valid inside the ``with`` block only.  ``None`` if the archive needs
        xarray to be decoded (:func:`needs_xarray`): read it with
        :func:`~ncstab.studies.open_study_lazily` instead.

    Raises
    ------
    ArchiveError
        As :func:`~ncstab.studies.open_study`: a file that is not a readable
        ncstab archive, with what is wrong.
    """
    import netCDF4

    from ncstab.studies.verification import check_archive, check_digests, existing_file

    path = existing_file(path)
    try:
        dataset = netCDF4.Dataset(path, "r")
    except Exception as error:  # OSError, RuntimeError...: as opened() says it
        raise ArchiveError(path, f"netCDF cannot open it ({error})") from None
    with dataset:
        try:
            dataset.set_auto_maskandscale(False)
            if needs_xarray(dataset):
                contents = None
            else:
                contents = ArchiveContents(dataset)
                check_digests(contents, path)
                contents.attrs.pop(DIGEST_ATTRIBUTE, None)
                check_archive(contents, path)
                if dataset.data_model.startswith("NETCDF4"):
                    check_compressed_chunks(path)
        except ArchiveError:
            raise
        except Exception as error:  # noqa: BLE001 - damaged metadata: netCDF raises AttributeError, RuntimeError...
            raise ArchiveError(path, f"its metadata cannot be read (damaged file?): {error}") from None
        yield contents  # type: ignore[misc]
