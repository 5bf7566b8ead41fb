"""Text for a terminal: control characters escaped, tables fitted to a width.

* :func:`printable` -- a text with every character a terminal would act on
  (ESC, NUL, carriage return, bidirectional overrides...) written as its
  Python escape, ``\\x1b``, ``\\x00``, ``\\u202e``: a study's description is
  shown as written, never obeyed;
* :func:`fitted_table` -- rows as columns of at most a given width, the
  widest columns wrapped onto continuation lines.
"""

from __future__ import annotations

import textwrap
from collections.abc import Sequence

__all__ = ["LINE_WIDTH", "fitted_table", "printable"]

#: Width of the commands' tables, characters.
LINE_WIDTH = 100
#: A wrapped column keeps at least this many characters.
MIN_COLUMN = 12


def printable(text: str) -> str:
    """``text`` with each non-printable character written as its escape (as ``repr`` does).

    Spaces stay; every other character that :meth:`str.isprintable` rejects
    (the C0 and C1 controls, format characters such as U+202E, line and
    paragraph separators, unassigned code points) becomes ``\\xNN``,
    ``\\uNNNN`` or ``\\n``.  Backslashes are not doubled: the result is for
    reading, not for parsing back.

    Examples
    --------
    >>> printable("clear \\x1b[2J, nul \\x00, γ = 2")
    'clear \\\\x1b[2J, nul \\\\x00, γ = 2'
    """
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c == " " else repr(c)[1:-1] for c in text)


def _widths(natural: list[int], width: int, fixed: int) -> list[int]:
    """Column widths summing (with two spaces between columns) to at most ``width``:
    the widest of the columns after the first ``fixed`` shrunk first, none below MIN_COLUMN."""
    widths = list(natural)
    budget = width - 2 * (len(widths) - 1)
    while sum(widths) > budget:
        candidates = [k for k in range(fixed, len(widths)) if widths[k] > MIN_COLUMN]
        if not candidates:
            break
        widest = max(candidates, key=lambda k: widths[k])
        widths[widest] -= 1
    return widths


def fitted_table(rows: Sequence[Sequence[str]], header: Sequence[str], width: int = LINE_WIDTH,
                 fixed: int = 2, notes: Sequence[Sequence[str]] | None = None) -> str:
    """A text table of ``rows`` under ``header`` whose lines are at most ``width`` characters.

    Parameters
    ----------
    rows
        Cells, one sequence per row, as many as ``header``.
    header
        Column titles.
    width
        The longest line allowed (a column narrower than :data:`MIN_COLUMN`
        is never made, so a table of very many columns may exceed it).
    fixed
        The first ``fixed`` columns are never wrapped (names a reader, or a
        script, finds at the start of a row).
    notes
        Per row, lines written under it, indented by four spaces and wrapped
        to ``width`` (continuations by eight): what is too long for a column.

    Returns
    -------
    str
        Header, a rule, then each row (and its notes): its first line holds the start of every
        cell, continuation lines (blank under the unwrapped columns) the rest;
        columns are separated by two spaces, lines carry no trailing spaces.
    """
    cells = [[str(c) for c in row] for row in rows]
    natural = [max(len(str(r[i])) for r in cells + [list(header)]) for i in range(len(header))]
    widths = _widths(natural, width, fixed)
    out = ["  ".join(h.ljust(w) for h, w in zip(header, widths)).rstrip(), "  ".join("-" * w for w in widths)]
    for index, row in enumerate(cells):
        pieces = [textwrap.wrap(c, w, break_on_hyphens=False) or [""] if k >= fixed else [c]
                  for k, (c, w) in enumerate(zip(row, widths))]
        for line in range(max(len(p) for p in pieces)):
            texts = [p[line] if line < len(p) else "" for p in pieces]
            out.append("  ".join(t.ljust(w) for t, w in zip(texts, widths)).rstrip())
        for note in (notes[index] if notes is not None else ()):
            out += textwrap.wrap(note, width, initial_indent=" " * 4, subsequent_indent=" " * 8,
                                 break_on_hyphens=False)
    return "\n".join(out)
