"""One curve per case: what the path figures of a few cases share, and the planar figures.

Every case of the Dataset (law x swept parameters) is one curve with its
located events and, where the seed has one, its closed form dashed over it
(:mod:`ncstab.plotting.closed_form_overlays`).  Two refinements show the
seed's points:

* a single case whose path runs on both branches of the closed form (the
  McNamara path past the maximum of alpha, seed Figs. 3-5) is drawn in two
  colours, one per branch, like the closed form's branches;
* cases that follow the same path (Cundall-Strack and McNamara in pure shear,
  seed Eq. 60) are said to coincide in the legend, and the later ones are
  dashed over the first so that both colours show.

Artists carry a ``gid``: ``"path:<case label>"`` (``"path:<branch>:<case
label>"`` for the parts of a two-branch path), ``"closed_form:<branch>:<case
label>"`` (branch ``-``, ``+``, ``first`` or ``blocking``) and
``"event:<event>:<case label>"``.
"""

from __future__ import annotations

import textwrap
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import xarray as xr
from matplotlib import rc_context
from matplotlib.axes import Axes
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.case_styles import CaseStyles, case_styles
from ncstab.plotting.cases import Case, CaseEvent, path_cases
from ncstab.plotting.coincident_cases import coincidence_note, coincident_cases
from ncstab.plotting.closed_form_overlays import (
    ClosedFormOverlay,
    closed_form_overlay,
)
from ncstab.plotting.event_markers import separate_event_markers
from ncstab.plotting.legend import CLOSED_FORM_STYLE, Legend, event_style
from ncstab.plotting.style import (
    AXIS_LABELS,
    EVENT_MARKERS,
    FAILED_COLOUR,
    FIGURE_SIZE,
    RC_PARAMS,
    fixed_parameters_text,
    force_label,
    format_parameter,
    law_display_name,
    symbolic_text,
)

__all__ = [
    "BRANCH_COLOURS",
    "CurvesContext",
    "curves_context",
    "draw_path",
    "figure_title",
    "mark_events",
    "planar_curves_figure",
]

#: Titles of the figure kinds, and the axes they draw as symbols (second title line).
KIND_TITLES = {
    "load_rotation": "Load–rotation response",
    "load_displacement": "Load–displacement response",
    "load_displacement_rotation": "Load–displacement–rotation response",
    "stability": "Stability indicators along the path",
}
KIND_AXES = {
    "load_rotation": "{F} against $\\alpha$",
    "load_displacement": "{F} against $\\Delta_1^*$",
    "load_displacement_rotation": "({D}, $\\alpha$, {F})",
    "stability": "$\\det K^*$, $\\lambda_{{\\min}}(K^*_{{\\mathrm{{sym}}}})$ and normalised $d^2W$ against $\\Delta_1^*$",
}

#: Line styles: computed paths, under a closed form, failed, following a coincident path.
PATH_STYLE = {"linewidth": 1.8, "solid_capstyle": "round", "zorder": 2}
PATH_WITH_CLOSED_FORM_STYLE = {"linewidth": 3.2, "alpha": 0.45, "solid_capstyle": "round", "zorder": 2}
FAILED_STYLE = {"color": FAILED_COLOUR, "linestyle": (0, (2, 2)), "linewidth": 1.2, "zorder": 1}
#: Dash pattern (points) of a path drawn over a coincident one: the earlier one shows in the gaps.
COINCIDENT_DASH = 7.0
#: Colours of the two branches of a closed form (seed Figs. 4-5 colour each branch).
BRANCH_COLOURS = {-1: "tab:blue", 1: "tab:red"}


