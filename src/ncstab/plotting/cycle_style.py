"""The look of the cycle figures: colours by law or along the sweep, markers and line
styles by swept parameters, legends, subtitles and stage marks."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import xarray as xr
from matplotlib import colormaps
from matplotlib.axes import Axes
from matplotlib.figure import Figure
from matplotlib.lines import Line2D

from ncstab.plotting.cycle_cases import CycleCase, CycleLayout
from ncstab.plotting.style import fixed_parameters_text, law_display_name

__all__ = [
    "LINESTYLES",
    "MARKERS",
    "CycleStyle",
    "cycle_styles",
    "legend_handles",
    "new_figure",
    "stage_boundaries",
    "stage_labels",
    "subtitle",
]

#: Marker and line style of the k-th combination of swept parameters.
MARKERS = ("o", "s", "^", "D", "v", "P", "X", "<", ">")
LINESTYLES = ("-", "--", ":", "-.")


@dataclass(frozen=True)
class CycleStyle:
    colour: object
    marker: str
    linestyle: str


def cycle_styles(cases: Sequence[CycleCase]) -> list[CycleStyle]:
    """Colour by law (several laws) or along viridis (one law); marker and line style by parameters."""
    n_laws = len({c.law_index for c in cases})
    n_parameters = len({c.parameter_index for c in cases})
    palette = colormaps["tab10"].colors
    viridis = colormaps["viridis"]
    out = []
    for case in cases:
        p = case.parameter_index
        if n_laws > 1:
            colour: object = palette[case.law_index % len(palette)]
        else:
            colour = viridis(0.0 if n_parameters == 1 else 0.85 * p / (n_parameters - 1))
        out.append(CycleStyle(colour, MARKERS[p % len(MARKERS)], LINESTYLES[p % len(LINESTYLES)]))
    return out


def legend_handles(
    cases: Sequence[CycleCase], styles: Sequence[CycleStyle], markers: bool
) -> list[Line2D]:
    """Proxy artists: one per law (colour), one per parameter combination (marker/line)."""
    laws: dict[int, Line2D] = {}
    parameters: dict[int, Line2D] = {}
    several_laws = len({c.law_index for c in cases}) > 1
    for case, style in zip(cases, styles):
        if several_laws and case.law_index not in laws:
            laws[case.law_index] = Line2D(
                [], [], color=style.colour, lw=2.2, label=law_display_name(case.law)
            )
        if case.parameter_index not in parameters and case.parameter_label:
            colour = "0.35" if several_laws else style.colour
            parameters[case.parameter_index] = Line2D(
                [],
                [],
                color=colour,
                ls=style.linestyle,
                lw=1.2,
                marker=style.marker if markers else None,
                ms=5,
                label=case.parameter_label,
            )
    if not several_laws and cases:
        if len(parameters) <= 1:
            return [
                Line2D([], [], color=styles[0].colour, lw=2.2, label=law_display_name(cases[0].law))
            ]
        parameters = {
            -1: Line2D([], [], color="none", label=law_display_name(cases[0].law)),
            **parameters,
        }
    return list(laws.values()) + list(parameters.values())


def new_figure(figure: Figure | None, size: tuple[float, float]) -> Figure:
    return figure if figure is not None else Figure(figsize=size, layout="constrained")


def subtitle(dataset: xr.Dataset, layout: CycleLayout, stages: bool = False) -> str:
    """Fixed parameters (``"α₀ = π/4, γ = 0.5"``), optionally with each stage's turns and sense."""
    parts = [fixed_parameters_text(dataset.attrs)]
    if stages:
        parts.append("; ".join(layout.describe(k) for k in layout.stages))
    return " — ".join(p for p in parts if p)


def stage_boundaries(ax: Axes, layout: CycleLayout, positions: Sequence[float]) -> None:
    for x in positions:
        ax.axvline(x, color="0.45", ls="--", lw=0.8, zorder=1, gid="stage_boundary")


def stage_labels(ax: Axes, layout: CycleLayout, centre: dict[int, float]) -> None:
    """Direction of each cycle stage written above the axes, over its turns."""
    transform = ax.get_xaxis_transform()
    for k in layout.stages:
        ax.text(
            centre[k],
            1.015,
            layout.describe(k),
            transform=transform,
            ha="center",
            va="bottom",
            fontsize=8,
            color="0.25",
            gid="stage_label",
        )
