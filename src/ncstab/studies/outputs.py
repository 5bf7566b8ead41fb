"""Claiming an output before a run writes it: lock, leftovers of a killed run, finished parts.

:func:`claim_output` is what every run (in process or in chunks) does before
it computes anything: it takes the output's lock
(:class:`~ncstab.studies.locks.OutputLock`), removes the temporary files a
killed run left (:func:`~ncstab.studies.archive.remove_stale_temporaries`),
and refuses to start over on top of the finished chunks of an earlier run
unless told to resume or to overwrite them.
"""

from __future__ import annotations

import contextlib
import os
import shutil
from collections.abc import Callable, Iterator
from pathlib import Path as FilePath

from ncstab.studies.archive import remove_stale_temporaries
from ncstab.studies.errors import PartsExistError
from ncstab.studies.locks import OutputLock

__all__ = ["ARCHIVE_IN_PROGRESS", "claim_output", "finished_parts", "parts_directory"]

#: The archive being written by a chunked run, inside the parts directory until complete.
ARCHIVE_IN_PROGRESS = "archive.nc.tmp"


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
    """
    if resume and overwrite:
        raise ValueError("resume keeps the finished parts and overwrite discards them: give one, not both")
    output = FilePath(output)
    with OutputLock(output) as lock:
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
