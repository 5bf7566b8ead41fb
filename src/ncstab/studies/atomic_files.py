"""Files written atomically: a temporary beside the destination, renamed over it once complete.

:func:`atomic_destination` serves the archive (:mod:`ncstab.studies.archive`), the
chunked run's parts and its manifest; :func:`remove_stale_temporaries` removes what a
killed process left behind.
"""

from __future__ import annotations

import contextlib
import os
import re
import secrets
from collections.abc import Iterator
from pathlib import Path as FilePath

__all__ = ["atomic_destination", "remove_stale_temporaries"]

#: Random part of a temporary file's name (hex digits).
_TEMPORARY_TOKEN = 8


def _default_mode() -> int:
    """File mode a plain ``open(..., "w")`` would give: 0o666 less the umask."""
    mask = os.umask(0o022)
    os.umask(mask)
    return 0o666 & ~mask


def _temporary_pattern(destination: FilePath) -> re.Pattern[str]:
    """Names of the temporaries :func:`atomic_destination` makes for ``destination``."""
    return re.compile(rf"\.{re.escape(destination.name)}\.[0-9a-f]{{{_TEMPORARY_TOKEN}}}\.(tmp|part)")


@contextlib.contextmanager
def atomic_destination(destination: FilePath, suffix: str = ".tmp") -> Iterator[FilePath]:
    """Yield a temporary path beside ``destination``; on success it replaces it.

    The temporary, ``.<name>.<8 hex digits><suffix>`` (``suffix`` is
    ``".tmp"`` or ``".part"``), is created exclusively, synced to disk, given
    the default file mode and renamed over ``destination`` (:func:`os.replace`,
    atomic on one file system).  If anything fails -- an exception or an
    interrupt -- the temporary is removed and ``destination`` is left as it
    was: never a half-written file.  A process killed outright leaves the
    temporary behind; :func:`remove_stale_temporaries` removes it.
    """
    if suffix not in (".tmp", ".part"):
        raise ValueError(f"a temporary's suffix is '.tmp' or '.part', not {suffix!r}")
    while True:
        temporary = destination.with_name(f".{destination.name}.{secrets.token_hex(_TEMPORARY_TOKEN // 2)}{suffix}")
        try:
            os.close(os.open(temporary, os.O_CREAT | os.O_EXCL | os.O_WRONLY, 0o600))
            break
        except FileExistsError:  # pragma: no cover - 1 chance in 4e9
            continue
    try:
        yield temporary
        with open(temporary, "rb+") as written:
            os.fsync(written.fileno())
        os.chmod(temporary, _default_mode())
        os.replace(temporary, destination)
    except BaseException:
        temporary.unlink(missing_ok=True)
        raise


def remove_stale_temporaries(destination: str | os.PathLike[str]) -> list[FilePath]:
    """Remove the temporaries a killed process left for ``destination`` and its figures.

    Those of :func:`atomic_destination` (``.<name>.<hex>.tmp``/``.part``) and
    of the figures drawn beside the archive
    (``.<stem>_<kind>.png.<pid>.<hex>.tmp``, :func:`ncstab.plotting.draw_figures`).
    Call it only while holding the output's lock
    (:class:`~ncstab.studies.locks.OutputLock`): no other run is writing them.

    Returns
    -------
    list of pathlib.Path
        The files removed.
    """
    destination = FilePath(destination)
    patterns = [
        _temporary_pattern(destination),
        re.compile(rf"\.{re.escape(destination.stem)}_[a-z0-9_]+\.png\.\d+\.[0-9a-f]{{12}}\.tmp"),
    ]
    removed = []
    try:
        entries = list(os.scandir(destination.parent))
    except OSError:
        return removed
    for entry in entries:
        if any(pattern.fullmatch(entry.name) for pattern in patterns) and entry.is_file(follow_symlinks=False):
            FilePath(entry.path).unlink(missing_ok=True)
            removed.append(FilePath(entry.path))
    return removed
