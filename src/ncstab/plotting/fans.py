"""Fans: the paths of a large 1-D sweep drawn together, with their envelope and a few labelled.

For more cases than curves can be told apart (:data:`ncstab.plotting.sweep_shape.MAX_CURVES`)
along one swept parameter (or three and more), each law gets a panel (a
column; the stability kind has three rows: det K, Hill's eigenvalue, d2W)
holding:

* the paths as one :class:`~matplotlib.collections.LineCollection`,
  rasterised, coloured along the swept parameter (a colour bar); at most
  :data:`MAX_FAN_LINES` paths per figure are drawn, every k-th in sweep order,
  so the cost of drawing is bounded whatever the sweep;
* the envelope of *all* the paths: their least and greatest value at
  :data:`ENVELOPE_BINS` values of x across the panel (:func:`envelope`);
* :data:`LABELLED_CASES` cases spread along the sweep, drawn on top and named
  in the legend;
* the located events of every case, one scatter per event kind.

Artists carry gids ``"fan:<law>"``, ``"envelope:<law>"``, ``"path:<label>"``,
``"events:<event>:<law>"``; the legend sits below the panels (a fixed place).
"""

from __future__ import annotations

import math

import numpy as np
import xarray as xr
from matplotlib import colormaps, patheffects, rc_context
from matplotlib.cm import ScalarMappable
from matplotlib.collections import LineCollection
from matplotlib.colors import Normalize
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.curves import figure_title, set_limits
from ncstab.plotting.legend import event_style
from ncstab.plotting.panel_grid import grid_width, legend_columns, panel_grid, title_and_legend
from ncstab.plotting.plane_grid import parameter_label
from ncstab.plotting.style import (
    EVENT_MARKERS,
    FAILED_COLOUR,
    RC_PARAMS,
    format_parameter,
    law_display_name,
)
from ncstab.plotting.sweep_arrays import event_values, events_present, path_values, quantity_label
from ncstab.plotting.sweep_shape import sweep_shape

__all__ = ["ENVELOPE_BINS", "FAN_PANELS", "LABELLED_CASES", "MAX_FAN_LINES", "fan_figure"]

#: Panels (x quantity, y quantity) of each figure kind, one row each.
FAN_PANELS: dict[str, tuple[tuple[str, str], ...]] = {
    "load_rotation": (("alpha", "F1"),),
    "load_displacement": (("D1", "F1"),),
    "stability": (("D1", "det_K"), ("D1", "hill"), ("D1", "d2W")),
}
#: Most paths drawn in one figure (spread over its panels); the envelope uses them all.
MAX_FAN_LINES = 4096
#: Values of x at which the envelope takes the least and greatest value of the paths.
ENVELOPE_BINS = 120
ENVELOPE_STYLE = {"color": "k", "linewidth": 1.2, "linestyle": (0, (5, 2))}
#: Paths whose segments are interpolated together (memory: ~ block x bins values).
ENVELOPE_BLOCK = 4096
#: Cases drawn on top and named in the legend (the first, the last, evenly between).
LABELLED_CASES = 5
#: Size of one panel, inches.
PANEL_SIZE = (4.0, 2.4)
COLORMAP = "viridis"


