"""No two texts or legends of a figure overlap, for every figure kind and 1, 3, 12 and 13 cases.

Each figure is drawn by the Agg canvas (``fig.canvas.draw``); then the window
extents (display pixels) of every visible, non-empty text (titles, labels,
tick labels, notes; a legend's own texts excepted) and of every legend are
compared pairwise (tick labels of ticks outside the view are not drawn and
not compared): two that share more than :data:`TOUCH` pixels along both
axes overlap.  A legend is one box (its texts are inside it by construction).

Three small studies, each run once (a few seconds in all), give every kind
its data: the diamond (path, cycle and map figures), the diamond over a plane
of two parameters (the stability diagram) and Ziegler's pendulum over both
dashpots with its spectrum (the dynamic figures).  The case counts are
sub-sweeps of them (``isel``): 13 cases is a fan (more than MAX_CURVES), 12 a
law x value grid of curves.
"""

from __future__ import annotations

import itertools

import matplotlib

matplotlib.use("Agg")

import pytest
import xarray as xr
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.legend import Legend
from matplotlib.text import Text

from ncstab.plotting import FIGURE_KINDS
from ncstab.studies import parse_study, run_study

#: Overlap allowed along an axis, pixels (rounding of the extents).
TOUCH = 1.0

DIAMOND = """\
[study]
name = "overlaps"
description = "Texts and legends apart: the diamond, gamma = 0.25 ... 2, alpha0 = pi/4"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.15, 1.3, 1.45, 1.6, 1.75, 1.9, 2.0]
[[loading]]
hold = { D2 = 0.0 }
drive = { D1 = 0.05 }
[[loading]]
cycle = { center = [0.08, 0.0], turns = 1, direction = 1 }
[options]
max_step = 0.05
[map]
directions = 12
grid = { D1 = [-0.1, 0.2, 5], D2 = [-0.1, 0.1, 4] }
"""

PLANE = """\
[study]
name = "overlaps_plane"
description = "Texts and legends apart: a plane of gamma and F2*"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.25, 0.4, 0.55, 0.7, 0.85, 1.0, 1.15, 1.3, 1.45, 1.6, 1.75, 1.9, 2.0]
F2_lateral = [0.0, 0.3, 0.6, 0.8]
[[loading]]
hold = { F1 = 0.0 }
drive = { F2 = "F2_lateral" }
[[loading]]
hold = { F2 = "current" }
drive = { D1 = 0.4 }
[options]
sample_step = 0.1
"""

ZIEGLER = """\
[study]
name = "overlaps_ziegler"
description = "Texts and legends apart: Ziegler's pendulum over both dashpots"
[system]
name = "ziegler"
load = "follower"
[parameters]
b1 = [0.01, 0.02, 0.03, 0.04, 0.05, 0.06, 0.07, 0.08, 0.09, 0.1, 0.11, 0.12, 0.13]
b2 = [0.01, 0.05, 0.1, 0.15]
[[loading]]
drive = { P = 3.0 }
[options]
sample_step = 0.1
[output]
spectrum = true
"""

PATH_KINDS = ("load_rotation", "load_displacement", "load_displacement_rotation", "stability",
              "second_order_work_map", "second_order_work_polar", "state_map", "cycle_work", "cycle_paths",
              "cycle_force_drift")
DYNAMIC_KINDS = ("root_locus", "frequencies", "damping_map", "stability")


@pytest.fixture(scope="module")
def studies() -> dict[str, xr.Dataset]:
    return {name: run_study(parse_study(text)) for name, text in
            (("diamond", DIAMOND), ("plane", PLANE), ("ziegler", ZIEGLER))}


#: Sub-sweeps by number of cases: study -> cases -> isel.
SUBSETS = {
    "diamond": {1: {"law": [0], "gamma": [0]}, 3: {"law": [0], "gamma": [0, 6, 12]},
                12: {"gamma": slice(0, 6)}, 13: {"law": [0]}},
    "plane": {1: {"law": [0], "gamma": [0], "F2_lateral": [0]}, 3: {"law": [0], "gamma": [0, 6, 12], "F2_lateral": [1]},
              12: {"law": [0], "gamma": [0, 4, 8], "F2_lateral": slice(None)}, 13: {"law": [0], "F2_lateral": [2]}},
    "ziegler": {1: {"b1": [0], "b2": [0]}, 3: {"b1": [0, 4, 9], "b2": [1]}, 12: {"b1": [0, 4, 9], "b2": slice(None)},
                13: {"b2": [1]}},
}

CASES = (1, 3, 12, 13)
KINDS = [("diamond", kind) for kind in PATH_KINDS] + [("plane", "stability_diagram")] + \
        [("ziegler", kind) for kind in DYNAMIC_KINDS]


def _undrawn_tick_labels(figure) -> set[int]:
    """Tick labels matplotlib keeps but does not draw: their tick lies outside the view."""
    hidden = set()
    for axes in figure.axes:
        for axis in (axes.xaxis, axes.yaxis):
            low, high = sorted(axis.get_view_interval())
            span = (high - low) * 1e-9
            for tick in axis.get_major_ticks() + axis.get_minor_ticks():
                if not low - span <= tick.get_loc() <= high + span:
                    hidden |= {id(tick.label1), id(tick.label2)}
    return hidden


def boxes(figure) -> list[tuple[str, object]]:
    """(description, window extent) of every visible non-empty text outside a legend, and of
    every legend."""
    figure.canvas.draw()
    renderer = figure.canvas.get_renderer()
    legends = [legend for legend in figure.findobj(Legend) if legend.get_visible()]
    inside = {id(text) for legend in legends for text in legend.findobj(Text)}
    inside |= _undrawn_tick_labels(figure)
    out = [(f"legend {legend.get_gid()}", legend.get_window_extent(renderer)) for legend in legends]
    for text in figure.findobj(Text):
        if id(text) in inside or not text.get_visible() or not text.get_text().strip():
            continue
        axes = text.axes
        if axes is not None and not axes.get_visible():
            continue
        out.append((repr(text.get_text()), text.get_window_extent(renderer)))
    return out


def overlapping(figure) -> list[str]:
    found = []
    for (name_a, a), (name_b, b) in itertools.combinations(boxes(figure), 2):
        dx = min(a.x1, b.x1) - max(a.x0, b.x0)
        dy = min(a.y1, b.y1) - max(a.y0, b.y0)
        if dx > TOUCH and dy > TOUCH:
            found.append(f"{name_a} and {name_b} overlap by {dx:.0f} x {dy:.0f} px")
    return found


@pytest.mark.parametrize("cases", CASES)
@pytest.mark.parametrize("study, kind", KINDS, ids=[f"{s}-{k}" for s, k in KINDS])
def test_no_two_texts_or_legends_overlap(studies, study, kind, cases):
    dataset = studies[study].isel(SUBSETS[study][cases])
    n_cases = dataset["status"].size
    assert n_cases == cases
    figure = FIGURE_KINDS[kind](dataset)
    FigureCanvasAgg(figure)
    assert overlapping(figure) == []
