"""Figures of stability boundaries traced as curves (:func:`ncstab.boundaries.boundary`).

* :func:`boundary_figure` (figure kind ``boundary``): the curve of each case,
  the load at the event (the load parameter, else the force that varies most)
  against the boundary parameter; a family over the other sweep dimension
  (Ziegler's destabilization paradox: the flutter load against b1 for several
  b2).  Folds of a curve are marked.
* :func:`boundary_over_diagram_figure`: the curve drawn over the pixel diagram
  of an archive that swept the same parameter (the event's located load per
  cell, drawn as the cells it is known to), both from Datasets only.
"""

from __future__ import annotations

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from ncstab.plotting.style import FIGURE_SIZE, format_parameter, parameter_symbol

__all__ = ["boundary_curves", "boundary_figure", "boundary_over_diagram_figure"]


def _quantity(dataset: xr.Dataset) -> tuple[str, str | None]:
    """The variable on the vertical axis and its dof (``None`` for the load parameter)."""
    if "boundary_load" in dataset:
        return "boundary_load", None
    F = dataset["boundary_F"]
    spread = (F.max([d for d in F.dims if d != "dof"]) - F.min([d for d in F.dims if d != "dof"])).values
    return "boundary_F", str(dataset["dof"].values[int(np.nanargmax(np.nan_to_num(spread, nan=-1.0)))])


def boundary_curves(dataset: xr.Dataset) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
    """Per case: its label, the parameter, the load at the event and the fold indices along the curve."""
    parameter = dataset.attrs["boundary_parameter"]
    name, dof = _quantity(dataset)
    x_all = dataset[f"boundary_{parameter}"]
    y_all = dataset[name] if dof is None else dataset[name].sel(dof=dof)
    case_dims = [d for d in x_all.dims if d != "point"]
    curves = []
    for index in np.ndindex(*[dataset.sizes[d] for d in case_dims]):
        where = dict(zip(case_dims, index))
        count = int(dataset["n_points"].isel(where).values)
        x = x_all.isel(where).values[:count]
        y = y_all.isel(where).values[:count]
        notes = dataset["boundary_note"].isel(where).values[:count]
        label = ", ".join(
            format_parameter(d, dataset[d].values[i]) for d, i in where.items() if d != "law" and dataset.sizes[d] > 1
        ) or str(dataset["law"].values[where.get("law", 0)])
        folds = np.array([i for i, note in enumerate(notes) if str(note) == "fold"], dtype=int)
        curves.append((label, x, y, folds))
    return curves


def _axis_labels(axes, dataset: xr.Dataset) -> None:
    parameter = dataset.attrs["boundary_parameter"]
    _name, dof = _quantity(dataset)
    axes.set_xlabel(parameter_symbol(parameter))
    if dof is None:
        axes.set_ylabel(f"{dataset.attrs.get('load_parameter', 'load')} at {dataset.attrs['boundary_event']} [{dataset['boundary_load'].attrs.get('units', '1')}]")
    else:
        force = str(dataset["force"].sel(dof=dof).values) if "force" in dataset.coords else dof
        axes.set_ylabel(f"{force} at {dataset.attrs['boundary_event']}")


def boundary_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """The boundary curve of each case (kind ``boundary``), folds marked with circles."""
    figure = figure or Figure(figsize=FIGURE_SIZE)
    axes = figure.add_subplot()
    for label, x, y, folds in boundary_curves(dataset):
        (line,) = axes.plot(x, y, label=label)
        if folds.size:
            axes.plot(x[folds], y[folds], "o", mfc="none", color=line.get_color())
    _axis_labels(axes, dataset)
    axes.set_title(f"{dataset.attrs['boundary_event']} boundary along {dataset.attrs['boundary_parameter']} (continuation)")
    if len(axes.lines) > 1:
        axes.legend(fontsize="small")
    return figure


def boundary_over_diagram_figure(boundary: xr.Dataset, diagram: xr.Dataset, figure: Figure | None = None) -> Figure:
    """The boundary curves over the pixel diagram of ``diagram``, an archive sweeping the same parameter.

    For each curve, the diagram's cells at the nearest values of the curve's
    other parameters give the event's located load per cell (``<event>_load``,
    else ``<event>_F`` of the same force), drawn as steps one cell wide: the
    resolution of a sweep; the curve is drawn over them.
    """
    parameter, event = boundary.attrs["boundary_parameter"], boundary.attrs["boundary_event"]
    if parameter not in diagram.dims:
        raise ValueError(f"the diagram does not sweep {parameter!r}: nothing to draw the boundary over")
    _name, dof = _quantity(boundary)
    field = diagram[f"{event}_load"] if dof is None else diagram[f"{event}_F"].sel(dof=dof)
    figure = figure or Figure(figsize=FIGURE_SIZE)
    axes = figure.add_subplot()
    case_dims = [d for d in boundary["boundary_" + parameter].dims if d not in ("point", "law")]
    curves = boundary_curves(boundary)
    for (label, x, y, folds), index in zip(curves, np.ndindex(*[boundary.sizes[d] for d in ["law"] + case_dims])):
        select = {d: boundary[d].values[i] for d, i in zip(case_dims, index[1:]) if d in diagram.dims}
        cells = field.sel(select, method="nearest") if select else field
        if "law" in cells.dims:
            cells = cells.isel(law=0)
        cells = cells.squeeze(drop=True)
        values = diagram[parameter].values
        (line,) = axes.plot(x, y, label=f"curve {label}", zorder=3)
        axes.step(values, cells.values, where="mid", color=line.get_color(), alpha=0.45, lw=3,
                  label=f"{len(values)}-cell sweep {label}", zorder=2)
    _axis_labels(axes, boundary)
    axes.set_title(f"{event}: boundary curve over the pixel diagram")
    axes.legend(fontsize="small")
    return figure
