"""What ncstab keeps between runs, under one cache root.

The root is ``$NCSTAB_CACHE_DIR``, else ``$XDG_CACHE_HOME/ncstab``, else
``~/.cache/ncstab`` (:func:`cache_root`); each cache is one folder of it,
``<root>/<kind>`` (:func:`cache_directory`), named in :data:`CACHE_KINDS`:

* ``compiled`` -- the generated modules numba compiles (the compiled stepper's
  loops, :mod:`ncstab.paths.compiled`; general models' kernels,
  :mod:`ncstab.operators.model_kernel`; the n-dof cofactor tangent,
  :mod:`ncstab.paths.cofactor`), with numba's machine code beside them
  (:mod:`ncstab.generated_modules`);
* ``law_classes`` -- the class of a law and the derivation ``ncstab laws``
  prints (:mod:`ncstab.symbolic.class_cache`);
* ``valid_studies`` -- the study texts already found valid in an archive
  (:mod:`ncstab.studies.verification`).

``ncstab cache`` reports these folders and ``ncstab cache clear`` removes
them (:func:`cache_usage`, :func:`clear_cache`); nothing else under the root
is ncstab's, and nothing else is removed.  Deleting any of them is always
safe: what was kept is derived again.

The last two hold small results, one JSON file per entry (:func:`read_entry`,
:func:`write_entry`).  An entry is named by its key (a SHA-256 the caller makes
of everything the value depends on, the ncstab version included) and holds
that key: a file that cannot be read, is not JSON, or holds another key or
format (corrupt or foreign) is ignored, and the next :func:`write_entry`
replaces it.  Entries are written to a temporary name and renamed
(:func:`os.replace`); a directory that cannot be written only costs the
derivation next time.
"""

from __future__ import annotations

import errno
import json
import os
import secrets
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

__all__ = [
    "CACHE_FORMAT",
    "CACHE_KINDS",
    "CacheClearance",
    "CacheUsage",
    "cache_directory",
    "cache_root",
    "cache_usage",
    "clear_cache",
    "read_entry",
    "write_entry",
]

#: Bumped when the layout of an entry changes.
CACHE_FORMAT = 1

#: Every folder ncstab keeps under the cache root, and what it holds.  A cache is
#: named here before it is used (:func:`cache_directory` refuses another name), so
#: that ``ncstab cache`` reports and clears all of them, and nothing else.
CACHE_KINDS: dict[str, str] = {
    "compiled": "compiled loops and kernels, numba's machine code",
    "law_classes": "each law's class and derivation (ncstab laws)",
    "state_kernels": "each law's generated kernel of forces and K",
    "valid_studies": "study texts found valid in archives (ncstab info, plot)",
}


def cache_root() -> Path:
    """The folder of every cache of ncstab (it need not exist).

    ``$NCSTAB_CACHE_DIR`` if set and not empty, else ``$XDG_CACHE_HOME/ncstab``
    (if that is set and not empty), else ``~/.cache/ncstab``.
    """
    if os.environ.get("NCSTAB_CACHE_DIR"):
        return Path(os.environ["NCSTAB_CACHE_DIR"])
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "ncstab"


def unusable_cache(kind: str = "compiled") -> str | None:
    """Why ``<root>/<kind>`` cannot hold a cache (None: it can): a path on the way that is a
    file, or a folder that cannot be created or written.  Creates the folder if it can."""
    folder = cache_root() / kind
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        return f"{folder}: a file on the way is not a folder (NCSTAB_CACHE_DIR={cache_root()})"
    except OSError as error:
        return f"cannot create the cache folder {folder}: {error.strerror or error}"
    if not os.access(folder, os.W_OK | os.X_OK):
        return f"cannot write into the cache folder {folder}"
    return None


def cache_directory(kind: str) -> Path:
    """The folder of one cache: ``<root>/<kind>`` (:func:`cache_root`).

    Parameters
    ----------
    kind
        A name of :data:`CACHE_KINDS` (``"law_classes"``).

    Raises
    ------
    ValueError
        For a name that is not in :data:`CACHE_KINDS`.
    """
    if kind not in CACHE_KINDS:
        known = ", ".join(CACHE_KINDS)
        raise ValueError(f"unknown cache {kind!r}: the caches are {known} (ncstab.cache.CACHE_KINDS)")
    return cache_root() / kind


# --- what the caches hold, and clearing them ---------------------------------------------------


@dataclass(frozen=True)
class CacheUsage:
    """The files of one cache folder (found, or removed by :func:`clear_cache`).

    Attributes
    ----------
    kind : str
        The cache's name in :data:`CACHE_KINDS`.
    path : Path
        Its folder, ``<root>/<kind>``.
    files : int
        Files (and symbolic links) at any depth under it; 0 if it does not exist.
    size : int
        Their total size in bytes (:func:`os.lstat`: a link's own size).
    """

    kind: str
    path: Path
    files: int
    size: int


