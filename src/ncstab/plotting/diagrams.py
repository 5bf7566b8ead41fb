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
failed cases are cross-hatched.

Built with :class:`matplotlib.figure.Figure` (no pyplot) under the project
style; the caller saves the figure.  See ``docs/stability-diagrams.md``.
"""

from __future__ import annotations

import textwrap

import numpy as np
import xarray as xr
from matplotlib import colormaps, rc_context
from matplotlib.axes import Axes
from matplotlib.collections import LineCollection, PatchCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.patches import Patch, Rectangle

from ncstab.plotting.style import RC_PARAMS, fixed_parameters_text, force_label, law_display_name

__all__ = [
    "DIAGRAM_EVENTS",
    "diagram_dims",
    "failed_cases",
    "hill_before_limit",
    "parameter_label",
    "stability_diagram_figure",
]

#: The events drawn, one column each: event -> column title.
DIAGRAM_EVENTS: dict[str, str] = {
    "hill_loss": "loss of Hill's condition",
    "limit_point": "limit point (det K = 0)",
    "controllability_loss": "loss of controllability",
}

#: Axis labels of parameters known by name (others: long_name and units).
PARAMETER_LABELS: dict[str, str] = {
    "gamma": r"$\gamma = k_t/k_n$",
    "alpha0": r"$\alpha_0$ (rad)",
    "kappa": r"$\kappa$ (secondary contact stiffness / $k_n$)",
    "F2_lateral": r"lateral preload $F_2^* = F_2/(2R\,k_n)$",
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
#: Size of one panel, inches (width, height), and room for titles and colour bars.
PANEL_SIZE = (2.9, 2.3)
EXTRA_HEIGHT = 1.7


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
    hill = dataset["hill_loss_s"]
    limit = dataset["limit_point_s"]
    before = hill.notnull() & (limit.isnull() | (hill < limit - STRICTLY_BEFORE))
    before = before.transpose(*dataset["status"].dims)
    before.attrs = {
        "long_name": "Hill's condition lost before the limit point",
        "description": f"hill_loss located and (no limit_point, or hill_loss_s < limit_point_s - {STRICTLY_BEFORE:g})",
    }
    return before.rename("hill_before_limit")


def failed_cases(dataset: xr.Dataset) -> xr.DataArray:
    """Boolean ``(law, p, q)``: cases whose status is ``failed:<reason>``."""
    status = dataset["status"].astype(str)
    return xr.apply_ufunc(lambda s: np.char.startswith(s, "failed"), status)


def parameter_label(dataset: xr.Dataset, name: str) -> str:
    """Axis label of a swept parameter: its symbol, or long_name and units."""
    if name in PARAMETER_LABELS:
        return PARAMETER_LABELS[name]
    attrs = dataset[name].attrs if name in dataset.coords else {}
    label = str(attrs.get("long_name", name))
    units = str(attrs.get("units", ""))
    return f"{label} ({units})" if units not in ("", "1") else label


def _cell_edges(centres: np.ndarray) -> np.ndarray:
    """(n + 1,) cell edges around n increasing centres (midpoints, ends mirrored)."""
    centres = np.asarray(centres, dtype=float)
    if centres.size == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    middle = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - middle[0]], middle, [2 * centres[-1] - middle[-1]]])


def _outline(mask: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray) -> list[np.ndarray]:
    """Segments of the boundary of the union of cells where mask (shape (ny, nx)) is True."""
    padded = np.pad(mask, 1)
    segments = []
    # Vertical edges: between cells (j, i-1) and (j, i).
    for j, i in zip(*np.nonzero(padded[1:-1, 1:] != padded[1:-1, :-1])):
        segments.append(np.array([[x_edges[i], y_edges[j]], [x_edges[i], y_edges[j + 1]]]))
    # Horizontal edges: between cells (j-1, i) and (j, i).
    for j, i in zip(*np.nonzero(padded[1:, 1:-1] != padded[:-1, 1:-1])):
        segments.append(np.array([[x_edges[i], y_edges[j]], [x_edges[i + 1], y_edges[j]]]))
    return segments


def _hatch_cells(
    axes: Axes, mask: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray, hatch: str, colour: str, gid: str
) -> PatchCollection | None:
    """Hatch the cells where mask (ny, nx) is True, one rectangle per run along x."""
    rectangles = []
    for j in range(mask.shape[0]):
        row = np.concatenate([[False], mask[j], [False]])
        starts = np.flatnonzero(row[1:] & ~row[:-1])
        ends = np.flatnonzero(~row[1:] & row[:-1])
        for a, b in zip(starts, ends):
            rectangles.append(
                Rectangle((x_edges[a], y_edges[j]), x_edges[b] - x_edges[a], y_edges[j + 1] - y_edges[j])
            )
    if not rectangles:
        return None
    collection = PatchCollection(
        rectangles, facecolor="none", edgecolor=colour, hatch=hatch, linewidth=0.0, zorder=3
    )
    collection.set_gid(gid)
    axes.add_collection(collection)
    return collection


def _title(dataset: xr.Dataset) -> str:
    description = str(dataset.attrs.get("study_description") or dataset.attrs.get("description") or "")
    if description:
        return textwrap.fill(description, 100)
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
    x_edges = _cell_edges(dataset[x_name].values)
    y_edges = _cell_edges(dataset[y_name].values)
    normal = str(dataset.attrs.get("normal", "deformable"))
    load = "$\\hat F_1$" if normal == "rigid" else "$F_1^*$"

    with rc_context({**RC_PARAMS, "hatch.linewidth": 0.7}):
        if figure is None:
            figure = Figure(
                figsize=(PANEL_SIZE[0] * n_cols + 0.6, PANEL_SIZE[1] * n_rows + EXTRA_HEIGHT),
                layout="constrained",
            )
        else:
            figure.clear()
        axes_grid = np.atleast_2d(
            figure.subplots(n_rows, n_cols, sharex=True, sharey=True, squeeze=False)
        )
        for col, (event, event_title) in enumerate(DIAGRAM_EVENTS.items()):
            field = dataset[f"{event}_F"].isel(dof=0).transpose("law", y_name, x_name).values
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
                _hatch_cells(axes, before[row], x_edges, y_edges, HILL_HATCH, HILL_COLOUR, f"hill_before_limit:{law}")
                outline = _outline(before[row], x_edges, y_edges)
                if outline:
                    lines = LineCollection(outline, colors=HILL_COLOUR, linewidths=0.9, zorder=4)
                    lines.set_gid(f"hill_before_limit_outline:{law}")
                    axes.add_collection(lines)
                _hatch_cells(axes, failed[row], x_edges, y_edges, FAILED_HATCH, FAILED_COLOUR, f"failed:{law}")
                if not np.isfinite(field[row]).any():
                    axes.text(0.5, 0.5, "not reached\nin this plane", transform=axes.transAxes, ha="center",
                              va="center", color="0.45", fontsize=9, gid=f"not_reached:{law}")
                axes.set_xlim(x_edges[0], x_edges[-1])
                axes.set_ylim(y_edges[0], y_edges[-1])
                if row == 0:
                    axes.set_title(f"{load} at {event_title}")
                if col == 0:
                    axes.set_ylabel(f"{textwrap.fill(law_display_name(law), 26)}\n\n{parameter_label(dataset, y_name)}")
                if row == n_rows - 1:
                    axes.set_xlabel(parameter_label(dataset, x_name))
            colorbar = figure.colorbar(
                mesh, ax=list(axes_grid[:, col]), location="bottom", shrink=0.85, aspect=25, pad=0.02
            )
            colorbar.set_label(force_label(normal))
            colorbar.ax.set_gid(f"colorbar:{event}")

        handles = [
            Patch(facecolor=NOT_REACHED_COLOUR, edgecolor="0.6", label="not reached (event not located)"),
            Patch(facecolor="white", edgecolor=HILL_COLOUR, hatch=HILL_HATCH,
                  label="Hill's condition lost strictly before the limit point"),
        ]
        n_failed = int(failed.sum())
        if n_failed:
            handles.append(Patch(facecolor="white", edgecolor=FAILED_COLOUR, hatch=FAILED_HATCH,
                                 label=f"failed case ({n_failed} of {failed.size}; see 'status')"))
        figure.legend(handles=handles, loc="outside lower center", ncols=len(handles), frameon=False)
        figure.suptitle(_title(dataset))
    return figure
