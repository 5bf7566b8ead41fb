"""What issue 41 saw in the figures, each checked as an exact property of the drawn artists.

Case styles of a law x value grid, the symlog det K panel, event markers set
apart, the stability diagram's notes, Hencky's branches from the bifurcation
on, and the pure-shear blocking line from the branch's end.  Rendered by Agg,
never shown.
"""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from ncstab.plotting import plot_load_displacement
from ncstab.plotting.case_styles import LAW_LINESTYLES, case_styles
from ncstab.plotting.diagrams import sparse_note
from ncstab.plotting.event_markers import MARKER_GAP, separate_event_markers
from ncstab.plotting.stability_curves import symlog_if_spread
from ncstab.studies import load_study, run_study
from ncstab.systems.closed_forms import pure_shear_load_rotation

ROOT = Path(__file__).resolve().parents[1]


def test_a_law_by_value_grid_is_coloured_by_value_and_styled_by_law():
    styles = case_styles(["mcnamara", "mcnamara", "turco", "turco"], ["γ = 1", "γ = 2", "γ = 1", "γ = 2"])
    assert styles.colours[0] == styles.colours[2] and styles.colours[1] == styles.colours[3]
    assert styles.colours[0] != styles.colours[1]
    assert styles.linestyles == [LAW_LINESTYLES[0]] * 2 + [LAW_LINESTYLES[1]] * 2
    assert [text for _, text in styles.factors] == [
        "McNamara et al. 2008 (hyperelastic)", "Turco et al. 2019 (hyperelastic)", "γ = 1", "γ = 2"]
    # Not a grid (a pair missing): each case its own entry, its own colour and, from 4, marker.
    single = case_styles(["mcnamara"] * 5, [f"γ = {k}" for k in range(5)])
    assert single.factors is None
    assert len(set(single.markers)) == 5 and None not in single.markers


def test_det_k_goes_symlog_only_when_the_cases_spread_over_decades():
    figure = Figure()
    axes = figure.add_subplot()
    assert symlog_if_spread(axes, [np.linspace(1, 2, 5), np.linspace(1.5, 3, 5)]) is None
    assert axes.get_yscale() == "linear"
    # medians 1.5 and 1500: a factor 1000 > 30; linthresh the power of ten at or below 1.5.
    assert symlog_if_spread(axes, [np.linspace(1, 2, 5), np.linspace(1000, 2000, 5)]) == 1.0
    assert axes.get_yscale() == "symlog" and "symlog" in axes.get_ylabel()


def test_two_event_markers_at_one_point_are_drawn_apart():
    figure = Figure(figsize=(4, 3), dpi=100)
    FigureCanvasAgg(figure)
    axes = figure.add_subplot()
    axes.set_xlim(0, 1)
    axes.set_ylim(0, 1)
    axes.plot([0.5], [0.5], "x", markersize=8, gid="event:secondary_contact:a")
    second, = axes.plot([0.5], [0.5], "x", markersize=8, gid="event:secondary_contact:b")
    (moved, shift), = separate_event_markers(axes)
    assert moved is second
    assert math.hypot(*shift) == pytest.approx(8 + MARKER_GAP, rel=1e-12)  # two radii and the gap
    assert (second.get_xdata()[0], second.get_ydata()[0]) == (0.5, 0.5)  # the located point kept


@pytest.mark.parametrize("reached, note", [(0, "not reached\nin this plane"),
                                           (1, "reached in 1 of 4,096\ncells only (circled)"),
                                           (40, "reached in 40 of 4,096\ncells only (circled)"),
                                           (41, None)])
def test_every_nearly_empty_diagram_panel_says_so(reached, note):
    field = np.full(4096, np.nan)
    field[:reached] = 1.0
    assert sparse_note(field.reshape(64, 64)) == note


def test_hencky_branches_start_at_the_bifurcation_in_their_own_colour():
    study = load_study(ROOT / "studies" / "column_buckling.toml")  # P1 = 0.382 < the stop, 0.5
    dataset = run_study(study)
    axes = plot_load_displacement(dataset).axes[0]
    lines = {line.get_gid(): line for line in axes.lines if str(line.get_gid()).startswith("path:")}
    straight = [line for gid, line in lines.items() if "path followed" in gid]
    branches = [line for gid, line in lines.items() if "bifurcated branch" in gid]
    assert straight and len(branches) == 2
    at = float(dataset["bifurcation_load"].max())  # located on every branch (NaN skipped)
    assert np.isfinite(at)
    for line in branches:
        load = np.asarray(line.get_ydata())
        assert load[0] <= at and (load[1:] > at - 1e-9).all()  # the shared straight part not redrawn
        assert line.get_color() != straight[0].get_color()


def test_the_blocking_line_runs_from_the_branch_end_up_to_the_path():
    study = load_study(ROOT / "studies" / "seed" / "fig14_15_pure_shear_blocking.toml")
    dataset = run_study(study)
    axes = plot_load_displacement(dataset).axes[0]
    blocking = [line for line in axes.lines if str(line.get_gid()).startswith("closed_form:blocking:")]
    assert blocking
    alpha0 = math.pi / 4
    for line in blocking:
        law = "turco" if "Turco" in line.get_gid() else "rotational"
        alpha_max = math.pi / 3 if law == "rotational" else None
        start, top = line.get_ydata()
        if alpha_max is not None:  # seed Eq. (62) at alpha_max = pi/3 (Eq. 66)
            assert start == pytest.approx(float(pure_shear_load_rotation(alpha_max, alpha0, 0.0, "rotational")), abs=1e-12)
        assert top == pytest.approx(1.0, abs=1e-8)  # the stage drives F1 to 1 (to its stop tolerance)
        assert start < top