@dataclass
class CurvesContext:
    """Cases, their colours and labels, overlays and attributes of one Dataset."""

    dataset: xr.Dataset
    cases: list[Case]
    colours: list[object]
    labels: list[str]
    legend_title: str | None
    overlays: list[ClosedFormOverlay | None]
    normal: str
    description: str
    same_as: list[int | None]
    styles: CaseStyles

    @property
    def rigid(self) -> bool:
        return self.normal == "rigid"

    def path_style(self, k: int, overlaid: bool = True) -> dict[str, object]:
        """Path k: solid; a lighter, wider band under a closed form; dashed over a coincident
        path; dotted grey if failed."""
        if self.cases[k].failed:
            return dict(FAILED_STYLE)
        under_closed_form = overlaid and self.overlays[k] is not None
        style = {**(PATH_WITH_CLOSED_FORM_STYLE if under_closed_form else PATH_STYLE),
                 **self.styles.line(k, self.cases[k].n_steps, len(self.cases))}
        first = self.same_as[k]
        if first is not None:
            # The followers of one path take turns along it, a dash each, and leave one gap
            # in every turn for the first: every colour shows.
            followers = [j for j, same in enumerate(self.same_as) if same == first]
            period = COINCIDENT_DASH * (len(followers) + 1)
            offset = (period - COINCIDENT_DASH * followers.index(k)) % period
            style.update(linestyle=(offset, (COINCIDENT_DASH, period - COINCIDENT_DASH)), alpha=0.9, zorder=2.5)
        if "marker" in style and "alpha" in style:  # a light band, its markers opaque: they tell the cases apart
            opaque = to_rgba(style["color"])
            style.update(color=to_rgba(opaque, style.pop("alpha")), markerfacecolor=opaque, markeredgecolor=opaque)
        return style

    def legend(self) -> Legend:
        """A new legend of these cases: one entry per case, or per law and per value of a
        law x value grid (:mod:`ncstab.plotting.case_styles`)."""
        legend = Legend(title=self.legend_title, factors=self.styles.factors)
        if self.styles.factors is not None and any(case.failed for case in self.cases):
            legend.extra.append((Line2D([], [], **FAILED_STYLE), "failed case (stopped early)"))
        return legend

    def draws_overlay(self, k: int) -> bool:
        """Whether case k's closed form is drawn (not again for a coincident path)."""
        return self.overlays[k] is not None and self.same_as[k] is None


