"""Sizes in bytes as people read them (the standard library only: the CLI's fast paths use it)."""

from __future__ import annotations

__all__ = ["readable_size"]


def readable_size(size: float) -> str:
    """``size`` bytes in decimal units to three digits: ``"950 bytes"``, ``"12.4 kB"``, ``"3.1 MB"``."""
    for unit, scale in (("TB", 1e12), ("GB", 1e9), ("MB", 1e6), ("kB", 1e3)):
        if size >= scale:
            return f"{size / scale:.3g} {unit}"
    return "1 byte" if size == 1 else f"{size:.0f} bytes"
