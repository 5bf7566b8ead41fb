"""A grid of panels laid out once, in inches: figures of many panels without a layout engine.

matplotlib's constrained layout measures every text of every axes on each
draw: 6 s for 4 x 7 panels with colour bars, more than drawing them.  The
figures of large sweeps (fans, parameter planes, stability diagrams) place
their panels at fixed positions instead: margins in inches for the labels,
one colour bar below each column or one right of the grid, a legend strip at
the bottom and the title at the top.  Inner panels share axes with the outer
ones and draw no axis of their own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

__all__ = ["PanelGrid", "grid_width", "legend_columns", "panel_grid", "title_and_legend"]

#: Margins, inches: left (row labels: a law's name over two lines and the axis label),
#: right, top (title: three lines), bottom (x label and tick labels), gaps between panels.
LEFT, RIGHT, TOP, BOTTOM = 1.35, 0.25, 0.95, 0.62
GAP_X, GAP_Y = 0.22, 0.3
#: Colour bars: thickness, gap to the panels, room for their label and ticks, inches.
BAR, BAR_GAP, BAR_LABELS = 0.13, 0.1, 0.55
#: Height of the legend strip at the bottom, inches: a margin and one row of 8 pt entries each.
LEGEND, LEGEND_ROW = 0.12, 0.22


@dataclass(frozen=True)
class PanelGrid:
    """Panels ``axes[row, col]`` and the colour-bar axes of a figure.

    Attributes
    ----------
    figure
        The figure (no layout engine).
    axes
        ``(rows, cols)`` panels; panels share x within a column and y within a row.
    colorbars
        Colour-bar axes: one per column (``bars="columns"``), one in all
        (``bars="right"``), or none.
    """

    figure: Figure
    axes: np.ndarray
    colorbars: list[Axes]


def panel_grid(
    rows: int,
    cols: int,
    panel: tuple[float, float],
    bars: str | None = None,
    share: str = "all",
    legend_rows: int = 1,
    figure: Figure | None = None,
) -> PanelGrid:
    """Lay out ``rows x cols`` panels of ``panel`` = (width, height) inches.

    Parameters
    ----------
    rows, cols
        Number of panels down and across.
    panel
        Size of one panel, inches.
    bars
        ``"columns"``: a horizontal colour bar below each column; ``"right"``:
        one vertical colour bar right of the grid; None: no colour bar.
    share
        Every panel shares x; ``"all"``: y too (one parameter plane),
        ``"rows"``: y within a row (one quantity per row).
    legend_rows
        Rows of legend entries the bottom strip holds.
    figure
        A Figure to lay out (resized to fit); a new one by default.

    Returns
    -------
    PanelGrid
    """
    width, height = panel
    below = BAR_GAP + BAR + BAR_LABELS if bars == "columns" else 0.0
    total_w = grid_width(cols, width, bars)
    total_h = TOP + rows * height + (rows - 1) * GAP_Y + BOTTOM + below + LEGEND + legend_rows * LEGEND_ROW
    if figure is None:
        figure = Figure(figsize=(total_w, total_h))
    else:
        figure.clear()
        figure.set_size_inches(total_w, total_h)
    axes = np.empty((rows, cols), dtype=object)
    for r in range(rows):
        for c in range(cols):
            x = LEFT + c * (width + GAP_X)
            y = total_h - TOP - (r + 1) * height - r * GAP_Y
            sharex = axes[0, 0] if (r, c) != (0, 0) else None
            sharey = axes[r, 0] if c > 0 else (axes[0, 0] if share == "all" and r > 0 else None)
            ax = figure.add_axes((x / total_w, y / total_h, width / total_w, height / total_h),
                                 sharex=sharex, sharey=sharey)
            # Inner panels draw no axis at all (an invisible axis computes no ticks: a tenth of
            # a second per panel); they share limits and scales with the outer ones.
            ax.xaxis.set_visible(r == rows - 1)
            ax.yaxis.set_visible(c == 0)
            axes[r, c] = ax
    colorbars: list[Axes] = []
    grid_bottom = total_h - TOP - rows * height - (rows - 1) * GAP_Y
    if bars == "columns":
        for c in range(cols):
            x = LEFT + c * (width + GAP_X) + 0.08 * width
            y = grid_bottom - BOTTOM - BAR_GAP - BAR
            colorbars.append(figure.add_axes((x / total_w, y / total_h, 0.84 * width / total_w, BAR / total_h)))
    elif bars == "right":
        x = LEFT + cols * width + (cols - 1) * GAP_X + BAR_GAP
        span = rows * height + (rows - 1) * GAP_Y
        colorbars.append(figure.add_axes((x / total_w, (grid_bottom + 0.1 * span) / total_h, BAR / total_w,
                                          0.8 * span / total_h)))
    return PanelGrid(figure=figure, axes=axes, colorbars=colorbars)


def grid_width(cols: int, width: float, bars: str | None = None) -> float:
    """Width in inches of a figure of ``cols`` panels ``width`` inches wide (see :func:`panel_grid`)."""
    beside = BAR_GAP + BAR + 0.75 if bars == "right" else 0.0
    return LEFT + cols * width + (cols - 1) * GAP_X + beside + RIGHT


def legend_columns(width: float, count: int, longest: int) -> int:
    """Columns of a legend of ``count`` entries, the longest ``longest`` characters, across ``width`` inches."""
    entry = 0.55 + 0.062 * longest  # handle and 8 pt text, inches
    return max(1, min(count, int(width / entry)))


def title_and_legend(figure: Figure, title: str, handles: list, ncols: int) -> None:
    """The title at the top of a panel grid, the legend in the strip at its bottom (fixed places)."""
    height = figure.get_size_inches()[1]
    figure.suptitle(title, fontsize=10, y=1 - 0.08 / height, va="top")
    if handles:
        legend = figure.legend(handles=handles, loc="lower center", bbox_to_anchor=(0.5, 0.04 / height),
                               ncols=ncols, frameon=False)
        legend.set_gid("legend")
