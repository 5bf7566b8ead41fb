"""Path figures of any system: axes chosen from what the stages drive and hold.

The seed's diamond has its own figures (F1* against Delta1* and alpha, with
the seed's closed forms).  For every other system the axes come from the
Dataset alone: its ``stage_drives`` attribute names what the last stage
drives.

* A load-parameter stage (``drive = { P = ... }``): the load on y, on x the dof
  that moves most over the sweep.
* Driven displacements (or forces): the first driven dof's displacement on x,
  its conjugate force on y.
* A cycle: the plane of its two dofs.

Where a study follows the branches of a bifurcation (a ``branch`` dimension)
each branch is a curve.  The stability of each state is drawn as the line
style: for a conservative system (hyperelastic laws, no follower load) a
state is stable while the smallest eigenvalue of K is positive (solid),
unstable otherwise (dashed).  A non-conservative system has no such
criterion from K alone, so its curves are solid and the loss of Hill's
condition (and flutter, divergence) is marked where it was located.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.legend import event_style
from ncstab.plotting.case_styles import case_styles
from ncstab.plotting.style import EVENT_MARKERS, FIGURE_SIZE, RC_PARAMS, format_parameter, law_display_name
from ncstab.plotting.sweep_shape import MAX_CURVES, sweep_shape

__all__ = ["PathAxes", "is_seed_diamond", "model_path_figure", "path_axes"]

#: Events marked on the curves, in drawing order.
MARKED_EVENTS = ("bifurcation", "limit_point", "hill_loss", "flutter_onset", "divergence", "turning_point")


def is_seed_diamond(dataset: xr.Dataset) -> bool:
    """Whether the Dataset is of the seed's reduced diamond (which has its own figures)."""
    settings = str(dataset.attrs.get("system_settings", "reduction=symmetric"))
    return str(dataset.attrs.get("system", "diamond")) == "diamond" and "axes" not in settings


@dataclass(frozen=True)
class PathAxes:
    """What goes on the axes of a path figure: a variable and an index for each.

    ``x`` and ``y`` are ``(variable, dof name or None)``: ``("u", "D_top")``,
    ``("load", None)``.
    """

    x: tuple[str, str | None]
    y: tuple[str, str | None]

    def label(self, dataset: xr.Dataset, axis: str) -> str:
        name, dof = self.x if axis == "x" else self.y
        if name == "load":
            return f"load {dataset.attrs.get('load_parameter', 'P')} ({_units(dataset)})"
        if name == "F":
            forces = dict(zip(dataset["dof"].values.tolist(), dataset["force"].values.tolist()))
            return f"{forces[dof]} ({dataset.attrs.get('force_unit', '1')})"
        if name == "u":
            units = str(dataset["u"].attrs.get("units", "1"))
            return f"{dof} ({units})" if units != "1" else f"{dof} (dimensionless)"
        return f"{name} (rad)"

    def values(self, dataset: xr.Dataset, axis: str) -> xr.DataArray:
        name, dof = self.x if axis == "x" else self.y
        array = dataset[name]
        return array.sel(dof=dof) if dof is not None else array


def _units(dataset: xr.Dataset) -> str:
    return str(dataset.attrs.get("force_unit", "1")) + ("/l" if dataset.attrs.get("system") == "ziegler" else "")


def path_axes(dataset: xr.Dataset) -> PathAxes:
    """The axes of the path figures of a Dataset, from its last stage's drives."""
    stages = [s.strip() for s in str(dataset.attrs.get("stage_drives", "")).split(";") if s.strip()]
    drives = stages[-1] if stages else ""
    dofs = [str(d) for d in dataset["dof"].values]
    forces = [str(f) for f in dataset["force"].values] if "force" in dataset.coords else dofs
    load = str(dataset.attrs.get("load_parameter", ""))
    if drives.startswith("cycle:"):
        first, second = drives[len("cycle:"):].split(",")
        return PathAxes(("u", first), ("u", second))
    names = [d for d in drives.split(",") if d]
    if load and load in names or not names:
        u = dataset["u"]
        spread = (u.max(dim=[d for d in u.dims if d != "dof"]) - u.min(dim=[d for d in u.dims if d != "dof"])).values
        moving = dofs[int(np.nanargmax(np.nan_to_num(spread, nan=-1.0)))]
        return PathAxes(("u", moving), ("load" if "load" in dataset else "F", None if "load" in dataset else moving))
    first = names[0]
    dof = first if first in dofs else dofs[forces.index(first)]
    return PathAxes(("u", dof), ("F", dof))


def _conservative(dataset: xr.Dataset) -> bool:
    classes = {str(c) for c in np.atleast_1d(dataset["law_class"].values)} if "law_class" in dataset.coords else set()
    return classes <= {"hyperelastic"} and dataset.attrs.get("load_kind", "dead") != "follower"


def _case_label(dataset: xr.Dataset, index: dict) -> str:
    parts = []
    for name, value in index.items():
        if name == "law":
            parts.append(law_display_name(str(dataset["law"].values[value])))
        elif name == "branch":
            branch = float(dataset["branch"].values[value])
            parts.append("path followed" if branch == 0 else f"bifurcated branch ({'+' if branch > 0 else '−'})")
        else:
            parts.append(format_parameter(name, float(dataset[name].values[value])))
    return ", ".join(parts)


