"""Event markers of different cases that would cover one another, set apart.

Two cases often meet an event at nearly the same point (the secondary
contact of the hyper- and the hypoelastic paths, seed Fig. 6): their markers,
several points wide, then cover each other and one is lost.  Each marker
keeps its data coordinates (what a reader of the artist finds is the located
point); a marker that would overlap one drawn before it is drawn shifted, by
an offset transform in points, just far enough from it, away from it, with a
thin leader to its true place where the shift exceeds half a marker.
"""

from __future__ import annotations

import numpy as np
from matplotlib.axes import Axes
from matplotlib.lines import Line2D
from matplotlib.transforms import offset_copy

__all__ = ["MARKER_GAP", "separate_event_markers"]

#: Space left between two event markers, points.
MARKER_GAP = 2.0
#: Direction of the shift of a marker on top of another (exactly the same point).
SAME_POINT_DIRECTION = np.array([1.0, 1.0]) / np.sqrt(2.0)


def _event_markers(axes: Axes) -> list[Line2D]:
    return [line for line in axes.lines if str(line.get_gid()).startswith("event:") and len(line.get_xdata()) == 1]


def separate_event_markers(axes: Axes) -> list[tuple[Line2D, np.ndarray]]:
    """Shift the event markers of the axes that overlap an earlier one (2-D axes, limits set).

    Parameters
    ----------
    axes
        Axes whose event markers are lines of one point with a gid
        ``"event:..."`` (:func:`ncstab.plotting.curves.mark_events`).

    Returns
    -------
    list of (Line2D, ndarray)
        The markers shifted and their shifts, points (x, y).
    """
    figure = axes.figure
    points_per_pixel = 72.0 / figure.dpi
    placed: list[tuple[np.ndarray, float]] = []  # centre (points), radius (points)
    shifted = []
    for line in _event_markers(axes):
        xy = np.array([float(line.get_xdata()[0]), float(line.get_ydata()[0])])
        if not np.isfinite(xy).all():
            continue
        centre = axes.transData.transform(xy) * points_per_pixel
        radius = float(line.get_markersize()) / 2
        shift = np.zeros(2)
        for _ in range(len(placed) + 1):  # moved off one marker, it may land on another
            moved = False
            for other, other_radius in placed:
                apart = centre + shift - other
                distance = float(np.hypot(*apart))
                needed = radius + other_radius + MARKER_GAP
                if distance < needed:
                    direction = apart / distance if distance > 1e-9 else SAME_POINT_DIRECTION
                    shift = shift + direction * (needed - distance)
                    moved = True
            if not moved:
                break
        placed.append((centre + shift, radius))
        if np.any(shift != 0):
            line.set_transform(offset_copy(axes.transData, fig=figure, x=shift[0], y=shift[1], units="points"))
            if np.hypot(*shift) > radius:
                axes.annotate("", xy=tuple(xy), xytext=tuple(shift), textcoords="offset points",
                              arrowprops={"arrowstyle": "-", "lw": 0.6, "color": "0.3", "shrinkA": 0,
                                          "shrinkB": 0}, gid=f"leader:{line.get_gid()}", zorder=4)
            shifted.append((line, shift))
    return shifted
