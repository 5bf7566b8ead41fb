"""Sizes in bytes as people read them, and the memory available (the standard library only:
the CLI's fast paths use it)."""

from __future__ import annotations

import os

__all__ = ["available_memory", "readable_count", "readable_duration", "readable_size"]


def available_memory() -> int | None:
    """Bytes of memory available to a new allocation (``MemAvailable``), or None if unknown."""
    try:
        with open("/proc/meminfo", encoding="ascii") as meminfo:
            for line in meminfo:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):  # pragma: no cover
        return None


def readable_count(count: float) -> str:
    """A count for a message: ``"1,234"`` below a million, else its order, ``"~5e299"``.

    An estimate from a tiny ``sample_step`` is a float of 300 digits: the
    message says its order of magnitude, not its digits.
    """
    if count < 1e6:
        return f"{count:,.0f}"
    mantissa, exponent = f"{count:.0e}".split("e")
    return f"~{mantissa}e{int(exponent)}"


def readable_size(size: float) -> str:
    """``size`` bytes in decimal units to three digits: ``"950 bytes"``, ``"12.4 kB"``, ``"3.1 MB"``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return "1 byte" if size == 1 else f"{size:.0f} bytes"


def readable_duration(seconds: float) -> str:
    """A duration for a message, to two digits: ``"45 s"``, ``"3.2 min"``, ``"1.5 h"``, ``"12 days"``."""
    for unit, scale in (("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= scale:
            value = seconds / scale
            return f"{value:,.0f} {unit}" if value >= 100 else f"{value:.2g} {unit}"
    return f"{seconds:.2g} s"
