"""The figure kinds, each a function ``(dataset, figure=None) -> Figure``.

Every kind draws one curve per case of the Dataset (law x swept parameters),
marks the located events, and overlays the seed's closed form where one
exists (:mod:`ncstab.plotting.closed_form_overlays`).  Figures are plain
:class:`matplotlib.figure.Figure` objects, not pyplot figures: nothing is
registered globally, nothing needs closing, no window ever opens.

Artists carry a ``gid`` saying what they are, for tests and for later
editing: ``"path:<case label>"``, ``"closed_form:<branch>:<case label>"``
(branch ``-``, ``+``, ``first`` or ``blocking``) and
``"event:<event>:<case label>"``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D
from matplotlib.ticker import MaxNLocator

from ncstab.plotting.cycles import cycle_force_drift_figure, cycle_paths_figure, cycle_work_figure
from ncstab.plotting.maps import second_order_work_map_figure, second_order_work_polar_figure, state_map_figure
from ncstab.plotting.diagrams import stability_diagram_figure
from ncstab.plotting.cases import Case, CaseEvent, path_cases
from ncstab.plotting.closed_form_overlays import ClosedFormOverlay, closed_form_overlay
from ncstab.plotting.style import (
    AXIS_LABELS,
    EVENT_MARKERS,
    FAILED_COLOUR,
    FIGURE_SIZE,
    RC_PARAMS,
    case_colours,
    fixed_parameters_text,
    force_label,
    format_parameter,
    law_display_name,
)

__all__ = [
    "FIGURE_KINDS",
    "KIND_TITLES",
    "plot_load_displacement",
    "plot_load_displacement_rotation",
    "plot_load_rotation",
    "plot_stability",
]

#: Default titles (used when the Dataset has no study description).
KIND_TITLES = {
    "load_rotation": "Load–rotation response",
    "load_displacement": "Load–displacement response",
    "load_displacement_rotation": "Load–displacement–rotation response",
    "stability": "Stability indicators along the path",
}

#: Line styles: computed paths, closed forms of the seed.
PATH_STYLE = {"linewidth": 1.8, "solid_capstyle": "round", "zorder": 2}
PATH_WITH_CLOSED_FORM_STYLE = {
    "linewidth": 3.2,
    "alpha": 0.45,
    "solid_capstyle": "round",
    "zorder": 2,
}
CLOSED_FORM_STYLE = {"linestyle": (0, (4, 2.5)), "linewidth": 1.1, "zorder": 3}
FAILED_STYLE = {"color": FAILED_COLOUR, "linestyle": (0, (2, 2)), "linewidth": 1.2, "zorder": 1}

#: Legend entries from which the legend goes outside the axes.
LEGEND_INSIDE_MAX = 5
#: Cases beyond which the legend lists only the first and the last.
LEGEND_MAX_CURVES = 16


# --- what a figure knows about its Dataset --------------------------------------------------


@dataclass
class _Context:
    """Cases, their colours and labels, overlays and attributes of one Dataset."""

    dataset: xr.Dataset
    cases: list[Case]
    colours: list[object]
    labels: list[str]
    legend_title: str | None
    overlays: list[ClosedFormOverlay | None]
    normal: str
    description: str

    @property
    def rigid(self) -> bool:
        return self.normal == "rigid"


def _context(dataset: xr.Dataset) -> _Context:
    cases = path_cases(dataset)
    normal = str(dataset.attrs.get("normal", "deformable"))
    secondary_contacts = str(dataset.attrs.get("secondary_contacts", "activate"))
    laws = [case.law for case in cases]
    labels, title = _compact_labels(cases)
    description = str(
        dataset.attrs.get("study_description") or dataset.attrs.get("description") or ""
    )
    return _Context(
        dataset=dataset,
        cases=cases,
        colours=case_colours(laws, len(cases)),
        labels=labels,
        legend_title=title,
        overlays=[closed_form_overlay(case, normal, secondary_contacts) for case in cases],
        normal=normal,
        description=description,
    )


def _compact_labels(cases: list[Case]) -> tuple[list[str], str | None]:
    """Legend texts saying only what varies between cases; what they share goes in the title."""
    if len(cases) <= 1:
        return [case.label for case in cases], None
    laws = {case.law for case in cases}
    names = list(cases[0].swept)
    varying = [n for n in names if len({repr(case.swept.get(n)) for case in cases}) > 1]
    common = []
    if len(laws) == 1:
        common.append(law_display_name(cases[0].law))
    common += [format_parameter(n, cases[0].swept[n]) for n in names if n not in varying]
    labels = []
    for case in cases:
        parts = [law_display_name(case.law)] if len(laws) > 1 else []
        parts += [format_parameter(n, case.swept[n]) for n in varying]
        labels.append((", ".join(parts) or law_display_name(case.law)) + case.failure_note)
    return labels, (", ".join(common) or None)


def _title(context: _Context, kind: str) -> str:
    if context.description:
        return textwrap.fill(context.description, 64)  # fits 6.4 in at 10 pt
    title = KIND_TITLES[kind]
    details = fixed_parameters_text(context.dataset.attrs)
    if context.rigid:
        details = ", ".join(filter(None, [details, "pure-shear limit"]))
    return f"{title}\n{details}" if details else title


# --- legend ---------------------------------------------------------------------------------


@dataclass
class _Legend:
    """Curves, then one entry for the closed forms and one per event kind present."""

    title: str | None = None
    curves: list[tuple[object, str]] = field(default_factory=list)
    equations: set[int] = field(default_factory=set)
    events: dict[str, Line2D] = field(default_factory=dict)

    def curve(self, handle: object, label: str) -> None:
        self.curves.append((handle, label))

    def closed_form(self, equations: str) -> None:
        """Record the seed equations of an overlay (``"seed Eq. 46, 53"``)."""
        self.equations.update(int(n) for n in equations.removeprefix("seed Eq. ").split(", "))

    def event(self, name: str) -> None:
        if name not in self.events:
            self.events[name] = Line2D([], [], linestyle="none", **_event_style(name, "0.55"))

    @property
    def closed_form_label(self) -> str:
        return "closed form (seed Eq. " + ", ".join(str(n) for n in sorted(self.equations)) + ")"

    def entries(self) -> tuple[list[object], list[str]]:
        curves = self.curves
        if len(curves) > LEGEND_MAX_CURVES:
            # A large sweep: the first and last curves bracket the rest.
            gap = (Line2D([], [], linestyle="none"), f"⋯ ({len(curves) - 2} more cases)")
            curves = [curves[0], gap, curves[-1]]
        handles = [h for h, _ in curves]
        labels = [t for _, t in curves]
        if self.equations:
            style = {k: v for k, v in CLOSED_FORM_STYLE.items() if k != "zorder"}
            handles.append(Line2D([], [], color="0.2", **style))
            labels.append(self.closed_form_label)
        present = [name for name in EVENT_MARKERS if name in self.events]
        handles += [self.events[name] for name in present]
        labels += [EVENT_MARKERS[name][3] for name in present]
        return handles, labels

    def draw(self, figure: Figure, axes: Axes, place: str | None = None) -> None:
        """Place the legend: ``"inside"`` (best place in the axes), ``"right"`` or
        ``"below"`` the axes, or ``"corner"`` (upper left of the figure, for 3-D
        axes).  By default inside when short, else right of the axes for short
        texts and below, in columns, for long ones.
        """
        handles, labels = self.entries()
        if not handles:
            return
        longest = max(len(text) for text in labels)
        if place is None:
            place = (
                "inside"
                if len(handles) <= LEGEND_INSIDE_MAX
                else ("right" if longest <= 28 else "below")
            )
        if place == "inside":
            legend = axes.legend(handles, labels, loc="best", title=self.title)
        elif place == "right":
            legend = figure.legend(handles, labels, loc="outside right center", title=self.title)
        elif place == "corner":
            legend = figure.legend(
                handles, labels, loc="upper left", bbox_to_anchor=(0.01, 0.9), title=self.title
            )
        else:
            ncols = min(3 if longest <= 26 else (2 if longest <= 44 else 1), len(handles))
            legend = figure.legend(
                handles, labels, loc="outside lower center", ncols=ncols, title=self.title
            )
        if self.title:
            legend.get_title().set_fontsize(8)
        legend.set_gid("legend")


def _event_style(name: str, colour: object) -> dict[str, object]:
    marker, size, filled, _ = EVENT_MARKERS[name]
    if marker == "x":
        return {"marker": marker, "markersize": size, "color": "k", "markeredgewidth": 1.8}
    return {
        "marker": marker,
        "markersize": size,
        "markerfacecolor": colour if filled else "none",
        "markeredgecolor": "k",
        "markeredgewidth": 1.0 if filled else 1.3,
        "color": colour,
    }


# --- shared drawing helpers -----------------------------------------------------------------


def _path_style(context: _Context, k: int, overlaid: bool = True) -> dict[str, object]:
    """Computed path k: solid; a lighter, wider band under a closed form; dotted grey if failed."""
    case = context.cases[k]
    if case.failed:
        return dict(FAILED_STYLE)
    base = (
        PATH_WITH_CLOSED_FORM_STYLE if overlaid and context.overlays[k] is not None else PATH_STYLE
    )
    return {**base, "color": context.colours[k]}


def _set_limits(
    axes: Axes, xs: Iterable[np.ndarray], ys: Iterable[np.ndarray], margin: float = 0.04
) -> None:
    """Axis limits from the computed data (closed forms beyond them are clipped)."""
    for values, setter in ((xs, axes.set_xlim), (ys, axes.set_ylim)):
        finite = np.concatenate([np.ravel(v) for v in values] or [np.empty(0)])
        finite = finite[np.isfinite(finite)]
        if finite.size == 0:
            continue
        low, high = float(finite.min()), float(finite.max())
        span = high - low
        pad = margin * span if span > 0 else max(abs(high) * 0.1, 0.05)
        setter(low - pad, high + pad)


def _new_figure(figure: Figure | None) -> Figure:
    return figure if figure is not None else Figure(figsize=FIGURE_SIZE, layout="constrained")


def _mark_events(
    axes: Axes,
    context: _Context,
    legend: _Legend,
    k: int,
    where: Callable[[CaseEvent], tuple[float, ...]],
) -> list[tuple[float, ...]]:
    """Draw the events of case k at where(event); return the points drawn."""
    case, colour = (
        context.cases[k],
        (FAILED_COLOUR if context.cases[k].failed else context.colours[k]),
    )
    points = []
    for name in EVENT_MARKERS:
        event = case.events.get(name)
        if event is None:
            continue
        point = where(event)
        if not np.all(np.isfinite(point)):
            continue
        axes.plot(
            *[[c] for c in point],
            linestyle="none",
            zorder=5,
            gid=f"event:{name}:{case.label}",
            **_event_style(name, colour),
        )
        legend.event(name)
        points.append(point)
    return points


# --- load-rotation and load-displacement ----------------------------------------------------


def _planar(dataset: xr.Dataset, figure: Figure | None, kind: str) -> Figure:
    rotation = kind == "load_rotation"
    with rc_context(RC_PARAMS):
        context = _context(dataset)
        fig = _new_figure(figure)
        axes = fig.add_subplot()
        legend = _Legend(title=context.legend_title)
        xs, ys = [], []
        for k, case in enumerate(context.cases):
            x = case.alpha if rotation else case.u[:, 0]
            y = case.F[:, 0]
            (line,) = axes.plot(
                x, y, label=case.label, gid=f"path:{case.label}", **_path_style(context, k)
            )
            legend.curve(line, context.labels[k])
            xs.append(x)
            ys.append(y)
            overlay = context.overlays[k]
            if overlay is not None:
                _draw_overlay_2d(axes, overlay, case, context.colours[k], rotation)
                legend.closed_form(
                    overlay.rotation_equations if rotation else overlay.displacement_equations
                )
            points = _mark_events(
                axes, context, legend, k, lambda e: (e.alpha if rotation else e.u[0], e.F[0])
            )
            xs += [p[0] for p in points]
            ys += [p[1] for p in points]
        _set_limits(axes, xs, ys)
        axes.set_xlabel(AXIS_LABELS["alpha" if rotation else "D1"])
        axes.set_ylabel(force_label(context.normal))
        if rotation:
            top = axes.secondary_xaxis("top", functions=(np.degrees, np.radians))
            top.set_xlabel(AXIS_LABELS["alpha_deg"], fontsize=9)
        axes.axhline(0.0, color="0.5", linewidth=0.6, zorder=1)
        # A figure title: above an outside legend too (constrained layout).
        fig.suptitle(_title(context, kind), fontsize=10)
        if not context.cases:
            axes.text(
                0.5,
                0.5,
                "no cases in the Dataset",
                transform=axes.transAxes,
                ha="center",
                va="center",
            )
        legend.draw(fig, axes)
    return fig


def _draw_overlay_2d(
    axes: Axes, overlay: ClosedFormOverlay, case: Case, colour: object, rotation: bool
) -> None:
    for branch in overlay.branches:
        x = branch.alpha if rotation else branch.D1
        axes.plot(
            x,
            branch.F1,
            color=colour,
            gid=f"closed_form:{branch.name}:{case.label}",
            label="_closed form",
            **CLOSED_FORM_STYLE,
        )
    if overlay.blocking is not None:
        position = overlay.blocking.alpha if rotation else overlay.blocking.D1
        axes.axvline(
            position,
            color=colour,
            gid=f"closed_form:blocking:{case.label}",
            label="_blocking",
            **CLOSED_FORM_STYLE,
        )


def plot_load_rotation(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Load-rotation curves F1 against alpha (seed Figs. 3, 8, 9, 12, 14).

    Parameters
    ----------
    dataset
        A path Dataset (:meth:`ncstab.paths.PathResult.to_dataset`).
    figure
        A Figure to draw into (a new (6.4, 4.8) in Figure by default).

    Returns
    -------
    Figure
        One axes: a curve per case, its events, closed-form overlays (dashed),
        alpha in rad below and in degrees above.
    """
    return _planar(dataset, figure, "load_rotation")


