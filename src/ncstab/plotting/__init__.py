"""Figures of path Datasets (layer ``plotting/``): matplotlib, from Datasets only.

* :data:`FIGURE_KINDS` -- the figure kinds by name, each a function
  ``(dataset, figure=None) -> matplotlib.figure.Figure``;
* :func:`draw_figures` -- draw kinds of a Dataset to PNG files.
"""

from ncstab.plotting.draw import draw_figures
from ncstab.plotting.figures import (
    FIGURE_KINDS,
    plot_load_displacement,
    plot_load_displacement_rotation,
    plot_load_rotation,
    plot_stability,
)

__all__ = [
    "FIGURE_KINDS",
    "draw_figures",
    "plot_load_displacement",
    "plot_load_displacement_rotation",
    "plot_load_rotation",
    "plot_stability",
]
