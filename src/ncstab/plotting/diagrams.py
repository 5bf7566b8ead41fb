"""Stability diagrams: where the stability criteria are lost over a plane of two parameters.

A study sweeping two parameters (``gamma`` x ``F2_lateral``, ``gamma`` x
``alpha0``...) locates per case the first loss of Hill's condition
(``hill_loss``: the smallest eigenvalue of K_sym vanishes), the limit point
(``limit_point``: det K = 0, seed Eq. 36) and the loss of controllability
(``controllability_loss``: det K_SS = 0 under mixed control, seed Eq. 35).
:func:`stability_diagram_figure` draws, for each law (a row) and each of these
events (a column), the load F1* at which the event is located as a field over
the parameter plane; cells where the event is not reached are light grey.  The
region where Hill's condition fails strictly before the limit point
(:func:`hill_before_limit`) is hatched and outlined in every panel of the law;
failed cases are cross-hatched.  Every panel whose event is reached in fewer
than 1 % of its cells says so (:func:`sparse_note`), its few cells circled.

Built with :class:`matplotlib.figure.Figure` (no pyplot) under the project
style; the caller saves the figure.  See ``docs/stability-diagrams.md``.
"""

from __future__ import annotations

import math
import textwrap

import numpy as np
import xarray as xr
from matplotlib import colormaps, rc_context
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ncstab.plotting.panel_grid import grid_width, legend_columns, panel_grid, title_and_legend
from ncstab.plotting.plane_grid import (
    cell_edges,
    hatch_cells,
    is_geometric,
    outline,
    parameter_label,
)
from ncstab.plotting.style import (
    RC_PARAMS,
    fixed_parameters_text,
    force_label,
    law_display_name,
    symbolic_text,
)

__all__ = [
    "DIAGRAM_EVENTS",
    "diagram_dims",
    "failed_cases",
    "hill_before_limit",
    "parameter_label",
    "sparse_note",
    "stability_diagram_figure",
]

#: The events drawn, one column each: event -> column title.
DIAGRAM_EVENTS: dict[str, str] = {
    "hill_loss": "loss of Hill's condition",
    "limit_point": "limit point (det K = 0)",
    "controllability_loss": "loss of controllability",
}

#: Arclength margin for "strictly before": Hill's condition and det K vanish at
#: the same state for hyperelastic laws (K symmetric on the path, seed Eq. 41),
#: where the two located arclengths differ only by the event brackets (event_tol).
STRICTLY_BEFORE = 1e-7

#: Colour of cells where the event is not reached.
NOT_REACHED_COLOUR = "0.9"
#: Hatching: Hill's condition lost before the limit point; failed cases.
HILL_HATCH = "///"
HILL_COLOUR = "crimson"
FAILED_HATCH = "xxx"
FAILED_COLOUR = "0.35"
#: Colormap of the event load F1*.
FIELD_COLORMAP = "viridis"
#: A panel whose event is reached in fewer cells than this share of them says so in a note
#: (none reached: "not reached"; a few: how many, circled), like every other such panel.
SPARSE_FRACTION = 0.01
#: Size of one panel, inches (width, height).
PANEL_SIZE = (2.9, 2.3)


def sparse_note(field: np.ndarray) -> str | None:
    """The note of a panel whose event is reached in fewer than :data:`SPARSE_FRACTION` of its
    cells: ``"not reached\nin this plane"``, or ``"reached in 1 of 4,096\ncells (circled)"``;
    None for a panel that shows its field."""
    reached, total = int(np.isfinite(field).sum()), int(field.size)
    if reached >= SPARSE_FRACTION * total:
        return None
    if reached == 0:
        return "not reached\nin this plane"
    return f"reached in {reached:,} of {total:,}\ncells only (circled)"


def diagram_dims(dataset: xr.Dataset) -> tuple[str, str]:
    """The two swept parameters of a stability diagram (x axis, y axis).

    Raises
    ------
    ValueError
        If ``status`` has other than two dimensions besides ``law``; the
        message names them.
    """
    dims = [d for d in dataset["status"].dims if d != "law"]
    if len(dims) != 2:
        raise ValueError(
            "a stability diagram needs exactly two swept parameters besides 'law'; "
            f"this Dataset sweeps {len(dims)}: {dims}"
        )
    return dims[0], dims[1]


