"""Parameter-plane figures of large 2-D sweeps: a field over the two swept parameters.

Thousands of paths over a plane of two parameters (``gamma`` x ``F2_lateral``)
are not drawn as curves: each case is a cell of the plane, coloured by one
quantity of a state of its path.  One row per law; one column for the end of
the path and one for each event located in at least one case (in the order
of :data:`ncstab.plotting.style.EVENT_MARKERS`).  The quantity is the one the
figure kind is about:

===============================  =========================================
kind                             field
===============================  =========================================
``load_displacement``            the load F1* (``F``, ``<event>_F``)
``load_rotation``                the rotation alpha (``alpha``, ``<event>_alpha``)
``load_displacement_rotation``   the displacement Delta1* (``u``, ``<event>_u``)
===============================  =========================================

(The ``stability`` kind draws the stability diagram,
:mod:`ncstab.plotting.diagrams`.)  Cells where the event is not located are
light grey, failed cases cross-hatched.  Each column has one colour bar shared
by the laws.  Axes carry gids ``"plane:<column>:<law>"``, colour bars
``"colorbar:<column>"``; the meshes are rasterised.  A geometric sweep (a
``scale = "log"`` range) gets a log axis.
"""

from __future__ import annotations

import textwrap

import numpy as np
import xarray as xr
from matplotlib import colormaps, rc_context
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch

from ncstab.plotting.curves import figure_title
from ncstab.plotting.panel_grid import panel_grid, title_and_legend
from ncstab.plotting.plane_grid import cell_edges, hatch_cells, is_geometric, parameter_label
from ncstab.plotting.style import EVENT_MARKERS, RC_PARAMS, law_display_name
from ncstab.plotting.sweep_arrays import (
    end_values,
    event_values,
    events_present,
    path_values,
    quantity_label,
)
from ncstab.plotting.sweep_shape import sweep_shape

__all__ = ["PLANE_QUANTITIES", "parameter_plane_figure", "plane_fields"]

#: Figure kind -> the quantity of its field.
PLANE_QUANTITIES = {"load_displacement": "F1", "load_rotation": "alpha", "load_displacement_rotation": "D1"}
#: Colour of cells where the event is not located; hatching of failed cases.
NOT_REACHED_COLOUR = "0.9"
FAILED_HATCH = "xxx"
FAILED_COLOUR = "0.35"
#: Size of one panel, inches (width, height).
PANEL_SIZE = (2.3, 1.9)
FIELD_COLORMAP = "viridis"


def _plane(dataset: xr.Dataset, values: np.ndarray, dims: list[str], x_name: str, y_name: str) -> np.ndarray:
    """``(*case_dims,)`` values -> ``(law, y, x)`` (swept dimensions of length 1 dropped)."""
    array = xr.DataArray(values, dims=dims)
    array = array.squeeze([d for d in dims if d not in ("law", x_name, y_name)])
    if "law" not in array.dims:
        array = array.expand_dims("law")
    return np.asarray(array.transpose("law", y_name, x_name).values)


def plane_fields(dataset: xr.Dataset, kind: str) -> dict[str, np.ndarray]:
    """The fields of a parameter-plane figure, by column: ``"end"`` then the events located.

    Returns
    -------
    dict
        Column -> ``(law, y, x)`` array of the kind's quantity (:data:`PLANE_QUANTITIES`),
        x and y the first and second swept parameter; NaN where the event is not located.
    """
    shape = sweep_shape(dataset)
    x_name, y_name = shape.swept
    dims = list(shape.dims)
    quantity = PLANE_QUANTITIES[kind]
    n_steps = np.asarray(dataset["n_steps"].transpose(*dims).values)
    fields = {"end": _plane(dataset, end_values(path_values(dataset, quantity, dims), n_steps), dims, x_name, y_name)}
    for event in events_present(dataset, list(EVENT_MARKERS)):
        fields[event] = _plane(dataset, event_values(dataset, event, quantity, dims), dims, x_name, y_name)
    return fields