def envelope(x: np.ndarray, y: np.ndarray, bins: int = ENVELOPE_BINS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Least and greatest y of a set of polylines at ``bins`` values of x evenly spread over their range.

    Each polyline is linear between its stored states: at a grid value of x
    it takes the value of every segment that spans it (a path that turns back
    in x spans it several times).  The states of a segment along y (constant
    x) and isolated states count at the grid value nearest to them.

    Parameters
    ----------
    x, y
        ``(paths, states)``, NaN past the end of a path.
    bins
        Number of grid values.

    Returns
    -------
    (grid, lower, upper)
        Shape (m,) each: the grid values reached by at least one path.
    """
    finite = np.isfinite(x) & np.isfinite(y)
    if not finite.any():
        return np.empty(0), np.empty(0), np.empty(0)
    low, high = float(x[finite].min()), float(x[finite].max())
    width = (high - low) / (bins - 1) if high > low else 1.0
    lower, upper = np.full(bins, np.inf), np.full(bins, -np.inf)
    # States on a segment along y, or with no finite neighbour, count at the nearest grid value.
    along_y = np.zeros_like(finite)
    same = finite[:, :-1] & finite[:, 1:] & (x[:, :-1] == x[:, 1:])
    along_y[:, :-1] |= same
    along_y[:, 1:] |= same
    alone = finite & ~np.pad(finite[:, 1:], ((0, 0), (0, 1))) & ~np.pad(finite[:, :-1], ((0, 0), (1, 0)))
    points = along_y | alone
    nearest = np.clip(np.rint((x[points] - low) / width).astype(int), 0, bins - 1)
    np.minimum.at(lower, nearest, y[points])
    np.maximum.at(upper, nearest, y[points])
    for block in range(0, x.shape[0], ENVELOPE_BLOCK):  # blocks of paths: bounded memory
        xs, ys = x[block:block + ENVELOPE_BLOCK], y[block:block + ENVELOPE_BLOCK]
        keep = np.isfinite(xs[:, :-1] + xs[:, 1:] + ys[:, :-1] + ys[:, 1:]) & (xs[:, :-1] != xs[:, 1:])
        a, b, ya, yb = xs[:, :-1][keep], xs[:, 1:][keep], ys[:, :-1][keep], ys[:, 1:][keep]
        # Grid values within rounding (1e-9 of the spacing) of a segment's end count as on it.
        first = np.clip(np.ceil((np.minimum(a, b) - low) / width - 1e-9), 0, bins - 1).astype(int)
        last = np.clip(np.floor((np.maximum(a, b) - low) / width + 1e-9), 0, bins - 1).astype(int)
        count = np.maximum(last - first + 1, 0)
        segment = np.repeat(np.arange(a.size), count)
        index = first[segment] + np.arange(segment.size) - np.repeat(np.cumsum(count) - count, count)
        at = low + width * index
        value = ya[segment] + (at - a[segment]) / (b - a)[segment] * (yb - ya)[segment]
        np.minimum.at(lower, index, value)
        np.maximum.at(upper, index, value)
    reached = np.isfinite(lower)
    grid = low + width * np.arange(bins)
    return grid[reached], lower[reached], upper[reached]


def _labelled(n: int) -> np.ndarray:
    """Indices of the labelled cases: evenly spread, first and last included."""
    return np.unique(np.linspace(0, n - 1, min(LABELLED_CASES, n)).round().astype(int))


def fan_figure(dataset: xr.Dataset, kind: str, figure: Figure | None = None) -> Figure:
    """The fan of a large sweep for a planar or stability figure kind (module docstring).

    Parameters
    ----------
    dataset
        A path Dataset.
    kind
        A key of :data:`FAN_PANELS`.
    figure
        A Figure to draw into (a new one, sized to the panels, by default).
    """
    shape = sweep_shape(dataset)
    dims = list(shape.dims)
    has_law = "law" in dims
    if has_law:  # law first, then the others in order
        dims.remove("law")
        dims.insert(0, "law")
    n_laws = len(shape.laws)
    n_steps = np.asarray(dataset["n_steps"].transpose(*dims).values).reshape(n_laws, -1)
    per_law = n_steps.shape[1]
    status = (np.asarray(dataset["status"].transpose(*dims).values).astype(str).reshape(n_laws, -1)
              if "status" in dataset else np.full(n_steps.shape, "finished"))
    failed = np.char.startswith(status, "failed")
    swept = [d for d in dims if d != "law"]
    if len(shape.swept) == 1:  # colour along the swept parameter, else along the case number
        name = shape.swept[0]
        grids = np.meshgrid(*[np.asarray(dataset[d].values) if d in dataset.coords else np.arange(dataset.sizes[d])
                              for d in swept], indexing="ij")
        colour_values = np.asarray(grids[swept.index(name)], dtype=float).ravel()
        colour_label = parameter_label(dataset, name)
    else:
        colour_values = np.arange(1, per_law + 1, dtype=float)
        colour_label = "case number (C order over " + " × ".join(swept) + ")"
    norm = Normalize(float(np.nanmin(colour_values)), float(np.nanmax(colour_values)) or 1.0)
    cmap = colormaps[COLORMAP]
    rows = FAN_PANELS[kind]
    stride = max(1, math.ceil(per_law * n_laws * len(rows) / MAX_FAN_LINES))  # paths drawn: 1 in stride
    normal = str(dataset.attrs.get("normal", "deformable"))

    def label(c: int) -> str:
        index = np.unravel_index(c, [dataset.sizes[d] for d in swept]) if swept else ()
        parts = [format_parameter(d, dataset[d].values[i].item() if d in dataset.coords else i)
                 for d, i in zip(swept, index) if dataset.sizes[d] > 1]
        return ", ".join(parts) or f"case {c + 1}"

    events = events_present(dataset, list(EVENT_MARKERS))
    n_failed = int(failed.sum())
    entries = len(_labelled(per_law)) + 1 + len(events) + bool(n_failed)
    width = grid_width(n_laws, PANEL_SIZE[0], bars="right")
    ncols = legend_columns(width, entries, 40)
    with rc_context(RC_PARAMS):
        grid = panel_grid(len(rows), n_laws, PANEL_SIZE, bars="right", share="rows",
                          legend_rows=math.ceil(entries / ncols), figure=figure)
        figure = grid.figure
        handles: dict[str, object] = {}
        for r, (xq, yq) in enumerate(rows):
            x_all = path_values(dataset, xq, dims).reshape(n_laws, per_law, -1)
            y_all = path_values(dataset, yq, dims).reshape(n_laws, per_law, -1)
            if yq == "d2W" and "stage" in dataset:
                # d2W jumps where one stage hands over to the next: break its lines there.
                stage = path_values_stage(dataset, dims).reshape(n_laws, per_law, -1)
                y_all = np.where(np.diff(stage, axis=-1, prepend=stage[..., :1]) != 0, np.nan, y_all)
            limits = []
            for col, law in enumerate(shape.laws):
                axes = grid.axes[r, col]
                x, y = x_all[col], y_all[col]
                colours = cmap(norm(colour_values))
                colours[failed[col]] = (0.6, 0.6, 0.6, 1.0)
                drawn = np.arange(0, per_law, stride)
                fan = LineCollection(np.stack([x[drawn], y[drawn]], axis=-1), colors=colours[drawn],
                                     linewidths=0.6, alpha=0.6, rasterized=True, zorder=2)
                fan.set_gid(f"fan:{law}")
                axes.add_collection(fan, autolim=False)
                centres, lower, upper = envelope(x, y)
                if centres.size:
                    axes.fill_between(centres, lower, upper, color="0.9", zorder=1, linewidth=0,
                                      gid=f"envelope:{law}")
                    for bound in (lower, upper):
                        axes.plot(centres, bound, zorder=3, gid=f"envelope_line:{law}", **ENVELOPE_STYLE)
                    handles.setdefault("envelope", Line2D([], [], **ENVELOPE_STYLE,
                                                          label=f"envelope of all {per_law} paths per law"))
                for c in _labelled(per_law):
                    text = label(c)
                    axes.plot(x[c], y[c], color=colours[c], linewidth=1.8, zorder=4, gid=f"path:{text}",
                              path_effects=[patheffects.Stroke(linewidth=3.0, foreground="white"), patheffects.Normal()])
                    handles.setdefault(f"case:{c}", Line2D([], [], color=colours[c], linewidth=1.8, label=text))
                for event in events:
                    ex = event_values(dataset, event, xq, dims).reshape(n_laws, per_law)[col]
                    ey = event_values(dataset, event, yq, dims).reshape(n_laws, per_law)[col]
                    located = np.isfinite(ex) & np.isfinite(ey)
                    if not located.any():
                        continue
                    style = event_style(event, "0.5")
                    marker, _, filled, text = EVENT_MARKERS[event]
                    if marker == "x":  # an unfilled marker: its colour is the face colour
                        look: dict[str, object] = {"c": "k", "linewidths": 1.0}
                    else:
                        look = {"c": colours[located] if filled else "none", "edgecolors": "k", "linewidths": 0.5}
                    points = axes.scatter(ex[located], ey[located], s=14, marker=marker, zorder=5,
                                          rasterized=True, **look)
                    points.set_gid(f"events:{event}:{law}")
                    handles.setdefault(f"event:{event}", Line2D([], [], linestyle="none", **style, label=text))
                limits.append((x, y))
                if r == 0:
                    axes.set_title(law_display_name(law), fontsize=9)
                if col == 0:
                    axes.set_ylabel(quantity_label(yq, normal))
                if r == len(rows) - 1:
                    axes.set_xlabel(quantity_label(xq, normal))
                if yq in ("det_K", "hill", "d2W"):
                    axes.axhline(0.0, color="k", linewidth=0.7, zorder=1)
            set_limits(grid.axes[r, 0], [v[0] for v in limits], [v[1] for v in limits])
        if n_failed:
            handles["failed"] = Line2D([], [], color=FAILED_COLOUR, label=f"failed cases ({n_failed}; see 'status')")
        colorbar = figure.colorbar(ScalarMappable(norm=norm, cmap=cmap), cax=grid.colorbars[0])
        colorbar.set_label(colour_label)
        colorbar.ax.set_gid("colorbar")
        drawn_note = f"{per_law} cases per law" + (f", one path in {stride} drawn" if stride > 1 else "")
        title_and_legend(figure, figure_title(dataset, kind, width=100) + f" — {drawn_note}",
                         list(handles.values()), ncols)
    return figure


def path_values_stage(dataset: xr.Dataset, dims: list[str]) -> np.ndarray:
    """``(*case_dims, step)`` loading-stage index of every stored state (NaN past n_steps)."""
    array = np.asarray(dataset["stage"].transpose(*dims, "step").values, dtype=float)
    n_steps = np.asarray(dataset["n_steps"].transpose(*dims).values)
    array[np.arange(array.shape[-1]) >= n_steps[..., None]] = np.nan
    return array
