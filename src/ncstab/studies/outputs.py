"""Claiming an output before a run writes it: lock, leftovers of a killed run, finished parts.

:func:`claim_output` is what every run (in process or in chunks) does before
it computes anything: it takes the output's lock
(:class:`~ncstab.studies.locks.OutputLock`), removes the temporary files a
killed run left (:func:`~ncstab.studies.atomic_files.remove_stale_temporaries`),
and refuses to start over on top of the finished chunks of an earlier run
unless told to resume or to overwrite them.  :func:`check_existing_output` is
the contract on what is already at the output's path: nothing, or an ncstab
archive replaced only with ``--overwrite``; any other file (a foreign NetCDF
file, a text file, the study file itself), a symbolic link, a device or a fifo
is refused, untouched.
"""

from __future__ import annotations

import contextlib
import errno
import os
import shutil
import stat
from collections.abc import Callable, Iterator
from pathlib import Path as FilePath

from ncstab.studies.atomic_files import remove_stale_temporaries
from ncstab.studies.errors import OutputPathError, PartsExistError
from ncstab.studies.locks import OutputLock

__all__ = [
    "ARCHIVE_IN_PROGRESS",
    "check_existing_output",
    "claim_output",
    "finished_parts",
    "is_ncstab_archive",
    "parts_directory",
]

#: The archive being written by a chunked run, inside the parts directory until complete.
ARCHIVE_IN_PROGRESS = "archive.nc.tmp"
#: The first bytes of an HDF5 file (a NetCDF-4 archive) when its superblock is at offset 0.
HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
#: The global attribute every archive ncstab writes carries.
ARCHIVE_MARK = "ncstab_version"