def parameter_plane_figure(dataset: xr.Dataset, kind: str, figure: Figure | None = None) -> Figure:
    """A field over the plane of the two swept parameters, per law and state (module docstring).

    Parameters
    ----------
    dataset
        A path Dataset sweeping exactly two parameters with more than one value.
    kind
        A key of :data:`PLANE_QUANTITIES`.
    figure
        A Figure to draw into (a new one, sized to the panels, by default).
    """
    shape = sweep_shape(dataset)
    if len(shape.swept) != 2:
        raise ValueError(f"a parameter plane needs two swept parameters; this Dataset sweeps {list(shape.swept)}")
    x_name, y_name = shape.swept
    dims = list(shape.dims)
    fields = plane_fields(dataset, kind)
    status = (np.asarray(dataset["status"].transpose(*dims).values).astype(str) if "status" in dataset
              else np.full(dataset["n_steps"].transpose(*dims).shape, "finished"))
    failed = _plane(dataset, np.char.startswith(status, "failed"), dims, x_name, y_name)
    x_values, y_values = np.asarray(dataset[x_name].values, float), np.asarray(dataset[y_name].values, float)
    x_log, y_log = is_geometric(x_values), is_geometric(y_values)
    x_edges, y_edges = cell_edges(x_values, log=x_log), cell_edges(y_values, log=y_log)
    normal = str(dataset.attrs.get("normal", "deformable"))
    symbol = quantity_label(PLANE_QUANTITIES[kind], normal)
    n_rows, n_cols = len(shape.laws), len(fields)

    n_failed = int(failed.sum())
    handles = [Patch(facecolor=NOT_REACHED_COLOUR, edgecolor="0.6", label="event not located")]
    if n_failed:
        handles.append(Patch(facecolor="white", edgecolor=FAILED_COLOUR, hatch=FAILED_HATCH,
                             label=f"failed case ({n_failed} of {failed.size}; see 'status')"))
    title = (figure_title(dataset, kind, width=110).rsplit("\n", 1)[0]
             + f"\n{symbol} over ({parameter_label(dataset, x_name)}, {parameter_label(dataset, y_name)})")

    with rc_context({**RC_PARAMS, "hatch.linewidth": 0.7}):
        grid = panel_grid(n_rows, n_cols, PANEL_SIZE, bars="columns", share="all", figure=figure)
        figure = grid.figure
        cmap = colormaps[FIELD_COLORMAP].with_extremes(bad=NOT_REACHED_COLOUR)
        for col, (column, field) in enumerate(fields.items()):
            finite = field[np.isfinite(field)]
            low, high = (float(finite.min()), float(finite.max())) if finite.size else (0.0, 1.0)
            if high <= low:
                low, high = low - 0.5, high + 0.5
            norm = Normalize(low, high)
            mesh = None
            for row, law in enumerate(shape.laws):
                axes = grid.axes[row, col]
                axes.grid(False)
                axes.set_gid(f"plane:{column}:{law}")
                mesh = axes.pcolormesh(x_edges, y_edges, np.ma.masked_invalid(field[row]), cmap=cmap, norm=norm,
                                       shading="flat", rasterized=True)
                hatch_cells(axes, failed[row], x_edges, y_edges, FAILED_HATCH, FAILED_COLOUR, f"failed:{law}")
                if row == 0:
                    where = "the end of the path" if column == "end" else EVENT_MARKERS[column][3]
                    axes.set_title(textwrap.fill(f"at {where}", 30), fontsize=9)
                if col == 0:
                    axes.set_ylabel(f"{textwrap.fill(law_display_name(law), 26)}\n\n{parameter_label(dataset, y_name)}")
                if row == n_rows - 1:
                    axes.set_xlabel(parameter_label(dataset, x_name))
            first = grid.axes[0, 0]
            first.set_xscale("log" if x_log else "linear")
            first.set_yscale("log" if y_log else "linear")
            first.set_xlim(x_edges[0], x_edges[-1])
            first.set_ylim(y_edges[0], y_edges[-1])
            colorbar = figure.colorbar(mesh, cax=grid.colorbars[col], orientation="horizontal")
            colorbar.set_label(symbol)
            colorbar.ax.set_gid(f"colorbar:{column}")
        title_and_legend(figure, title, handles, ncols=len(handles))
    return figure