def hill_before_limit(dataset: xr.Dataset) -> xr.DataArray:
    """Where Hill's condition fails strictly before the limit point.

    True where ``hill_loss`` is located and either ``hill_loss_s <
    limit_point_s - STRICTLY_BEFORE`` or no limit point is located on the
    path.  Hyperelastic laws (K symmetric on the equilibrium path) lose both
    at the same state and are False there.

    Returns
    -------
    xarray.DataArray
        Boolean, dims ``(law, p, q)`` like ``status``.
    """
    hill = _event_field(dataset, "hill_loss", "s")
    limit = _event_field(dataset, "limit_point", "s")
    before = hill.notnull() & (limit.isnull() | (hill < limit - STRICTLY_BEFORE))
    before = before.transpose(*dataset["status"].dims)
    before.attrs = {
        "long_name": "Hill's condition lost before the limit point",
        "description": f"hill_loss located and (no limit_point, or hill_loss_s < limit_point_s - {STRICTLY_BEFORE:g})",
    }
    return before.rename("hill_before_limit")


def _event_field(dataset: xr.Dataset, event: str, field: str) -> xr.DataArray:
    """``<event>_<field>``, or NaN over the cases where the archive has no table for the event
    (a lean archive leaves out the events that never occur); the first dof of ``_F``."""
    name = f"{event}_{field}"
    if name in dataset:
        values = dataset[name]
        return values.isel(dof=0) if "dof" in values.dims else values
    return xr.full_like(dataset["n_steps"], np.nan, dtype=float)


def failed_cases(dataset: xr.Dataset) -> xr.DataArray:
    """Boolean ``(law, p, q)``: cases whose status is ``failed:<reason>``."""
    status = dataset["status"].astype(str)
    return xr.apply_ufunc(lambda s: np.char.startswith(s, "failed"), status)


def _title(dataset: xr.Dataset) -> str:
    description = str(dataset.attrs.get("study_description") or dataset.attrs.get("description") or "")
    if description:
        return textwrap.fill(symbolic_text(description), 100)
    details = fixed_parameters_text(dataset.attrs)
    title = "Stability diagram"
    return f"{title}: {details}" if details else title


