"""Stability indicators along the paths of a few cases: det K, Hill's eigenvalue, d2W.

The normalised second-order work along the path, d2W = dF . dDelta /
(|dF| |dDelta|) (the cosine of the angle between the force and displacement
increments), jumps where the path's direction in force space turns back: at
a limit point (dF reverses under displacement control) and where one loading
stage hands over to the next.  Its line is broken there, and no event marker
is drawn on a jump (the value there is not defined).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ncstab.plotting.cases import Case, CaseEvent
from ncstab.plotting.curves import curves_context, figure_title, mark_events, set_limits
from ncstab.plotting.style import AXIS_LABELS, FIGURE_SIZE, RC_PARAMS

__all__ = ["D2W_EXPLANATION", "DYNAMIC_RANGE", "d2w_line", "stability_curves_figure", "symlog_if_spread"]

#: What the third panel shows, written on it.
D2W_EXPLANATION = (
    r"$d^2W = dF\cdot d\Delta\,/\,(|dF|\,|d\Delta|)$ along the path, in $[-1, 1]$;"
    "\nbroken where it jumps (a limit point: dF turns back; a new stage)"
)


#: Size of the stability figure, inches: three stacked panels and a legend below.
STABILITY_FIGURE_SIZE = (FIGURE_SIZE[0], 6.6)
#: Legend lines the figure of STABILITY_FIGURE_SIZE holds below its panels; inches per line more.
LEGEND_LINES, LEGEND_LINE_HEIGHT = 8, 0.2
#: Y labels of the panels, on two lines (a long rotated label outgrows a short panel).
PANEL_LABELS = {"det_K": AXIS_LABELS["det_K"], "hill": AXIS_LABELS["hill"], "d2W": "$d^2W$\n(normalised)"}
#: The det K panel is drawn on a symlog scale when the typical |det K| of its cases spans
#: more than this factor (on a linear scale the largest curve flattens the others).
DYNAMIC_RANGE = 30.0


def _figure_size(context) -> tuple[float, float]:
    """:data:`STABILITY_FIGURE_SIZE`, taller by a line's height per legend line past
    :data:`LEGEND_LINES` (the legend below must not squeeze the three panels)."""
    if context.styles.factors is not None:
        lines = len(context.styles.factors)
    else:
        lines = sum(label.count("\n") + 1 for label in context.labels)
    width, height = STABILITY_FIGURE_SIZE
    return width, height + LEGEND_LINE_HEIGHT * max(0, lines - LEGEND_LINES)


def symlog_if_spread(axes: Axes, values: list[np.ndarray]) -> float | None:
    """Put the axes' y on a symlog scale when the curves' magnitudes spread over decades.

    The magnitude of a curve is the median of its finite, non-zero ``|values|``.
    When the largest is more than :data:`DYNAMIC_RANGE` times the smallest, y
    becomes ``symlog``: linear within ``linthresh`` of zero (so a sign change,
    det K = 0 at a limit point, stays a crossing of the zero line) and
    logarithmic beyond, with ``linthresh`` the power of ten at or below the
    smallest magnitude.  The y label says so.

    Returns
    -------
    float or None
        ``linthresh``, or None where y stays linear.
    """
    magnitudes = []
    for array in values:
        finite = np.abs(np.asarray(array, dtype=float))
        finite = finite[np.isfinite(finite) & (finite > 0)]
        if finite.size:
            magnitudes.append(float(np.median(finite)))
    if len(magnitudes) < 2 or max(magnitudes) <= DYNAMIC_RANGE * min(magnitudes):
        return None
    linthresh = 10.0 ** np.floor(np.log10(min(magnitudes)))
    axes.set_yscale("symlog", linthresh=linthresh)
    axes.set_ylabel(f"{axes.get_ylabel()}\n(symlog, linear\nbelow {linthresh:g})")
    return linthresh


def _det_at_event(case: Case, event: CaseEvent) -> float:
    return float(np.linalg.det(event.K)) if np.isfinite(event.K).all() else np.nan


def _hill_at_event(case: Case, event: CaseEvent) -> float:
    if not np.isfinite(event.K).all():
        return np.nan
    return float(np.linalg.eigvalsh((event.K + event.K.T) / 2)[0])


def _jumps(case: Case) -> np.ndarray:
    """Indices k such that d2W jumps between stored states k - 1 and k: the stage changes,
    or a located limit point lies between them with d2W changing sign."""
    if case.n_steps < 2:
        return np.empty(0, dtype=int)
    stage_change = np.flatnonzero(np.diff(case.stage) != 0) + 1
    limit = case.events.get("limit_point")
    across = np.empty(0, dtype=int)
    if limit is not None and np.isfinite(limit.s):
        k = np.flatnonzero((case.s[:-1] <= limit.s) & (limit.s <= case.s[1:])) + 1
        across = k[case.d2W[k - 1] * case.d2W[k] < 0]
    return np.union1d(stage_change, across).astype(int)


def d2w_line(case: Case) -> tuple[np.ndarray, np.ndarray]:
    """(Delta1*, d2W) of a case with NaN inserted at each jump (the line breaks there)."""
    jumps = _jumps(case)
    return np.insert(case.u[:, 0], jumps, np.nan), np.insert(case.d2W, jumps, np.nan)


def _second_order_work_at_event(case: Case, event: CaseEvent) -> float:
    """d2W at the event, interpolated in arclength between the stored states around it;
    NaN where it jumps there (no marker on a jump) or the event is outside the path."""
    keep = np.isfinite(case.s) & np.isfinite(case.d2W)
    s, values = case.s[keep], case.d2W[keep]
    if s.size < 2 or not np.isfinite(event.s) or not s[0] <= event.s <= s[-1]:
        return np.nan
    k = int(np.clip(np.searchsorted(s, event.s), 1, s.size - 1))
    if values[k - 1] * values[k] < 0:
        return np.nan
    return float(np.interp(event.s, s, values))


#: Panels of the stability figure: variable, its value at a located event.
STABILITY_PANELS: tuple[tuple[str, Callable[[Case, CaseEvent], float]], ...] = (
    ("det_K", _det_at_event),
    ("hill", _hill_at_event),
    ("d2W", _second_order_work_at_event),
)


def _spread(values: np.ndarray) -> float:
    finite = values[np.isfinite(values)]
    return float(np.ptp(finite)) if finite.size else 0.0


def _along_load(dataset: xr.Dataset, cases) -> bool:
    """Whether the indicators are drawn against the load parameter: a system that has one
    (Ziegler's pendulum, a column) whose paths move it while the first dof stays put (a
    trivial path: Ziegler's straight pendulum up to its flutter load), where an axis of
    displacements would be a single point."""
    if "load" not in dataset or not cases:
        return False
    return (any(_spread(case.load) > 0 for case in cases)
            and all(_spread(case.u[:, 0]) <= 1e-12 * max(1.0, _spread(case.load)) for case in cases))


def _x_axis(dataset: xr.Dataset, along_load: bool) -> tuple[str, str]:
    """The x axis as (its name in the title, its label): the seed's Delta1* for a granular
    system's D1, else the load or the first dof labelled as the model path figures label them
    (:meth:`~ncstab.plotting.model_paths.PathAxes.label`: ``load P (k/l)``, ``w1 (dimensionless)``)."""
    from ncstab.plotting.model_paths import PathAxes

    first = str(dataset["dof"].values[0]) if "dof" in dataset.coords else "D1"
    if not along_load and first == "D1":
        return r"$\Delta_1^*$", AXIS_LABELS["D1"]
    x = ("load", None) if along_load else ("u", first)
    name = str(dataset.attrs.get("load_parameter", "P")) if along_load else first
    return name, PathAxes(x, x).label(dataset, "x")


def stability_curves_figure(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Three stacked panels against Delta1*: det K, the smallest eigenvalue of K_sym, d2W.

    Each with its zero line and the located events; in the pure-shear limit
    (rigid normal) K is not defined and the panels say so.
    """
    with rc_context(RC_PARAMS):
        context = curves_context(dataset)
        fig = figure if figure is not None else Figure(figsize=_figure_size(context), layout="constrained")
        panels = fig.subplots(len(STABILITY_PANELS), 1, sharex=True)
        legend = context.legend()
        listed: set[int] = set()
        along_load = _along_load(dataset, context.cases)
        for axes, (name, at_event) in zip(panels, STABILITY_PANELS):
            drawn = False
            for k, case in enumerate(context.cases):
                values = getattr(case, name)
                if not np.isfinite(values).any():
                    continue
                if along_load:
                    x, y = case.load, (d2w_line(case)[1] if name == "d2W" else values)
                else:
                    x, y = d2w_line(case) if name == "d2W" else (case.u[:, 0], values)
                (line,) = axes.plot(x, y, label=case.label, gid=f"path:{case.label}",
                                    **context.path_style(k, overlaid=False))
                if k not in listed:
                    legend.curve(line, context.labels[k])
                    listed.add(k)
                mark_events(axes, context, legend, k, lambda e, case=case, at_event=at_event:
                            (e.load if along_load else e.u[0], at_event(case, e)))
                drawn = True
            axes.set_ylabel(PANEL_LABELS[name])
            if name == "det_K" and drawn:
                symlog_if_spread(axes, [case.det_K for case in context.cases])
            if drawn:
                axes.axhline(0.0, color="k", linewidth=0.8, zorder=1)
                if name == "d2W":
                    axes.set_ylim(-1.1, 1.1)
                    axes.set_title(D2W_EXPLANATION, fontsize=7.5, loc="left", color="0.25")
            else:
                note = ("not defined in the pure-shear limit" if context.rigid
                        else "not available (no finite values)")
                axes.text(0.5, 0.5, note, transform=axes.transAxes, ha="center", va="center",
                          color="0.3", gid="note")
                axes.set_yticks([])
                axes.grid(False, axis="y")
        if not listed:
            set_limits(panels[-1], [case.load if along_load else case.u[:, 0] for case in context.cases], [])
        symbol, label = _x_axis(dataset, along_load)
        panels[-1].set_xlabel(label)
        title = figure_title(dataset, "stability", width=80).replace(r"$\Delta_1^*$", symbol)
        fig.align_ylabels(panels)
        fig.suptitle(title, fontsize=10)
        legend.draw(fig, panels[0], place="below")  # the right side would collide with the title
    return fig
