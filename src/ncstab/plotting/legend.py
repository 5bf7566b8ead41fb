"""Legends of the path figures: curves, closed forms, one entry per event kind; fixed places.

A legend is placed at a fixed location chosen from the data, never with
matplotlib's ``loc="best"`` (which tests every artist against every candidate
place: 6 s for 4,096 curves): inside the corner of the axes that holds no
drawn point, else outside the axes.
"""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.style import EVENT_MARKERS

__all__ = ["CLOSED_FORM_STYLE", "Legend", "empty_corner", "event_style"]

#: Line style of the seed's closed forms (dashed over the computed path).
CLOSED_FORM_STYLE = {"linestyle": (0, (4, 2.5)), "linewidth": 1.1, "zorder": 3}

#: Legend entries from which the legend goes outside the axes.
LEGEND_INSIDE_MAX = 5
#: Share of the axes (width, height) a legend in a corner may cover.
CORNER_SIZE = (0.5, 0.4)
#: Corners tried, in order: matplotlib location, (x, y) of the corner in axes fractions.
CORNERS = (("upper left", (0.0, 1.0)), ("lower right", (1.0, 0.0)),
           ("upper right", (1.0, 1.0)), ("lower left", (0.0, 0.0)))


def event_style(name: str, colour: object) -> dict[str, object]:
    """Marker style of an event (:data:`EVENT_MARKERS`) on a curve of the given colour."""
    marker, size, filled, _ = EVENT_MARKERS[name]
    if marker == "x":
        return {"marker": marker, "markersize": size, "color": "k", "markeredgewidth": 1.8}
    return {
        "marker": marker,
        "markersize": size,
        "markerfacecolor": colour if filled else "none",
        "markeredgecolor": "k",
        "markeredgewidth": 1.0 if filled else 1.3,
        "color": colour,
    }


def empty_corner(axes: Axes, points: Iterable[tuple[np.ndarray, np.ndarray]], size: tuple[float, float] = CORNER_SIZE) -> str | None:
    """The first corner of :data:`CORNERS` where no drawn point lies, or None.

    Parameters
    ----------
    axes
        Axes whose limits are set (data coordinates -> axes fractions, linear axes).
    points
        ``(x, y)`` arrays of everything drawn (NaN ignored).
    size
        Width and height of the corner box, in axes fractions.
    """
    (x0, x1), (y0, y1) = axes.get_xlim(), axes.get_ylim()
    xs, ys = [], []
    for x, y in points:
        xs.append(np.ravel(np.asarray(x, dtype=float)))
        ys.append(np.ravel(np.asarray(y, dtype=float)))
    if not xs:
        return CORNERS[0][0]
    fx = (np.concatenate(xs) - x0) / ((x1 - x0) or 1.0)
    fy = (np.concatenate(ys) - y0) / ((y1 - y0) or 1.0)
    for location, (cx, cy) in CORNERS:
        inside_x = fx <= size[0] if cx == 0 else fx >= 1 - size[0]
        inside_y = fy <= size[1] if cy == 0 else fy >= 1 - size[1]
        if not np.any(inside_x & inside_y):
            return location
    return None


def _legend_size(figure: Figure, axes: Axes, rows: int, longest: int) -> tuple[float, float]:
    """Estimated (width, height) of a legend in axes fractions: 8 pt text, a 30 pt handle."""
    width_in, height_in = figure.get_size_inches()
    box = axes.get_position()
    width_pt, height_pt = 72 * width_in * box.width, 72 * height_in * box.height
    return (
        min(1.0, (0.56 * 8 * longest + 40) / max(width_pt, 1.0)),
        min(1.0, (rows * 1.45 * 8 + 10) / max(height_pt, 1.0)),
    )


@dataclass
class Legend:
    """Curves, then one entry for the closed forms and one per event kind present."""

    title: str | None = None
    curves: list[tuple[object, str]] = field(default_factory=list)
    equations: set[int] = field(default_factory=set)
    events: dict[str, Line2D] = field(default_factory=dict)
    extra: list[tuple[object, str]] = field(default_factory=list)
    #: Entries that replace the curves' (the laws and the values of a law x value grid).
    factors: list[tuple[object, str]] | None = None

    def curve(self, handle: object, label: str) -> None:
        self.curves.append((handle, label))

    def closed_form(self, equations: str) -> None:
        """Record the seed equations of an overlay (``"seed Eq. 46, 53"``)."""
        self.equations.update(int(n) for n in equations.removeprefix("seed Eq. ").split(", "))

    def event(self, name: str) -> None:
        if name not in self.events:
            self.events[name] = Line2D([], [], linestyle="none", **event_style(name, "0.55"))

    @property
    def closed_form_label(self) -> str:
        return "closed form (seed Eq. " + ", ".join(str(n) for n in sorted(self.equations)) + ")"

    def entries(self) -> tuple[list[object], list[str]]:
        curves = self.curves if self.factors is None else self.factors  # at most MAX_CURVES: larger sweeps are fans or planes
        handles = [h for h, _ in curves] + [h for h, _ in self.extra]
        labels = [t for _, t in curves] + [t for _, t in self.extra]
        if self.equations:
            style = {k: v for k, v in CLOSED_FORM_STYLE.items() if k != "zorder"}
            handles.append(Line2D([], [], color="0.2", **style))
            labels.append(self.closed_form_label)
        present = [name for name in EVENT_MARKERS if name in self.events]
        handles += [self.events[name] for name in present]
        labels += [EVENT_MARKERS[name][3] for name in present]
        return handles, labels

    def draw(self, figure: Figure, axes: Axes, place: str | None = None,
             points: Iterable[tuple[np.ndarray, np.ndarray]] = ()) -> None:
        """Place the legend: ``"inside"`` (a corner of the axes free of ``points``),
        ``"right"`` or ``"below"`` the axes, or ``"corner"`` (upper left of the
        figure, for 3-D axes).  By default inside when short and a corner is
        free, else right of the axes for short texts and below, in columns, for
        long ones.  Never matplotlib's ``"best"``.
        """
        handles, labels = self.entries()
        if not handles:
            return
        longest = max(len(text) for text in labels)
        corner = None
        if place in (None, "inside") and len(handles) <= LEGEND_INSIDE_MAX:
            corner = empty_corner(axes, points, _legend_size(figure, axes, len(handles) + bool(self.title), longest))
        if place is None or (place == "inside" and corner is None):
            place = "inside" if corner is not None else ("right" if longest <= 28 else "below")
        if place == "inside":
            legend = axes.legend(handles, labels, loc=corner, title=self.title)
        elif place == "right":
            legend = figure.legend(handles, labels, loc="outside right center", title=self.title)
        elif place == "corner":
            legend = figure.legend(
                handles, labels, loc="upper left", bbox_to_anchor=(0.01, 0.9), title=self.title
            )
        else:
            ncols = min(3 if longest <= 26 else (2 if longest <= 44 else 1), len(handles))
            legend = figure.legend(
                handles, labels, loc="outside lower center", ncols=ncols, title=self.title
            )
        if self.title:
            legend.get_title().set_fontsize(8)
        legend.set_gid("legend")