def model_path_figure(dataset: xr.Dataset, figure: Figure | None = None, kind: str = "load_displacement") -> Figure:
    """The load (or force) against the displacement that the stages make move, per case.

    ``kind = "load_rotation"`` puts the first interaction angle on x instead
    (the first contact's alpha, or the first spring's theta).
    """
    shape = sweep_shape(dataset)
    axes_of = path_axes(dataset)
    if kind == "load_rotation":
        angle = "alpha" if "alpha" in dataset else "theta"
        if angle in dataset:
            axes_of = PathAxes((angle, None), axes_of.y)
    conservative = _conservative(dataset)
    with rc_context(RC_PARAMS):
        figure = figure if figure is not None else Figure(figsize=FIGURE_SIZE, layout="constrained")
        axes = figure.add_subplot()
        cases = list(np.ndindex(*[shape.sizes[d] for d in shape.dims]))[: max(MAX_CURVES, 1)]
        indices = [dict(zip(shape.dims, position)) for position in cases]
        laws = [str(dataset["law"].values[index["law"]]) if "law" in index else "" for index in indices]
        styles = case_styles(laws, [_case_label(dataset, {d: v for d, v in index.items() if d != "law"})
                                    for index in indices], law_linestyles=not conservative)
        colours = styles.colours
        x_all, y_all = axes_of.values(dataset, "x"), axes_of.values(dataset, "y")
        for k, index in enumerate(indices):
            n = int(dataset["n_steps"].isel(index))
            first = _branch_start(dataset, index, n)
            x, y = _member(x_all.isel(index).values[:n]), _member(y_all.isel(index).values[:n])
            stable = dataset["hill"].isel(index).values[:n] > 0 if conservative else np.ones(n, dtype=bool)
            label = _case_label(dataset, index)
            style = styles.line(k, n - first, len(indices))
            for piece, solid in _pieces(stable[first:]):
                piece = piece + first
                linestyle = style["linestyle"] if solid else (0, (4, 2.5))
                axes.plot(x[piece], y[piece], **{**style, "linestyle": linestyle},
                          gid=f"path:{label}", label=label if piece[0] == first else None)
            for event in MARKED_EVENTS:
                point = _event_point(dataset, axes_of, event, index)
                if point is not None:
                    axes.plot(*point, linestyle="none", gid=f"event:{event}:{label}", **event_style(event, colours[k]))
        axes.set_xlabel(axes_of.label(dataset, "x"))
        axes.set_ylabel(axes_of.label(dataset, "y"))
        axes.set_title(str(dataset.attrs.get("study_description") or dataset.attrs.get("system", "")), wrap=True)
        handles, labels = axes.get_legend_handles_labels()
        if styles.factors is not None:  # a law x value grid: each law and each value once
            handles, labels = [h for h, _ in styles.factors], [t for _, t in styles.factors]
        for event in MARKED_EVENTS:
            if any(str(line.get_gid()).startswith(f"event:{event}:") for line in axes.lines):
                handles.append(Line2D([], [], linestyle="none", **event_style(event, "0.5")))
                labels.append(EVENT_MARKERS[event][3])
        if conservative:
            handles.append(Line2D([], [], color="0.3", linestyle=(0, (4, 2.5))))
            labels.append("unstable (smallest eigenvalue of K < 0)")
        axes.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), borderaxespad=0.0)
    return figure


def _branch_start(dataset: xr.Dataset, index: dict, n: int) -> int:
    """First state drawn of a case: on a bifurcated branch (``branch`` != 0) the last state
    of the path shared with the straight one (arclength up to the bifurcation's), so that
    the branch starts where it leaves the path and the shared part keeps the path's colour."""
    if "branch" not in index or float(dataset["branch"].values[index["branch"]]) == 0:
        return 0
    if "bifurcation_s" not in dataset:
        return 0
    at = float(dataset["bifurcation_s"].isel(index))
    s = dataset["s"].isel(index).values[:n]
    if not np.isfinite(at) or s.size == 0:
        return 0
    return int(max(np.searchsorted(s, at, side="right") - 1, 0))


def _member(values: np.ndarray) -> np.ndarray:
    """A per-member variable (alpha of every contact): its first member."""
    return values[:, 0] if values.ndim > 1 else values


def _pieces(stable: np.ndarray) -> list[tuple[np.ndarray, bool]]:
    """Runs of equal stability, each extended by one state so that the line is unbroken."""
    n = stable.size
    if n == 0:
        return []
    breaks = np.flatnonzero(stable[1:] != stable[:-1]) + 1
    starts = np.concatenate([[0], breaks])
    ends = np.concatenate([breaks, [n]])
    return [(np.arange(a, min(b + 1, n)), bool(stable[a])) for a, b in zip(starts, ends)]


def _event_point(dataset: xr.Dataset, axes_of: PathAxes, event: str, index: dict) -> tuple[float, float] | None:
    """The event's (x, y) on the figure's axes, or None if it was not located."""
    if f"{event}_s" not in dataset or not np.isfinite(float(dataset[f"{event}_s"].isel(index))):
        return None
    point = []
    for axis in ("x", "y"):
        name, dof = axes_of.x if axis == "x" else axes_of.y
        field = f"{event}_{name}"
        if field not in dataset:
            return None
        value = dataset[field].isel(index)
        value = value.sel(dof=dof) if dof is not None else value
        point.append(float(np.ravel(value.values)[0]))  # a per-member variable: its first member
    return point[0], point[1]
