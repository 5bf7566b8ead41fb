"""Figures of path Datasets (layer ``plotting/``): matplotlib, from Datasets only.

* :data:`FIGURE_KINDS` -- the figure kinds by name, each a function
  ``(dataset, figure=None) -> matplotlib.figure.Figure``; the path kinds
  choose by the sweep's shape (:func:`sweep_shape`): curves for up to 12
  cases, a parameter plane for a larger 2-D sweep, a fan for a larger 1-D one;
* :func:`draw_figures` -- draw kinds of a Dataset to PNG files, with an
  optional per-figure progress callback.
"""

from ncstab.plotting.draw import FigureProgress, draw_figures, figure_kinds
from ncstab.plotting.figures import (
    FIGURE_KINDS,
    plot_load_displacement,
    plot_load_displacement_rotation,
    plot_load_rotation,
    plot_stability,
)
from ncstab.plotting.sweep_shape import MAX_CURVES, SweepShape, sweep_shape

__all__ = [
    "FIGURE_KINDS",
    "MAX_CURVES",
    "FigureProgress",
    "SweepShape",
    "draw_figures",
    "figure_kinds",
    "plot_load_displacement",
    "plot_load_displacement_rotation",
    "plot_load_rotation",
    "plot_stability",
    "sweep_shape",
]
