"""Is a file a readable ncstab archive?  Opening, digests and invariants.

:func:`~ncstab.studies.open_study` and
:func:`~ncstab.studies.open_study_lazily` open a file with :func:`opened`,
check the digest attributes with :func:`verified` and the invariants of an
archive with :func:`check_archive`; each raises
:class:`~ncstab.studies.errors.ArchiveError` saying what is wrong, which
``ncstab info`` and ``ncstab plot`` turn into one line and exit code 2.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
from collections.abc import Iterator
from pathlib import Path as FilePath
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.studies.checksums import DIGEST_ATTRIBUTE, parse_digests, variable_digest
from ncstab.studies.errors import ArchiveError
from ncstab.studies.figure_kinds import FIGURE_KINDS

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

__all__ = ["REQUIRED_VARIABLES", "check_archive", "check_digests", "check_study_text", "existing_file", "known_status", "opened",
           "remember_valid_study", "verified"]

#: Variables every archive has (with the coordinate ``law``).
REQUIRED_VARIABLES = ("status", "message", "n_steps")
#: The cache's folder of study texts found valid (:func:`check_study_text`).
VALID_STUDIES_KIND = "valid_studies"
#: A failure reason or an event name: lower-case words joined by '_'.
_WORD = re.compile(r"[a-z][a-z0-9_]*")


def existing_file(path: str | os.PathLike[str]) -> FilePath:
    """``path`` as a Path, once it is known to be a non-empty file.

    Raises
    ------
    ArchiveError
        No such file, a directory, or an empty file.
    """
    path = FilePath(path)
    if not path.exists():
        raise ArchiveError(path, "no such file")
    if path.is_dir():
        raise ArchiveError(path, "it is a directory")
    if path.stat().st_size == 0:
        raise ArchiveError(path, "the file is empty")
    return path


@contextlib.contextmanager
def opened(path: str | os.PathLike[str]) -> Iterator["xr.Dataset"]:
    """The file open as a (lazy) Dataset, closed on exit.

    Raises
    ------
    ArchiveError
        No such file, a directory, or a file netCDF cannot open (empty,
        truncated, not NetCDF/HDF5).
    """
    path = existing_file(path)
    try:
        dataset = open_undecoded_fill(path)
    except Exception as error:  # netCDF's errors are OSError, RuntimeError, ValueError...
        raise ArchiveError(path, f"netCDF cannot open it ({error})") from None
    with dataset:
        yield dataset


#: Attributes of the CF missing-value convention: in the file, not in the Dataset.
FILL_ATTRIBUTES = ("_FillValue", "missing_value")


def open_undecoded_fill(path: str | os.PathLike[str]) -> "xr.Dataset":
    """A NetCDF file open with xarray, integer variables kept integers.

    xarray would turn an integer variable with a ``_FillValue`` into floats
    with NaN; here no value is masked (every floating-point fill of an ncstab
    archive is NaN already) and the ``_FillValue`` attributes are left out of
    the Dataset, as they are out of the Dataset that was written.
    """
    import xarray as xr

    from ncstab.studies.archive import ENGINE

    dataset = xr.open_dataset(path, engine=ENGINE, mask_and_scale=False)
    for variable in dataset.variables.values():
        for name in FILL_ATTRIBUTES:
            variable.attrs.pop(name, None)
    return dataset


def check_digests(dataset: Any, path: str | os.PathLike[str]) -> None:
    """Check the variables named in the digest attribute against their SHA-256.

    ``dataset`` is an ``xarray.Dataset`` or anything with the same ``attrs``
    and ``variables[name].values`` (:class:`~ncstab.studies.quick_read.ArchiveContents`).
    An archive written before checksums has no such attribute and passes.

    Raises
    ------
    ArchiveError
        A digest differs or a named variable is missing (names it), the
        attribute cannot be read, or a variable cannot be read.
    """
    text = dataset.attrs.get(DIGEST_ATTRIBUTE)
    if text is None:
        return
    try:
        digests = parse_digests(text)
    except ValueError as error:
        raise ArchiveError(path, f"attribute {DIGEST_ATTRIBUTE!r} is damaged: {error}") from None
    for name, expected in digests.items():
        if name not in dataset.variables:
            raise ArchiveError(path, f"variable {name!r}, listed in {DIGEST_ATTRIBUTE!r}, is missing")
        try:
            found = variable_digest(dataset.variables[name].values)
        except Exception as error:
            raise ArchiveError(path, f"variable {name!r} cannot be read (damaged data?): {error}") from None
        if found != expected:
            raise ArchiveError(path, f"variable {name!r} does not match its checksum: the file is damaged")


def verified(dataset: "xr.Dataset", path: str | os.PathLike[str]) -> "xr.Dataset":
    """``dataset`` with the digests of its attribute checked (:func:`check_digests`), the attribute removed.

    The variables named in :data:`~ncstab.studies.checksums.DIGEST_ATTRIBUTE`
    are read and their SHA-256 compared; the others are checked by HDF5
    (Fletcher-32).

    Raises
    ------
    ArchiveError
        As :func:`check_digests`.
    """
    if dataset.attrs.get(DIGEST_ATTRIBUTE) is None:
        return dataset
    check_digests(dataset, path)
    dataset = dataset.copy(deep=False)
    dataset.attrs = {k: v for k, v in dataset.attrs.items() if k != DIGEST_ATTRIBUTE}
    return dataset


def check_study_text(study: str, path: str | os.PathLike[str]) -> None:
    """Check that an archive's ``study`` attribute is a valid study file.

    Its user laws are built from their formulas (bounded: :mod:`ncstab.laws.formula`)
    but not classified.  Parsing a study needs the law catalogue and sympy (a second): a text found
    valid is remembered in the cache directory (:mod:`ncstab.cache`, keyed by
    the SHA-256 of the text and the ncstab version), so the next archive of
    the same study -- and the next ``ncstab info`` -- skips the parse.

    Raises
    ------
    ArchiveError
        The text is not a valid study file (the first error it has).
    """
    from ncstab.cache import read_entry

    if read_entry(VALID_STUDIES_KIND, _study_key(study)) == {"valid": True}:
        return
    from ncstab.studies.study import StudyFileError, parse_study
    from ncstab.studies.user_laws import without_classification

    try:
        with without_classification():  # the archive stores the classes: no symbolic work to read it
            parse_study(study, "<archive>")
    except StudyFileError as error:
        if set(error.fields) == {"system.file"}:  # a packing file that is elsewhere now: the study
            return  # was valid when it ran (its archive holds what it computed, checksummed)
        field, message = error.errors[0]
        raise ArchiveError(path, f"its 'study' attribute is not a valid study file ({field}: {message})") from None


def remember_valid_study(study: str) -> None:
    """Remember a study text as valid (it parsed), so that :func:`check_study_text` of
    an archive of that study skips the parse: :func:`~ncstab.studies.parse_study` calls
    it for every text it validates, so ``ncstab plot``/``info`` of the archives of a
    study run here (``ncstab run``, ``run_study``, ``run_study_chunked``) import no sympy."""
    from ncstab.cache import write_entry

    write_entry(VALID_STUDIES_KIND, _study_key(study), {"valid": True})


def _study_key(study: str) -> str:
    """The cache key of a study text: SHA-256 of the ncstab version and the text."""
    import ncstab

    return hashlib.sha256(f"ncstab {ncstab.__version__}\n{study}".encode()).hexdigest()


def known_status(status: str) -> bool:
    """Whether a case status is one of ``finished``, ``stopped:<event>``, ``failed:<reason>``."""
    from ncstab.paths.programme import EVENTS

    if status == "finished":
        return True
    kind, _, detail = status.partition(":")
    if kind == "stopped":
        return detail in EVENTS
    return kind == "failed" and bool(_WORD.fullmatch(detail))


def check_archive(dataset: "xr.Dataset", path: str | os.PathLike[str]) -> None:
    """Check the invariants of an ncstab archive.

    * the variables ``status``, ``message``, ``n_steps`` and the coordinate
      ``law``, ``status`` and ``n_steps`` over the same dimensions, ``law`` first;
    * the attribute ``study`` is a valid study file (it parses), or empty (a
      Dataset of :func:`ncstab.follow`, written from Python);
    * 0 <= ``n_steps`` <= the length of ``step`` (0 without ``step``);
    * every status is ``finished``, ``stopped:<event>`` or ``failed:<reason>``;
    * the ``figures`` attribute, if any, names figure kinds ncstab draws.

    Raises
    ------
    ArchiveError
        Naming the first invariant that does not hold.
    """
    missing = [name for name in REQUIRED_VARIABLES if name not in dataset.variables]
    if missing or "law" not in dataset.coords:
        what = ", ".join(repr(name) for name in missing + ([] if "law" in dataset.coords else ["law"]))
        raise ArchiveError(path, f"no {what} variable: not an archive written by ncstab")
    dims = dataset["status"].dims
    if dataset["n_steps"].dims != dims or not dims or dims[0] != "law":
        raise ArchiveError(
            path, f"'status' {dims} and 'n_steps' {dataset['n_steps'].dims} should have the same "
            "dimensions, 'law' first"
        )
    study = dataset.attrs.get("study")
    if not isinstance(study, str):
        raise ArchiveError(path, "no 'study' attribute (the study file it was run from)")
    if study:  # "": a path followed from Python (ncstab.follow), without a study file
        check_study_text(study, path)
    n_steps = np.asarray(dataset["n_steps"].values)
    steps = int(dataset.sizes.get("step", 0))
    if n_steps.dtype.kind not in "iu":
        raise ArchiveError(path, f"variable 'n_steps' holds {n_steps.dtype} values, not whole numbers")
    outside = (n_steps < 0) | (n_steps > steps)
    if outside.any():
        raise ArchiveError(
            path, f"variable 'n_steps' has {int(n_steps[outside].ravel()[0])} stored states where the "
            f"'step' dimension has {steps}"
        )
    statuses = np.unique(np.asarray(dataset["status"].values).astype(str))
    unknown = [status for status in statuses.tolist() if not known_status(status)]
    if unknown:
        raise ArchiveError(
            path, f"variable 'status' holds {unknown[0]!r}, not finished, stopped:<event> or failed:<reason>"
        )
    figures = dataset.attrs.get("figures")
    if figures is not None:
        kinds = [k.strip() for k in str(figures).split(",") if k.strip()] if isinstance(figures, str) else None
        bad = [k for k in kinds if k not in FIGURE_KINDS] if kinds is not None else [repr(figures)]
        if bad:
            raise ArchiveError(path, f"attribute 'figures' names {bad[0]!r}, not a figure kind ncstab draws")
