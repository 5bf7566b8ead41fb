"""Named errors of runs and archives, each with the exit code ``ncstab`` gives it.

The exit codes are the contract of every command (docs/when-things-go-wrong.md):

* 0 -- success; 1 -- the archive was written but some case failed;
* 2 -- invalid input, nothing run or written (:class:`InvalidInputError`: a
  study file, an option, an output path, a scheduler address, a study too
  large for the limits, an archive that is not a readable ncstab archive);
* 3 -- the run could not complete (:class:`RunError`: the output is not
  writable or in use, the disk is full, the cluster is unreachable or lost,
  the run was interrupted), with what was kept (:attr:`RunError.kept`).

``str(error)`` is one line saying what is wrong and where; the command
line prints it after ``ncstab <command>:`` and exits with :attr:`exit_code`.
"""

from __future__ import annotations

import errno
import os
import shutil
from pathlib import Path as FilePath
from typing import ClassVar

__all__ = [
    "EXIT_FAILED_CASES",
    "EXIT_INVALID_INPUT",
    "EXIT_RUN_INCOMPLETE",
    "ArchiveError",
    "ClusterError",
    "DiskFullError",
    "InvalidInputError",
    "LimitError",
    "NcstabError",
    "OutputLockedError",
    "OutputNotWritableError",
    "OutputPathError",
    "PartsExistError",
    "ResumeError",
    "RunError",
    "RunInterrupted",
    "SchedulerAddressError",
    "WriteError",
    "write_error",
]

#: Exit code: the archive was written, but some case failed.
EXIT_FAILED_CASES = 1
#: Exit code: invalid input; nothing was run or written.
EXIT_INVALID_INPUT = 2
#: Exit code: the run could not complete (what was kept is said).
EXIT_RUN_INCOMPLETE = 3

#: Free bytes below which a failed write is put down to a full disk even when the
#: library does not say why (netCDF reports a full disk as "NetCDF: HDF error").
NEARLY_FULL_BYTES = 1 << 20


def _one_line(text: object) -> str:
    """``text`` on one line: the first non-empty line of its string."""
    lines = [line.strip() for line in str(text).splitlines() if line.strip()]
    return lines[0] if lines else type(text).__name__


class NcstabError(Exception):
    """Base of the errors the command line turns into one line and an exit code."""

    exit_code: ClassVar[int] = EXIT_RUN_INCOMPLETE


class InvalidInputError(NcstabError):
    """Invalid input: nothing was run or written (exit code 2)."""

    exit_code: ClassVar[int] = EXIT_INVALID_INPUT


class ArchiveError(InvalidInputError, ValueError):
    """A file that is not a readable ncstab archive.

    Attributes
    ----------
    path
        The file.
    reason
        What is wrong, in one line (``"variable 'n_steps': 415 states stored
        in a step dimension of 160"``).
    """

    def __init__(self, path: str | os.PathLike[str], reason: str) -> None:
        self.path = str(path)
        self.reason = _one_line(reason)
        super().__init__(f"{self.path} is not a readable ncstab archive: {self.reason}")

    def __reduce__(self):  # picklable despite the custom signature
        return (type(self), (self.path, self.reason))


class OutputPathError(InvalidInputError):
    """An output path that cannot name an archive (a directory, under a file, too long)."""


class PartsExistError(InvalidInputError):
    """Finished chunks of an earlier run are on disk and neither resume nor overwrite was asked."""


class SchedulerAddressError(InvalidInputError):
    """A ``--scheduler`` value that is not an address."""


class LimitError(InvalidInputError):
    """A study larger than a limit (cases, disk, memory): refused before anything runs.

    Attributes
    ----------
    key
        The study key or option that sets the size (``"[map] directions"``,
        ``"max_cases"``, ``"[parameters]"``).
    estimate
        The estimated need, in words (``"about 21 GiB of memory"``).
    """

    def __init__(self, key: str, estimate: str, message: str) -> None:
        self.key = key
        self.estimate = estimate
        super().__init__(message)

    def __reduce__(self):
        return (type(self), (self.key, self.estimate, str(self)))


