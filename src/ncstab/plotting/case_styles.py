"""How the curves of a few cases are told apart: colour, line style and marker.

Colour alone does not separate ten curves, nor eight neighbouring values of
one colormap (seed Fig. 8).  So:

* a sweep of several laws over several values of the other swept parameters
  (every law at every value: a grid) draws each **value in one colour** and
  each **law in one line style** (and one marker, where line styles are not
  free or too few); its legend lists the laws
  (grey, in their style) and the values (in their colour) once each, not
  every pair: 2 laws x 5 values are 7 entries, not 10 long ones;
* otherwise every case has its own colour (:func:`ncstab.plotting.style.case_colours`)
  and, from :data:`MARKED_FROM` cases on, its own marker as well.

Path markers are small and never one of the event markers
(:data:`ncstab.plotting.style.EVENT_MARKERS`), which are large and edged in black.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from matplotlib import colormaps
from matplotlib.lines import Line2D

from ncstab.plotting.style import case_colours, law_display_name

__all__ = ["LAW_LINESTYLES", "MARKED_FROM", "PATH_MARKERS", "CaseStyles", "case_styles"]

#: Line styles of the laws of a law x value grid, in order (solid, dashed, dotted, dash-dot).
LAW_LINESTYLES: tuple[object, ...] = ("-", (0, (5, 2)), (0, (1, 1.3)), (0, (6, 1.5, 1.2, 1.5)))
#: Markers of the paths (none of them an event marker).
PATH_MARKERS = ("<", "p", ">", "h", "d", "1", "8", "2", "H", "3", "4", "+")
#: From this many curves each case (or each law of a grid) has its own marker.
MARKED_FROM = 4
#: Markers along a path of n states: about this many.
MARKERS_PER_PATH = 7
#: Size of the path markers, points (the event markers are 6.5 to 11).
PATH_MARKER_SIZE = 5.0


@dataclass(frozen=True)
class CaseStyles:
    """Colour, line style and marker of each case, and the legend of a law x value grid.

    Attributes
    ----------
    colours
        One colour per case.
    linestyles
        One line style per case (``"-"`` unless the laws of a grid differ).
    markers
        One marker per case, or None (no marker).
    factors
        The legend of a law x value grid, ``(handle, text)``: the laws, then
        the values; None where each case is its own legend entry.
    """

    colours: list[object]
    linestyles: list[object]
    markers: list[str | None]
    factors: list[tuple[Line2D, str]] | None

    def line(self, k: int, n_states: int, n_cases: int) -> dict[str, object]:
        """Matplotlib keywords of case k's line of ``n_states`` points: colour, line style and
        markers, staggered from case to case so that they do not pile up where paths meet."""
        style: dict[str, object] = {"color": self.colours[k], "linestyle": self.linestyles[k]}
        marker = self.markers[k]
        if marker is not None and n_states > 1:
            every = max(1, n_states // MARKERS_PER_PATH)
            style.update(marker=marker, markersize=PATH_MARKER_SIZE, markevery=((k * every) // max(n_cases, 1), every))
        return style


def _grid(laws: Sequence[str], values: Sequence[str]) -> tuple[list[str], list[str]] | None:
    """The distinct laws and values when every law is met at every value (and each pair once)."""
    distinct_laws = list(dict.fromkeys(laws))
    distinct_values = list(dict.fromkeys(values))
    pairs = set(zip(laws, values))
    if len(distinct_laws) < 2 or len(distinct_values) < 2 or len(pairs) != len(laws):
        return None
    if len(pairs) != len(distinct_laws) * len(distinct_values):
        return None
    return distinct_laws, distinct_values


def case_styles(laws: Sequence[str], values: Sequence[str], law_linestyles: bool = True) -> CaseStyles:
    """The styles of cases given by their law and the text of their other swept values.

    Parameters
    ----------
    laws
        Each case's law name.
    values
        Each case's other swept values as a label (``"γ = 0.5"``; ``""`` when
        only the law varies).
    law_linestyles
        Whether the laws of a grid may differ by line style (False where the
        line style already says something, a state's stability).

    Returns
    -------
    CaseStyles
    """
    n = len(laws)
    grid = _grid(laws, values)
    if grid is None:
        colours = case_colours(list(laws), n)
        markers = [PATH_MARKERS[k % len(PATH_MARKERS)] if n >= MARKED_FROM else None for k in range(n)]
        return CaseStyles(colours, ["-"] * n, markers, None)
    distinct_laws, distinct_values = grid
    if len(distinct_values) >= MARKED_FROM:
        value_colours = [colormaps["viridis"](x) for x in np.linspace(0.0, 0.85, len(distinct_values))]
    else:
        value_colours = list(colormaps["tab10"].colors[: len(distinct_values)])
    law_styles = [LAW_LINESTYLES[j % len(LAW_LINESTYLES)] if law_linestyles else "-" for j in range(len(distinct_laws))]
    # Markers only where line styles alone cannot tell the laws apart (they clutter curves that meet).
    marked = not law_linestyles or len(distinct_laws) > len(LAW_LINESTYLES)
    law_markers = [PATH_MARKERS[j % len(PATH_MARKERS)] if marked else None for j in range(len(distinct_laws))]
    colours = [value_colours[distinct_values.index(v)] for v in values]
    linestyles = [law_styles[distinct_laws.index(law)] for law in laws]
    markers = [law_markers[distinct_laws.index(law)] for law in laws]
    factors = [
        (Line2D([], [], color="0.35", linestyle=style, marker=marker, markersize=PATH_MARKER_SIZE), law_display_name(law))
        for law, style, marker in zip(distinct_laws, law_styles, law_markers)
    ]
    factors += [(Line2D([], [], color=colour, linewidth=2.5), value) for value, colour in zip(distinct_values, value_colours)]
    return CaseStyles(colours, linestyles, markers, factors)