def curves_context(dataset: xr.Dataset) -> CurvesContext:
    """Everything the curve figures need from a Dataset (read once)."""
    cases = path_cases(dataset)
    normal = str(dataset.attrs.get("normal", "deformable"))
    secondary_contacts = str(dataset.attrs.get("secondary_contacts", "activate"))
    labels, title = _compact_labels(cases)
    same_as = coincident_cases(cases, normal == "rigid")
    for k, first in enumerate(same_as):
        if first is not None:
            labels[k] += coincidence_note(cases, labels, k, first, normal == "rigid")
    description = str(dataset.attrs.get("study_description") or dataset.attrs.get("description") or "")
    values = [", ".join(format_parameter(n, v) for n, v in case.swept.items()) for case in cases]
    styles = case_styles([case.law for case in cases], values)
    return CurvesContext(
        dataset=dataset,
        cases=cases,
        colours=styles.colours,
        labels=labels,
        legend_title=title,
        overlays=[closed_form_overlay(case, normal, secondary_contacts) for case in cases],
        normal=normal,
        description=description,
        same_as=same_as,
        styles=styles,
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


def figure_title(dataset: xr.Dataset, kind: str, width: int = 76) -> str:
    """Study description (or the kind's title and fixed parameters) in symbols, then the
    axes the kind draws: ``"Seed Figs. 3-5: ..., γ = 2, α₀ = π/4\\n$F_1^*$ against $\\alpha$"``."""
    description = str(dataset.attrs.get("study_description") or dataset.attrs.get("description") or "")
    rigid = str(dataset.attrs.get("normal", "deformable")) == "rigid"
    if description:
        head = textwrap.fill(symbolic_text(description), width)
    else:
        details = fixed_parameters_text(dataset.attrs)
        if rigid:
            details = ", ".join(filter(None, [details, "pure-shear limit"]))
        head = f"{KIND_TITLES[kind]}, {details}" if details else KIND_TITLES[kind]
    force = r"$\hat F_1$" if rigid else r"$F_1^*$"
    return head + "\n" + KIND_AXES[kind].format(F=force, D=r"$\Delta_1^*$")


def new_figure(figure: Figure | None) -> Figure:
    return figure if figure is not None else Figure(figsize=FIGURE_SIZE, layout="constrained")


def set_limits(axes: Axes, xs: list[np.ndarray], ys: list[np.ndarray], margin: float = 0.04) -> None:
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


def mark_events(
    axes: Axes,
    context: CurvesContext,
    legend: Legend,
    k: int,
    where: Callable[[CaseEvent], tuple[float, ...]],
) -> list[tuple[float, ...]]:
    """Draw the events of case k at where(event); return the points drawn (non-finite: none)."""
    case = context.cases[k]
    colour = FAILED_COLOUR if case.failed else context.colours[k]
    points = []
    for name, event in case.events.items():  # EVENT_MARKERS' order, then the extrema
        kind = "extremum" if name.startswith("extremum_") else name
        if kind not in EVENT_MARKERS:
            continue
        point = where(event)
        if not np.all(np.isfinite(point)):
            continue
        axes.plot(*[[c] for c in point], linestyle="none", zorder=5,
                  gid=f"event:{name}:{case.label}", **event_style(kind, colour))
        legend.event(kind)
        points.append(point)
    return points


def two_branch_case(context: CurvesContext) -> np.ndarray | None:
    """The branch of each state when the Dataset is one case running on both branches."""
    if len(context.cases) != 1 or context.overlays[0] is None:
        return None
    branch = context.overlays[0].path_branch
    if branch is None or not ((branch == -1).any() and (branch == 1).any()):
        return None
    return branch


def branch_pieces(branch: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """(branch, indices) of the runs of states on one branch; each run ends on the first
    state of the next one, so that the pieces join."""
    change = np.flatnonzero(np.diff(branch) != 0) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [branch.size]])
    return [(int(branch[a]), np.arange(a, min(b + 1, branch.size))) for a, b in zip(starts, ends)]


def _branch_label(overlay: ClosedFormOverlay, sign: int) -> str:
    where = "before the maximum of α" if sign == -1 else "past the maximum of α"
    return f"path on branch {'−' if sign == -1 else '+'} of {overlay.branch_equation} ({where})"


def draw_path(axes: Axes, context: CurvesContext, legend: Legend, k: int, *xyz: np.ndarray) -> None:
    """Case k's computed path through the coordinates xyz (2-D or 3-D), in its style; a
    two-branch single case in one colour per branch."""
    case = context.cases[k]
    branch = two_branch_case(context)
    if branch is None:
        style = context.path_style(k)
        (line,) = axes.plot(*xyz, label=case.label, gid=f"path:{case.label}", **style)
        if context.same_as[k] is not None:  # the legend shows the dashes from their start
            line = Line2D([], [], **{**style, "linestyle": (0, (COINCIDENT_DASH, COINCIDENT_DASH / 2))})
        legend.curve(line, context.labels[k])
        return
    overlay = context.overlays[k]
    assert overlay is not None
    seen = set()
    for sign, steps in branch_pieces(branch):
        style = {**context.path_style(k), "color": BRANCH_COLOURS.get(sign, context.colours[k])}
        name = {-1: "-", 1: "+"}.get(sign, "other")
        (line,) = axes.plot(*[c[steps] for c in xyz], label=case.label, gid=f"path:{name}:{case.label}", **style)
        if sign in BRANCH_COLOURS and sign not in seen:
            legend.curve(line, _branch_label(overlay, sign))
            seen.add(sign)


def overlay_colour(context: CurvesContext, k: int, branch_name: str) -> object:
    """Colour of a closed-form branch: its branch colour for a two-branch case, else the case's."""
    if two_branch_case(context) is not None and branch_name in ("-", "+"):
        return BRANCH_COLOURS[-1 if branch_name == "-" else 1]
    return context.colours[k]