def stability_diagram_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Stability diagram: F1* at the located events over the plane of two swept parameters.

    One row per law, one column per event of :data:`DIAGRAM_EVENTS`; each
    panel is a ``pcolormesh`` of ``<event>_F`` (dof 1) over the cells of the
    sweep, with one colour bar per column (shared by the laws).  Cells where
    the event is not reached are light grey; the region of
    :func:`hill_before_limit` is hatched and outlined; failed cases are
    cross-hatched and counted in a note.

    Parameters
    ----------
    dataset
        A path Dataset whose ``status`` has dims ``(law, p, q)``; ``p`` is the
        x axis, ``q`` the y axis.
    figure
        Figure to draw on (cleared); by default a new one sized to the panels.

    Returns
    -------
    matplotlib.figure.Figure
        Axes carry gids ``"diagram:<event>:<law>"`` and ``"colorbar:<event>"``.

    Raises
    ------
    ValueError
        If the Dataset does not sweep exactly two parameters besides ``law``.
    """
    x_name, y_name = diagram_dims(dataset)
    laws = [str(law) for law in dataset["law"].values]
    n_rows, n_cols = len(laws), len(DIAGRAM_EVENTS)
    before = hill_before_limit(dataset).transpose("law", y_name, x_name).values
    failed = failed_cases(dataset).transpose("law", y_name, x_name).values
    x_log, y_log = is_geometric(dataset[x_name].values), is_geometric(dataset[y_name].values)
    x_edges = cell_edges(dataset[x_name].values, log=x_log)
    y_edges = cell_edges(dataset[y_name].values, log=y_log)
    normal = str(dataset.attrs.get("normal", "deformable"))
    load = "$\\hat F_1$" if normal == "rigid" else "$F_1^*$"

    handles = [
        Patch(facecolor=NOT_REACHED_COLOUR, edgecolor="0.6", label="not reached (event not located)"),
        Patch(facecolor="white", edgecolor=HILL_COLOUR, hatch=HILL_HATCH,
              label="Hill's condition lost strictly before the limit point"),
    ]
    n_failed = int(failed.sum())
    if n_failed:
        handles.append(Patch(facecolor="white", edgecolor=FAILED_COLOUR, hatch=FAILED_HATCH,
                             label=f"failed case ({n_failed} of {failed.size}; see 'status')"))
    ncols = legend_columns(grid_width(n_cols, PANEL_SIZE[0]), len(handles), max(len(h.get_label()) for h in handles))

    with rc_context({**RC_PARAMS, "hatch.linewidth": 0.7}):
        grid = panel_grid(n_rows, n_cols, PANEL_SIZE, bars="columns", share="all",
                          legend_rows=math.ceil(len(handles) / ncols), figure=figure)
        figure, axes_grid = grid.figure, grid.axes
        for col, (event, event_title) in enumerate(DIAGRAM_EVENTS.items()):
            field = _event_field(dataset, event, "F").transpose("law", y_name, x_name).values
            finite = field[np.isfinite(field)]
            low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
            if high <= low:
                low, high = low - 0.5, high + 0.5
            norm = Normalize(low, high)
            cmap = colormaps[FIELD_COLORMAP].with_extremes(bad=NOT_REACHED_COLOUR)
            mesh = None
            for row, law in enumerate(laws):
                axes = axes_grid[row, col]
                axes.grid(False)
                axes.set_gid(f"diagram:{event}:{law}")
                values = np.ma.masked_invalid(field[row])
                mesh = axes.pcolormesh(x_edges, y_edges, values, cmap=cmap, norm=norm, shading="flat", rasterized=True)
                hatch_cells(axes, before[row], x_edges, y_edges, HILL_HATCH, HILL_COLOUR, f"hill_before_limit:{law}")
                boundary = outline(before[row], x_edges, y_edges)
                if boundary:
                    lines = LineCollection(boundary, colors=HILL_COLOUR, linewidths=0.9, zorder=4)
                    lines.set_gid(f"hill_before_limit_outline:{law}")
                    axes.add_collection(lines)
                hatch_cells(axes, failed[row], x_edges, y_edges, FAILED_HATCH, FAILED_COLOUR, f"failed:{law}")
                note = sparse_note(field[row])
                if note is not None:  # every nearly empty panel says so, the same way
                    axes.text(0.5, 0.5, note, transform=axes.transAxes, ha="center",
                              va="center", color="0.3", fontsize=9, gid=f"not_reached:{law}")
                    rows_at, columns_at = np.nonzero(np.isfinite(field[row]))
                    if rows_at.size:  # the few cells reached, circled: a cell alone is hard to see
                        x_mid = (x_edges[columns_at] + x_edges[columns_at + 1]) / 2
                        y_mid = (y_edges[rows_at] + y_edges[rows_at + 1]) / 2
                        axes.plot(x_mid, y_mid, linestyle="none", marker="o", markersize=9, markerfacecolor="none",
                                  markeredgecolor="crimson", markeredgewidth=1.2, clip_on=False,
                                  gid=f"sparse_cells:{event}:{law}")
                axes.set_xscale("log" if x_log else "linear")
                axes.set_yscale("log" if y_log else "linear")
                axes.set_xlim(x_edges[0], x_edges[-1])
                axes.set_ylim(y_edges[0], y_edges[-1])
                if row == 0:
                    axes.set_title(f"{load} at {event_title}")
                if col == 0:
                    axes.set_ylabel(f"{textwrap.fill(law_display_name(law), 26)}\n\n{parameter_label(dataset, y_name)}")
                if row == n_rows - 1:
                    axes.set_xlabel(parameter_label(dataset, x_name))
            colorbar = figure.colorbar(mesh, cax=grid.colorbars[col], orientation="horizontal")
            colorbar.set_label(force_label(normal))
            colorbar.ax.set_gid(f"colorbar:{event}")

        title_and_legend(figure, _title(dataset), handles, ncols)
    return figure
