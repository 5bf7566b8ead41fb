"""3-D curves (Delta1*, alpha, F1) of a few cases (seed Figs. 5 and 11).

The view looks mostly along the Delta1* axis from slightly above, so that alpha runs
across the page and F1 up it: a path that turns back in alpha (the maximum
of alpha of the McNamara path, seed Fig. 5) shows its fold, and the two
branches of the closed form, which seem to cross in the load-displacement
plane, are seen to join there without crossing (no bifurcation).
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.ticker import MaxNLocator

from ncstab.plotting.curves import (
    CurvesContext,
    curves_context,
    draw_path,
    figure_title,
    mark_events,
    overlay_colour,
)
from ncstab.plotting.legend import CLOSED_FORM_STYLE
from ncstab.plotting.style import AXIS_LABELS, FIGURE_SIZE, RC_PARAMS, force_label

__all__ = ["VIEW", "curves_3d_figure"]

#: (elevation, azimuth) of the view, degrees: alpha mostly across, F1 up, Delta1* in depth.
VIEW = (20.0, -20.0)


def _draw_overlay_3d(axes: Axes, context: CurvesContext, k: int, box: tuple[np.ndarray, np.ndarray]) -> None:
    overlay, case = context.overlays[k], context.cases[k]
    assert overlay is not None
    low, high = box
    for branch in overlay.branches:
        xyz = np.column_stack([branch.D1, branch.alpha, branch.F1])
        outside = ((xyz < low) | (xyz > high)).any(axis=1)
        xyz[outside] = np.nan  # 3-D axes do not clip
        if np.isfinite(xyz).all(axis=1).sum() < 2:
            continue
        axes.plot(*xyz.T, color=overlay_colour(context, k, branch.name),
                  gid=f"closed_form:{branch.name}:{case.label}", label="_closed form", **CLOSED_FORM_STYLE)
    if overlay.blocking is not None:
        F1 = case.F[:, 0]
        start = overlay.branches[0].F1[-1] if overlay.branches else np.nanmin(F1)
        top = max(float(np.nanmax(F1)), float(start))
        block = overlay.blocking
        axes.plot([block.D1, block.D1], [block.alpha, block.alpha], [start, top], color=context.colours[k],
                  gid=f"closed_form:blocking:{case.label}", label="_blocking", **CLOSED_FORM_STYLE)


#: Space between a 3-D axis and its label, points (6 let "0.025" run into the label).
LABEL_PAD = 20


def curves_3d_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """3-D curves (Delta1*, alpha, F1), one per case, with events and closed forms.

    Returns
    -------
    Figure
        One 3-D axes viewed from :data:`VIEW`.  Closed forms are cut (NaN)
        outside the box of the computed data, since 3-D axes do not clip.
    """
    with rc_context(RC_PARAMS):
        context = curves_context(dataset)
        if figure is None:
            # No layout engine: constrained layout leaves wide margins around 3-D axes.
            fig = Figure(figsize=FIGURE_SIZE)
            axes = fig.add_axes((0.06, 0.0, 0.9, 0.86), projection="3d")
        else:
            fig = figure
            axes = fig.add_subplot(projection="3d")
        legend = context.legend()
        data = [np.column_stack([c.u[:, 0], c.alpha, c.F[:, 0]]) for c in context.cases]
        points = [p for p in data if p.size]
        stacked = np.concatenate(points) if points else np.empty((0, 3))
        finite = stacked[np.isfinite(stacked).all(axis=1)]
        low = finite.min(axis=0) if finite.size else np.zeros(3)
        high = finite.max(axis=0) if finite.size else np.ones(3)
        pad = 0.05 * np.maximum(high - low, 1e-6)
        box = (low - pad, high + pad)
        for k, case in enumerate(context.cases):
            draw_path(axes, context, legend, k, case.u[:, 0], case.alpha, case.F[:, 0])
            if context.draws_overlay(k):
                _draw_overlay_3d(axes, context, k, box)
                overlay = context.overlays[k]
                assert overlay is not None
                legend.closed_form(overlay.equations)
            mark_events(axes, context, legend, k, lambda e: (e.u[0], e.alpha, e.F[0]))
        if finite.size:
            axes.set_xlim(box[0][0], box[1][0])
            axes.set_ylim(box[0][1], box[1][1])
            axes.set_zlim(box[0][2], box[1][2])
        axes.set_xlabel(AXIS_LABELS["D1"], labelpad=LABEL_PAD)  # clear of the tick labels
        axes.set_ylabel(AXIS_LABELS["alpha"], labelpad=LABEL_PAD)
        axes.set_zlabel(force_label(context.normal), labelpad=LABEL_PAD)
        for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
            axis.set_major_locator(MaxNLocator(4))
        axes.view_init(elev=VIEW[0], azim=VIEW[1])
        axes.set_box_aspect(None, zoom=0.88)
        fig.suptitle(figure_title(dataset, "load_displacement_rotation"), fontsize=10)
        legend.draw(fig, axes, place="corner")
    return fig