def _draw_overlay_2d(axes: Axes, context: CurvesContext, k: int, rotation: bool) -> None:
    overlay, case = context.overlays[k], context.cases[k]
    assert overlay is not None
    for branch in overlay.branches:
        axes.plot(branch.alpha if rotation else branch.D1, branch.F1,
                  color=overlay_colour(context, k, branch.name),
                  gid=f"closed_form:{branch.name}:{case.label}", label="_closed form", **CLOSED_FORM_STYLE)
    if overlay.blocking is not None:  # alpha = alpha_max from the first branch's end up to the path's top
        position = overlay.blocking.alpha if rotation else overlay.blocking.D1
        start = overlay.branches[0].F1[-1] if overlay.branches else np.nanmin(case.F[:, 0])
        top = max(float(np.nanmax(case.F[:, 0])), float(start))
        axes.plot([position, position], [start, top], color=context.colours[k],
                  gid=f"closed_form:blocking:{case.label}", label="_blocking", **CLOSED_FORM_STYLE)


def _note_junction(axes: Axes, context: CurvesContext) -> None:
    """Load-displacement of a two-branch case: where the branches meet looks like a
    crossing of two curves (a bifurcation); it is the maximum of alpha (seed Fig. 4-5)."""
    branch = two_branch_case(context)
    if branch is None:
        return
    case = context.cases[0]
    first = int(np.flatnonzero(branch == 1)[0])
    x, y = case.u[first, 0], case.F[first, 0]
    axes.annotate(
        "branches meet: an apparent crossing,\nnot a bifurcation (α is maximal here;\nsee the 3-D view)",
        xy=(x, y), xytext=(0.97, 0.06), textcoords="axes fraction", ha="right", va="bottom",
        fontsize=8, color="0.2", gid="branch_junction",
        arrowprops={"arrowstyle": "->", "color": "0.3", "lw": 0.9},
    )


def planar_curves_figure(dataset: xr.Dataset, figure: Figure | None, kind: str) -> Figure:
    """F1 against alpha (``load_rotation``) or Delta1* (``load_displacement``): one curve per case."""
    rotation = kind == "load_rotation"
    with rc_context(RC_PARAMS):
        context = curves_context(dataset)
        fig = new_figure(figure)
        axes = fig.add_subplot()
        legend = context.legend()
        xs, ys = [], []
        for k, case in enumerate(context.cases):
            x = case.alpha if rotation else case.u[:, 0]
            y = case.F[:, 0]
            draw_path(axes, context, legend, k, x, y)
            xs.append(x)
            ys.append(y)
            if context.draws_overlay(k):
                _draw_overlay_2d(axes, context, k, rotation)
                overlay = context.overlays[k]
                assert overlay is not None
                legend.closed_form(overlay.rotation_equations if rotation else overlay.displacement_equations)
            points = mark_events(axes, context, legend, k, lambda e: (e.alpha if rotation else e.u[0], e.F[0]))
            xs += [np.array([p[0]]) for p in points]
            ys += [np.array([p[1]]) for p in points]
        set_limits(axes, xs, ys)
        separate_event_markers(axes)  # cases meeting an event at nearly one point: each marker shows
        axes.set_xlabel(AXIS_LABELS["alpha" if rotation else "D1"])
        axes.set_ylabel(force_label(context.normal))
        if rotation:
            top = axes.secondary_xaxis("top", functions=(np.degrees, np.radians))
            top.set_xlabel(AXIS_LABELS["alpha_deg"], fontsize=9)
        else:
            _note_junction(axes, context)
        axes.axhline(0.0, color="0.5", linewidth=0.6, zorder=1)
        fig.suptitle(figure_title(dataset, kind), fontsize=10)  # above an outside legend too
        if not context.cases:
            axes.text(0.5, 0.5, "no cases in the Dataset", transform=axes.transAxes, ha="center", va="center")
        legend.draw(fig, axes, points=list(zip(xs, ys)))
    return fig
