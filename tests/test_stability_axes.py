"""The stability figure's x axis follows the system: the load for a path that stays straight
while its load rises (Ziegler's pendulum, a chain of bars), the first dof by its own name
otherwise (a column's w1, not the seed's Delta1*), labelled as the model path figures label them.  Rendered by Agg, never shown."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np

from ncstab.paths import SystemSpec, follow
from ncstab.plotting import plot_stability
from ncstab.systems.assembled_builders import assembled_column


def _paths(figure):
    return [line for axes in figure.axes for line in axes.get_lines() if str(line.get_gid()).startswith("path:")]


def test_a_straight_pendulum_is_drawn_against_its_load():
    """Ziegler under a follower load stays straight up to P = 3 (u = 0 at every state): its
    indicators are drawn against P, each curve's x the stored loads, flutter marked at its load."""
    dataset = follow(SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}]).to_dataset()
    figure = plot_stability(dataset)
    loads = dataset["load"].values.ravel()
    loads = loads[np.isfinite(loads)]
    lines = _paths(figure)
    assert lines
    for line in lines:
        np.testing.assert_array_equal(line.get_xdata(), loads[: len(line.get_xdata())])
    assert figure.axes[2].get_xlabel() == "load P (k/l)"  # as the model path figures label it
    assert figure._suptitle.get_text().endswith("against P")


def test_a_buckled_column_is_drawn_against_its_first_dof_by_name():
    links = 12
    P1 = 4 * np.sin(np.pi / (2 * links)) ** 2
    dataset = follow(assembled_column(links), None,
                     [{"drive": {"P": 1.2 * P1}, "at_bifurcation": "switch"}]).to_dataset()
    figure = plot_stability(dataset)
    u1 = dataset["u"].isel(dof=0).values.ravel()
    u1 = u1[np.isfinite(u1)]
    for line in _paths(figure):
        np.testing.assert_array_equal(line.get_xdata(), u1[: len(line.get_xdata())])
    assert figure.axes[2].get_xlabel() == "w1 (dimensionless)"
    assert figure._suptitle.get_text().endswith("against w1")
