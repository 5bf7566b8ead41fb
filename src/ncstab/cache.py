"""Small results kept between runs in the cache directory, one JSON file per entry.

Used for what is slow to derive and cheap to keep: the class of a law and the
derivation ``ncstab laws`` prints (:mod:`ncstab.symbolic.class_cache`), and the
study texts already found valid in an archive (:mod:`ncstab.studies.verification`).
The directory is ``$NCSTAB_CACHE_DIR/<kind>``, else
``$XDG_CACHE_HOME/ncstab/<kind>`` (``~/.cache/ncstab/<kind>``) -- the same roots
as the generated loops of :mod:`ncstab.paths.compiled`.

An entry is named by its key (a SHA-256 the caller makes of everything the
value depends on, the ncstab version included) and holds that key: a file
that cannot be read, is not JSON, or holds another key or format (corrupt or
foreign) is ignored, and the next :func:`write_entry` replaces it.  Entries
are written to a temporary name and renamed (:func:`os.replace`); a directory
that cannot be written only costs the derivation next time.
"""

from __future__ import annotations

import json
import os
import secrets
from pathlib import Path
from typing import Any

__all__ = ["CACHE_FORMAT", "cache_directory", "read_entry", "write_entry"]

#: Bumped when the layout of an entry changes.
CACHE_FORMAT = 1


def cache_directory(kind: str) -> Path:
    """``$NCSTAB_CACHE_DIR/<kind>``, else ``$XDG_CACHE_HOME/ncstab/<kind>`` (``~/.cache/ncstab/<kind>``)."""
    if os.environ.get("NCSTAB_CACHE_DIR"):
        return Path(os.environ["NCSTAB_CACHE_DIR"]) / kind
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "ncstab" / kind


def _entry_path(kind: str, key: str) -> Path:
    return cache_directory(kind) / f"{key}.json"


def read_entry(kind: str, key: str) -> dict[str, Any] | None:
    """The value kept under ``key``, or ``None`` if there is none, or it is corrupt or foreign.

    Parameters
    ----------
    kind
        The cache's folder (``"law_classes"``).
    key
        Hexadecimal digits naming the entry.
    """
    try:
        entry = json.loads(_entry_path(kind, key).read_text(encoding="utf-8"))
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