class ResumeError(InvalidInputError, ValueError):
    """The parts of an interrupted run do not belong to this study or chunking.

    Attributes
    ----------
    field
        What differs (``"study"``, ``"chunk_cases"``, ``"format"``, ``"part"``).
    """

    def __init__(self, field: str, message: str) -> None:
        super().__init__(message)
        self.field = field

    def __reduce__(self):
        return (type(self), (self.field, str(self)))


class RunError(NcstabError):
    """The run could not complete (exit code 3).

    Attributes
    ----------
    kept
        What is left on disk for the next run, in words (``"3 of 8 chunks kept
        in out.nc.parts: rerun with --resume"``); empty when not yet known.
    """

    exit_code: ClassVar[int] = EXIT_RUN_INCOMPLETE

    def __init__(self, message: str, kept: str = "") -> None:
        super().__init__(message)
        self.kept = kept

    def __reduce__(self):
        return (type(self), (str(self), self.kept))

    def line(self) -> str:
        """The message and what was kept, on one line."""
        return f"{self}; {self.kept}" if self.kept else str(self)


class OutputNotWritableError(RunError):
    """The output's directory cannot be written (permissions, read-only file system)."""


class OutputLockedError(RunError):
    """Another run holds the output's lock.

    Attributes
    ----------
    pid, host
        The holder's process id and host name, as its lock file says.
    """

    def __init__(self, message: str, pid: int | None = None, host: str = "", kept: str = "") -> None:
        super().__init__(message, kept)
        self.pid = pid
        self.host = host

    def __reduce__(self):
        return (type(self), (str(self), self.pid, self.host, self.kept))


class DiskFullError(RunError):
    """No space left where the run writes."""


class WriteError(RunError):
    """A write failed for another reason than a full disk or permissions."""


class ClusterError(RunError):
    """The dask cluster could not be reached, or was lost during the run."""


class RunInterrupted(KeyboardInterrupt):
    """The run was stopped by SIGINT, SIGTERM or SIGHUP (a ``KeyboardInterrupt``, so that
    nothing catching ``Exception`` swallows it).

    Attributes
    ----------
    signal_name
        ``"SIGINT"``, ``"SIGTERM"`` or ``"SIGHUP"``.
    kept
        What is left on disk, in words (set by the runner that was interrupted).
    """

    exit_code: ClassVar[int] = EXIT_RUN_INCOMPLETE

    def __init__(self, signal_name: str = "SIGINT", kept: str = "") -> None:
        super().__init__(signal_name)
        self.signal_name = signal_name
        self.kept = kept

    def __reduce__(self):
        return (type(self), (self.signal_name, self.kept))


def _free_bytes(path: FilePath) -> int | None:
    """Free bytes on the file system of ``path`` (or of its nearest existing parent)."""
    for candidate in (path, *path.parents):
        try:
            return shutil.disk_usage(candidate).free
        except OSError:
            continue
    return None


def write_error(error: BaseException, path: str | os.PathLike[str]) -> RunError | None:
    """The named error for a failed write of ``path``, or None if ``error`` is not one.

    An ``OSError`` with ``ENOSPC``/``EDQUOT`` (or saying so), or a netCDF/HDF5
    error while the file system is nearly full (:data:`NEARLY_FULL_BYTES`), is a
    :class:`DiskFullError`; ``EACCES``/``EPERM``/``EROFS`` an
    :class:`OutputNotWritableError`; any other ``OSError`` or netCDF/HDF5
    ``RuntimeError`` a :class:`WriteError`.  Anything else (a bug, an
    interrupt) is not a write error: None.
    """
    if isinstance(error, NcstabError):
        return None
    target = FilePath(path)
    text = _one_line(error)
    code = getattr(error, "errno", None)
    if isinstance(error, OSError) or (isinstance(error, RuntimeError) and ("HDF" in text or "NetCDF" in text)):
        full = code in (errno.ENOSPC, errno.EDQUOT) or "No space left" in str(error) or "errno = 28" in str(error)
        if not full and not isinstance(error, PermissionError):
            free = _free_bytes(target.parent)
            full = free is not None and free < NEARLY_FULL_BYTES
        if full:
            return DiskFullError(f"disk full while writing {target} ({text})")
        if code in (errno.EACCES, errno.EPERM, errno.EROFS) or isinstance(error, PermissionError):
            return OutputNotWritableError(f"cannot write {target}: {os.strerror(code) if code else text}")
        return WriteError(f"could not write {target}: {text}")
    return None