@dataclass(frozen=True)
class CacheClearance:
    """What :func:`clear_cache` did.

    Attributes
    ----------
    root : Path
        The cache root.
    removed : tuple of CacheUsage
        Per cache folder that existed: the files and bytes removed.
    failures : tuple of OSError
        What could not be removed (``filename``) and why (``errno``,
        ``strerror``); empty when everything was.
    """

    root: Path
    removed: tuple[CacheUsage, ...]
    failures: tuple[OSError, ...]

    @property
    def files(self) -> int:
        """Files removed, over every folder."""
        return sum(usage.files for usage in self.removed)

    @property
    def size(self) -> int:
        """Bytes freed, over every folder."""
        return sum(usage.size for usage in self.removed)


def _leaves(directory: str, subdirectories: list[str], names: list[str]) -> list[str]:
    """The files of one step of :func:`os.walk`, links to folders included (not followed)."""
    links = [name for name in subdirectories if os.path.islink(os.path.join(directory, name))]
    return [os.path.join(directory, name) for name in names + links]


def _files_under(folder: Path) -> Iterator[int]:
    """The size of each file under ``folder`` (what cannot be read is left out)."""
    for step in os.walk(folder):
        for path in _leaves(*step):
            try:
                yield os.lstat(path).st_size
            except OSError:  # removed meanwhile
                continue


def cache_usage() -> list[CacheUsage]:
    """The files and bytes of each cache of :data:`CACHE_KINDS`, in its order."""
    usages = []
    for kind in CACHE_KINDS:
        folder = cache_directory(kind)
        sizes = list(_files_under(folder))
        usages.append(CacheUsage(kind, folder, len(sizes), sum(sizes)))
    return usages


def _unlink(path: str, failures: list[OSError]) -> int | None:
    """Remove one file or link; its size, or None if it was not there or could not be removed."""
    try:
        size = os.lstat(path).st_size
        os.unlink(path)
    except FileNotFoundError:  # removed by another process meanwhile
        return None
    except OSError as error:
        failures.append(error)
        return None
    return size


def _rmdir(path: str, failures: list[OSError]) -> None:
    """Remove an empty folder; one that is not empty keeps what could not be removed (a
    failure already recorded) or what another process wrote meanwhile."""
    try:
        os.rmdir(path)
    except (FileNotFoundError, NotADirectoryError):
        pass
    except OSError as error:
        if error.errno not in (errno.ENOTEMPTY, errno.EEXIST):
            failures.append(error)


def _remove_folder(folder: Path, failures: list[OSError]) -> tuple[int, int]:
    """Remove ``folder`` and what it holds, bottom up; the files and bytes removed.

    A symbolic link in place of the folder is removed itself, never what it
    points to; the links inside are removed, not followed.
    """
    if folder.is_symlink() or not folder.is_dir():
        size = _unlink(str(folder), failures)
        return (0, 0) if size is None else (1, size)
    files = freed = 0
    for directory, subdirectories, names in os.walk(folder, topdown=False, onerror=failures.append):
        for path in _leaves(directory, subdirectories, names):
            size = _unlink(path, failures)
            if size is not None:
                files, freed = files + 1, freed + size
        for name in subdirectories:
            if not os.path.islink(os.path.join(directory, name)):
                _rmdir(os.path.join(directory, name), failures)
    _rmdir(str(folder), failures)
    return files, freed


def clear_cache() -> CacheClearance:
    """Remove the folders of :data:`CACHE_KINDS` under the cache root, and nothing else.

    What cannot be removed is kept and named in :attr:`CacheClearance.failures`
    (nothing is raised); what another process removes or writes meanwhile is
    not an error (a file written during the clearing may be kept).
    """
    root = cache_root()
    removed: list[CacheUsage] = []
    failures: list[OSError] = []
    for kind in CACHE_KINDS:
        folder = root / kind
        if os.path.lexists(folder):
            files, freed = _remove_folder(folder, failures)
            removed.append(CacheUsage(kind, folder, files, freed))
    return CacheClearance(root, tuple(removed), tuple(failures))


# --- entries: one JSON file each ----------------------------------------------------------------


def _entry_path(kind: str, key: str) -> Path:
    return cache_directory(kind) / f"{key}.json"


def read_entry(kind: str, key: str) -> dict[str, Any] | None:
    """The value kept under ``key``, or ``None`` if there is none, or it is corrupt or foreign.

    Parameters
    ----------
    kind
        The cache, a name of :data:`CACHE_KINDS` (``"law_classes"``).
    key
        Hexadecimal digits naming the entry.
    """
    path = _entry_path(kind, key)
    try:
        entry = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, ValueError):
        return None
    if not isinstance(entry, dict) or entry.get("key") != key or entry.get("format") != CACHE_FORMAT:
        return None
    value = entry.get("value")
    return value if isinstance(value, dict) else None


def write_entry(kind: str, key: str, value: dict[str, Any]) -> None:
    """Keep ``value`` (JSON-able) under ``key``, atomically; silently nothing if it cannot be written."""
    path = _entry_path(kind, key)
    scratch = path.with_name(f".{path.name}.{os.getpid()}.{secrets.token_hex(4)}.tmp")
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        scratch.write_text(json.dumps({"format": CACHE_FORMAT, "key": key, "value": value}, indent=1), "utf-8")
        os.replace(scratch, path)
    except (OSError, TypeError, ValueError):
        try:
            scratch.unlink(missing_ok=True)
        except OSError:
            pass