def plot_load_displacement(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Load-displacement curves F1 against Delta1* (seed Figs. 4, 6, 7, 10, 13, 15).

    Parameters
    ----------
    dataset
        A path Dataset (:meth:`ncstab.paths.PathResult.to_dataset`).
    figure
        A Figure to draw into (a new one by default).

    Returns
    -------
    Figure
        One axes, as :func:`plot_load_rotation` with Delta1* on x.
    """
    return _planar(dataset, figure, "load_displacement")


# --- 3-D load-displacement-rotation ---------------------------------------------------------


def plot_load_displacement_rotation(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """3-D curves (Delta1*, alpha, F1) (seed Figs. 5 and 11).

    The 3-D view shows that the two branches of the closed form, which seem
    to cross in the load-displacement plane, do not meet (no bifurcation).

    Parameters
    ----------
    dataset
        A path Dataset (:meth:`ncstab.paths.PathResult.to_dataset`).
    figure
        A Figure to draw into (a new one by default).

    Returns
    -------
    Figure
        One 3-D axes.  Closed forms are cut (NaN) outside the box of the
        computed data, since 3-D axes do not clip.
    """
    with rc_context(RC_PARAMS):
        context = _context(dataset)
        if figure is None:
            # No layout engine: constrained layout leaves wide margins around 3-D axes.
            fig = Figure(figsize=FIGURE_SIZE)
            axes = fig.add_axes((0.08, 0.0, 0.92, 0.9), projection="3d")
        else:
            fig = figure
            axes = fig.add_subplot(projection="3d")
        legend = _Legend(title=context.legend_title)
        data = [np.column_stack([c.u[:, 0], c.alpha, c.F[:, 0]]) for c in context.cases]
        points = [p for p in data if p.size]
        stacked = np.concatenate(points) if points else np.empty((0, 3))
        finite = stacked[np.isfinite(stacked).all(axis=1)]
        low = finite.min(axis=0) if finite.size else np.zeros(3)
        high = finite.max(axis=0) if finite.size else np.ones(3)
        pad = 0.05 * np.maximum(high - low, 1e-6)
        box = (low - pad, high + pad)
        for k, case in enumerate(context.cases):
            (line,) = axes.plot(
                case.u[:, 0],
                case.alpha,
                case.F[:, 0],
                label=case.label,
                gid=f"path:{case.label}",
                **_path_style(context, k),
            )
            legend.curve(line, context.labels[k])
            overlay = context.overlays[k]
            if overlay is not None:
                _draw_overlay_3d(axes, overlay, case, context.colours[k], box)
                legend.closed_form(overlay.equations)
            _mark_events(axes, context, legend, k, lambda e: (e.u[0], e.alpha, e.F[0]))
        if finite.size:
            axes.set_xlim(box[0][0], box[1][0])
            axes.set_ylim(box[0][1], box[1][1])
            axes.set_zlim(box[0][2], box[1][2])
        axes.set_xlabel(AXIS_LABELS["D1"], labelpad=6)
        axes.set_ylabel(AXIS_LABELS["alpha"], labelpad=6)
        axes.set_zlabel(force_label(context.normal), labelpad=6)
        for axis in (axes.xaxis, axes.yaxis, axes.zaxis):
            axis.set_major_locator(MaxNLocator(5))
        axes.view_init(elev=22, azim=-56)
        axes.set_box_aspect(None, zoom=0.9)
        fig.suptitle(_title(context, "load_displacement_rotation"), fontsize=10)
        legend.draw(fig, axes, place="corner")
    return fig


def _draw_overlay_3d(
    axes: Axes,
    overlay: ClosedFormOverlay,
    case: Case,
    colour: object,
    box: tuple[np.ndarray, np.ndarray],
) -> None:
    low, high = box
    for branch in overlay.branches:
        xyz = np.column_stack([branch.D1, branch.alpha, branch.F1])
        outside = ((xyz < low) | (xyz > high)).any(axis=1)
        xyz[outside] = np.nan
        if np.isfinite(xyz).all(axis=1).sum() < 2:
            continue
        axes.plot(
            *xyz.T,
            color=colour,
            gid=f"closed_form:{branch.name}:{case.label}",
            label="_closed form",
            **CLOSED_FORM_STYLE,
        )
    if overlay.blocking is not None:
        F1 = case.F[:, 0]
        start = overlay.branches[0].F1[-1] if overlay.branches else np.nanmin(F1)
        top = max(float(np.nanmax(F1)), float(start))
        block = overlay.blocking
        axes.plot(
            [block.D1, block.D1],
            [block.alpha, block.alpha],
            [start, top],
            color=colour,
            gid=f"closed_form:blocking:{case.label}",
            label="_blocking",
            **CLOSED_FORM_STYLE,
        )


# --- stability indicators -------------------------------------------------------------------


def _det_at_event(case: Case, event: CaseEvent) -> float:
    return float(np.linalg.det(event.K)) if np.isfinite(event.K).all() else np.nan


def _hill_at_event(case: Case, event: CaseEvent) -> float:
    if not np.isfinite(event.K).all():
        return np.nan
    return float(np.linalg.eigvalsh((event.K + event.K.T) / 2)[0])


def _second_order_work_at_event(case: Case, event: CaseEvent) -> float:
    """d2W at the event, from the stored states around it (it needs the path direction).

    Interpolated in arclength; where d2W changes sign between the two stored
    states that bracket the event (it jumps at a limit point, where dF turns
    back), the event is where the second-order work vanishes: 0.
    """
    keep = np.isfinite(case.s) & np.isfinite(case.d2W)
    s, values = case.s[keep], case.d2W[keep]
    if s.size < 2 or not np.isfinite(event.s) or not s[0] <= event.s <= s[-1]:
        return np.nan
    k = int(np.clip(np.searchsorted(s, event.s), 1, s.size - 1))
    if values[k - 1] * values[k] < 0:
        return 0.0
    return float(np.interp(event.s, s, values))


#: Panels of the stability figure: variable, its value at a located event.
_STABILITY_PANELS: tuple[tuple[str, Callable[[Case, CaseEvent], float]], ...] = (
    ("det_K", _det_at_event),
    ("hill", _hill_at_event),
    ("d2W", _second_order_work_at_event),
)


def plot_stability(dataset: xr.Dataset, figure: Figure | None = None) -> Figure:
    """Stability indicators along the path against Delta1*.

    Three stacked panels: det K (a limit point under force control where it
    vanishes, seed Eq. 36), the smallest eigenvalue of K_sym (Hill's
    condition holds while positive) and the normalised second-order work
    along the path; each with its zero line and the located events.  In the
    pure-shear limit (rigid normal) K is not defined and the panels say so.

    Parameters
    ----------
    dataset
        A path Dataset (:meth:`ncstab.paths.PathResult.to_dataset`).
    figure
        A Figure to draw into (a new one by default).

    Returns
    -------
    Figure
        Three axes sharing x.
    """
    with rc_context(RC_PARAMS):
        context = _context(dataset)
        fig = _new_figure(figure)
        panels = fig.subplots(len(_STABILITY_PANELS), 1, sharex=True)
        legend = _Legend(title=context.legend_title)
        listed: set[int] = set()
        for axes, (name, at_event) in zip(panels, _STABILITY_PANELS):
            drawn = False
            for k, case in enumerate(context.cases):
                values = getattr(case, name)
                if not np.isfinite(values).any():
                    continue
                style = _path_style(context, k, overlaid=False)
                (line,) = axes.plot(
                    case.u[:, 0], values, label=case.label, gid=f"path:{case.label}", **style
                )
                if k not in listed:
                    legend.curve(line, context.labels[k])
                    listed.add(k)
                _mark_events(
                    axes,
                    context,
                    legend,
                    k,
                    lambda e, case=case, at_event=at_event: (e.u[0], at_event(case, e)),
                )
                drawn = True
            axes.set_ylabel(AXIS_LABELS[name])
            if drawn:
                axes.axhline(0.0, color="k", linewidth=0.8, zorder=1)
                if name == "d2W":
                    axes.set_ylim(-1.1, 1.1)
            else:
                note = (
                    "not defined in the pure-shear limit"
                    if context.rigid
                    else "not available (no finite values)"
                )
                axes.text(
                    0.5,
                    0.5,
                    note,
                    transform=axes.transAxes,
                    ha="center",
                    va="center",
                    color="0.3",
                    gid="note",
                )
                axes.set_yticks([])
                axes.grid(False, axis="y")
        if not listed:
            _set_limits(panels[-1], [case.u[:, 0] for case in context.cases], [])
        panels[-1].set_xlabel(AXIS_LABELS["D1"])
        fig.suptitle(_title(context, "stability"), fontsize=10)
        legend.draw(fig, panels[0], place="below")  # the right side would collide with the title
    return fig


#: Figure kinds by name (the ``figures`` of a study file, ``ncstab plot --kinds``).
FIGURE_KINDS: dict[str, Callable[..., Figure]] = {
    "load_rotation": plot_load_rotation,
    "load_displacement": plot_load_displacement,
    "load_displacement_rotation": plot_load_displacement_rotation,
    "stability": plot_stability,
    "cycle_work": cycle_work_figure,
    "cycle_paths": cycle_paths_figure,
    "cycle_force_drift": cycle_force_drift_figure,
    "stability_diagram": stability_diagram_figure,
    "second_order_work_map": second_order_work_map_figure,
    "second_order_work_polar": second_order_work_polar_figure,
    "state_map": state_map_figure,
}
