"""Cells of a parameter plane: edges around swept values, hatching, outlines, axis labels.

Shared by the stability diagram (:mod:`ncstab.plotting.diagrams`) and the
parameter-plane figures of large 2-D sweeps (:mod:`ncstab.plotting.parameter_plane`).
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.axes import Axes
from matplotlib.collections import PathCollection
from matplotlib.path import Path

from ncstab.plotting.style import parameter_symbol

__all__ = [
    "PARAMETER_LABELS",
    "cell_edges",
    "cell_runs",
    "hatch_cells",
    "is_geometric",
    "outline",
    "parameter_label",
]

#: Axis labels of parameters known by name (others: symbol, or long_name and units).
PARAMETER_LABELS: dict[str, str] = {
    "gamma": r"$\gamma = k_t/k_n$",
    "alpha0": r"$\alpha_0$ (rad)",
    "kappa": r"$\kappa$ (secondary contact stiffness / $k_n$)",
    "F2_lateral": r"lateral preload $F_2^* = F_2/(2R\,k_n)$",
}

#: Relative spread of the ratios of successive values below which a sweep is
#: geometric (a ``scale = "log"`` range: numpy.geomspace rounds to ~1e-15).
GEOMETRIC_TOL = 1e-9


def parameter_label(dataset: xr.Dataset, name: str) -> str:
    """Axis label of a swept parameter: known label, its symbol, or long_name and units."""
    if name in PARAMETER_LABELS:
        return PARAMETER_LABELS[name]
    symbol = parameter_symbol(name)
    if symbol != name:
        return symbol
    attrs = dataset[name].attrs if name in dataset.coords else {}
    label = str(attrs.get("long_name", name))
    units = str(attrs.get("units", ""))
    return f"{label} ({units})" if units not in ("", "1") else label


def is_geometric(values: np.ndarray) -> bool:
    """Whether three or more positive increasing values have a constant ratio (a log range)."""
    values = np.asarray(values, dtype=float)
    if values.size < 3 or not np.all(values > 0) or not np.all(np.diff(values) > 0):
        return False
    ratios = values[1:] / values[:-1]
    return bool(np.ptp(ratios) <= GEOMETRIC_TOL * ratios.mean()) and ratios.mean() > 1 + 1e-6


def cell_edges(centres: np.ndarray, log: bool = False) -> np.ndarray:
    """(n + 1,) cell edges around n increasing centres: midpoints, ends mirrored.

    With ``log``, midpoints and mirroring in log (geometric means), for a log axis.
    """
    centres = np.asarray(centres, dtype=float)
    if log:
        return np.exp(cell_edges(np.log(centres)))
    if centres.size == 1:
        return np.array([centres[0] - 0.5, centres[0] + 0.5])
    middle = 0.5 * (centres[1:] + centres[:-1])
    return np.concatenate([[2 * centres[0] - middle[0]], middle, [2 * centres[-1] - middle[-1]]])


def outline(mask: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray) -> list[np.ndarray]:
    """Segments ``(2, 2)`` of the boundary of the union of cells where mask (ny, nx) is True."""
    padded = np.pad(mask, 1)
    segments = []
    # Vertical edges: between cells (j, i-1) and (j, i).
    for j, i in zip(*np.nonzero(padded[1:-1, 1:] != padded[1:-1, :-1])):
        segments.append(np.array([[x_edges[i], y_edges[j]], [x_edges[i], y_edges[j + 1]]]))
    # Horizontal edges: between cells (j-1, i) and (j, i).
    for j, i in zip(*np.nonzero(padded[1:, 1:-1] != padded[:-1, 1:-1])):
        segments.append(np.array([[x_edges[i], y_edges[j]], [x_edges[i + 1], y_edges[j]]]))
    return segments


def cell_runs(mask: np.ndarray, x_edges: np.ndarray, y_edges: np.ndarray) -> np.ndarray:
    """``(m, 4)`` rectangles ``(x0, y0, x1, y1)``: the runs along x of cells where mask (ny, nx) is True."""
    padded = np.pad(np.asarray(mask, dtype=bool), ((0, 0), (1, 1)))
    rows, starts = np.nonzero(padded[:, 1:-1] & ~padded[:, :-2])
    _, ends = np.nonzero(padded[:, 1:-1] & ~padded[:, 2:])  # same rows, in the same order
    return np.column_stack([x_edges[starts], y_edges[rows], x_edges[ends + 1], y_edges[rows + 1]])


def hatch_cells(
    axes: Axes,
    mask: np.ndarray,
    x_edges: np.ndarray,
    y_edges: np.ndarray,
    hatch: str,
    colour: str,
    gid: str,
) -> PathCollection | None:
    """Hatch the cells where mask (ny, nx) is True: one compound path of the runs along x.

    One path, so the hatch is filled once (a collection of one patch per run
    fills it per patch: a second per panel for a few hundred runs).  Its
    closed sub-paths (``path.to_polygons()``) are the runs.
    """
    runs = cell_runs(mask, x_edges, y_edges)
    if runs.size == 0:
        return None
    x0, y0, x1, y1 = runs.T
    corners = np.stack([np.column_stack(c) for c in ((x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0))], axis=1)
    codes = np.tile([Path.MOVETO, Path.LINETO, Path.LINETO, Path.LINETO, Path.CLOSEPOLY], len(runs))
    collection = PathCollection([Path(corners.reshape(-1, 2), codes)], facecolors="none", edgecolors=colour,
                                hatch=hatch, linewidths=0.0, zorder=3)
    collection.set_gid(gid)
    axes.add_collection(collection, autolim=False)
    return collection