def is_ncstab_archive(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a regular file that ncstab wrote as an archive.

    Only the file's first bytes (the HDF5 signature) and the names of its
    global attributes (:data:`ARCHIVE_MARK`) are read: nothing of a file
    that is not HDF5, and no variable.  A file that HDF5 cannot open is not
    an archive.
    """
    return _archive_study(path) is not None


def _archive_study(path: str | os.PathLike[str]) -> str | None:
    """The ``study`` attribute of an ncstab archive (``""`` if unreadable), or None if
    ``path`` is not one (see :func:`is_ncstab_archive`)."""
    try:
        with open(path, "rb") as handle:
            if handle.read(len(HDF5_SIGNATURE)) != HDF5_SIGNATURE:
                return None
        import h5py

        with h5py.File(path, "r") as archive:
            if ARCHIVE_MARK not in archive.attrs.keys():
                return None
            try:
                study = archive.attrs["study"]
            except Exception:  # noqa: BLE001 - a damaged attribute: an archive of no known study
                return ""
            return study.decode("utf-8", "replace") if isinstance(study, bytes) else str(study)
    except Exception:  # noqa: BLE001 - any file h5py cannot read is not an archive
        return None


def _kind(mode: int) -> str:
    """What a file that is neither regular nor a directory is, in words."""
    for test, name in ((stat.S_ISLNK, "a symbolic link"), (stat.S_ISCHR, "a character device"),
                       (stat.S_ISBLK, "a block device"), (stat.S_ISFIFO, "a fifo (named pipe)"),
                       (stat.S_ISSOCK, "a socket")):
        if test(mode):
            return name
    return "not a regular file"  # pragma: no cover - doors, whiteouts


def check_existing_output(
    output: str | os.PathLike[str],
    overwrite: bool = False,
    resume: bool = False,
    inputs: tuple[str | os.PathLike[str], ...] = (),
    study_text: str | None = None,
) -> None:
    """Refuse an output path that holds anything but an ncstab archive to be replaced.

    The contract of ``ncstab run`` (docs/when-things-go-wrong.md): the output
    is absent, or it is an ncstab archive (:func:`is_ncstab_archive`) and
    ``overwrite`` is given.  Nothing is opened for writing or changed here.

    Parameters
    ----------
    output
        The archive the run would write.
    overwrite
        ``--overwrite``: an existing ncstab archive may be replaced.
    resume
        ``--resume``: an existing archive is kept as it is if it is the
        complete archive of this study (``study_text``: the run does nothing),
        and replaced only by the run that finished parts continue (a run
        started with ``--overwrite`` and interrupted); any other is refused.
    inputs
        The run's study files: an output that is one of them is named as such.
    study_text
        The text of the study the run writes (for ``resume``).

    Raises
    ------
    OutputPathError
        (exit code 2) naming the output and what is there.
    """
    output = FilePath(output)
    try:
        mode = os.lstat(output).st_mode
    except OSError as error:
        if error.errno == errno.ENAMETOOLONG:
            raise OutputPathError(f"output path {str(output)[:40]!r}... is too long for the file system "
                                  f"({error.strerror})") from None
        return  # absent, or unreachable: check_output_path says why it cannot be written
    if stat.S_ISDIR(mode):
        raise OutputPathError(f"output {output} is a directory: give the archive's file name, e.g. {output / 'out.nc'}")
    if not stat.S_ISREG(mode):
        raise OutputPathError(
            f"output {output} is {_kind(mode)}: ncstab writes only regular files; give another output (-o)"
        )
    for study in inputs:
        with contextlib.suppress(OSError):
            if os.path.samefile(study, output):
                raise OutputPathError(f"output {output} is the study file {study}: give another output (-o)")
    study = _archive_study(output)
    if study is None:
        raise OutputPathError(
            f"output {output} exists and is not an ncstab archive: ncstab replaces only its own archives "
            "(with --overwrite); move the file away or give another output (-o)"
        )
    if resume:
        if finished_parts(output) or (study_text is not None and study == study_text):
            return  # chunks of an --overwrite run to finish, or this study's archive, complete: kept
        raise OutputPathError(
            f"output {output} is an ncstab archive of another study (or another version of it) and "
            f"{parts_directory(output).name} holds no chunk to resume: --resume does not replace it; move it "
            "away, or start over with --overwrite"
        )
    if not overwrite:
        raise OutputPathError(
            f"output {output} is an ncstab archive already: pass --overwrite to replace it, or give another "
            "output (-o)"
        )


def parts_directory(output: str | os.PathLike[str]) -> FilePath:
    """Where the parts of the archive ``output`` are kept while it is computed: ``<output>.parts``."""
    output = FilePath(output)
    return output.with_name(output.name + ".parts")


def finished_parts(output: str | os.PathLike[str]) -> list[FilePath]:
    """The finished chunks (``*.npz``) an earlier run of ``output`` kept."""
    directory = parts_directory(output)
    return sorted(directory.glob("*.npz")) if directory.is_dir() else []


def _remove_part_temporaries(directory: FilePath) -> list[FilePath]:
    """The temporaries of a killed chunked run inside its parts directory."""
    if not directory.is_dir():
        return []
    stale = [p for p in directory.glob(".*") if p.is_file()] + [directory / ARCHIVE_IN_PROGRESS]
    removed = [p for p in stale if p.exists()]
    for path in removed:
        path.unlink(missing_ok=True)
    return removed


@contextlib.contextmanager
def claim_output(
    output: str | os.PathLike[str],
    resume: bool = False,
    overwrite: bool = False,
    notify: Callable[[str], None] | None = None,
    protect_existing: bool = False,
    study_text: str | None = None,
) -> Iterator[OutputLock]:
    """Hold the output's lock for a run; clean what a killed run left; protect finished parts.

    Parameters
    ----------
    output
        The archive the run writes (its directory must exist).
    resume
        The run keeps the finished parts of an earlier run (``--resume``).
    overwrite
        The run discards them (``--overwrite``): the parts directory is removed.
    notify
        Called with one line when a stale lock is taken over or temporaries
        of a killed run are removed (the command line prints it).
    protect_existing
        Check again, under the lock, what is at the output's path
        (:func:`check_existing_output`): another run may have written it since
        the command checked it (``ncstab run`` passes True); ``study_text`` is
        the text of the study the run writes (see :func:`check_existing_output`).

    Yields
    ------
    OutputLock
        Held until the ``with`` block ends (re-entrant in the same thread).

    Raises
    ------
    OutputLockedError
        Another run holds the lock (exit code 3).
    PartsExistError
        Finished parts are on disk and neither ``resume`` nor ``overwrite``
        (exit code 2): nothing is deleted.
    OutputPathError
        ``protect_existing`` and the output holds anything but an ncstab
        archive that ``overwrite`` allows to replace (exit code 2).
    """
    if resume and overwrite:
        raise ValueError("resume keeps the finished parts and overwrite discards them: give one, not both")
    output = FilePath(output)
    with OutputLock(output) as lock:
        if protect_existing:
            check_existing_output(output, overwrite=overwrite, resume=resume, study_text=study_text)
        removed = remove_stale_temporaries(output) + _remove_part_temporaries(parts_directory(output))
        notes = []
        if lock.stale_pid is not None:
            notes.append(f"took over the lock {lock.path} of process {lock.stale_pid}, which is no longer running")
        if removed:
            notes.append(f"removed {len(removed)} temporary file(s) a killed run left ({removed[0].name}...)")
        if notes and notify is not None:
            notify("; ".join(notes))
        parts = finished_parts(output)
        if parts and not resume:
            if not overwrite:
                raise PartsExistError(
                    f"{parts_directory(output)} holds {len(parts)} finished chunk(s) of an earlier run of "
                    f"{output.name}: pass --resume to keep them and compute the rest, or --overwrite to "
                    "discard them"
                )
            shutil.rmtree(parts_directory(output))
        try:
            yield lock
        except BaseException:
            # A run that stops (an interrupt, a lost cluster) has closed its local cluster
            # by now; a worker closed while it wrote its part left that part's temporary.
            # The finished parts stay for --resume.
            _remove_part_temporaries(parts_directory(output))
            raise
