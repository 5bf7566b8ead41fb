"""The [map] section of study files and the second-order work figures (issue 6)."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import xarray as xr

from ncstab import DiamondChain, make_law
from ncstab.operators.state_map import state_map
from ncstab.plotting import draw_figures
from ncstab.plotting.maps import (
    second_order_work_map_figure,
    second_order_work_polar_figure,
    state_map_figure,
)
from ncstab.studies import StudyFileError, open_study, parse_study, run_study, write_dataset

STUDY = """
[study]
name = "maps"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.5, 2.0]
F2_lateral = 0.75
[[loading]]
hold = { F1 = 0.0 }
drive = { F2 = "F2_lateral" }
[[loading]]
hold = { F2 = "current" }
drive = { D1 = 0.6 }
[map]
directions = 36
grid = { D1 = [-0.35, 0.65, 21], D2 = [-0.1, 0.6, 15] }
[output]
figures = ["second_order_work_map", "second_order_work_polar", "state_map"]
"""


@pytest.fixture(scope="module")
def dataset() -> xr.Dataset:
    return run_study(parse_study(STUDY))


def test_map_section_adds_directional_maps_and_state_maps(dataset, tmp_path):
    assert dataset["d2W_dir"].dims == ("law", "gamma", "step", "theta")
    assert dataset.sizes["theta"] == 36
    assert dataset["map_hill"].dims == ("law", "gamma", "map_D1", "map_D2")
    # The rate law has no state map (its K depends on the history): NaN, never a number.
    assert np.isnan(dataset["map_hill"].sel(law="cundall_strack").values).all()
    # The hyperelastic maps equal the operator-level state map, case by case.
    expected = state_map(DiamondChain(), make_law("mcnamara", gamma=2.0), dataset["map_D1"].values,
                         dataset["map_D2"].values)
    np.testing.assert_allclose(dataset["map_det_K"].sel(law="mcnamara", gamma=2.0).values,
                               expected["map_det_K"], rtol=0, atol=1e-13)
    for name in ("map_hill", "d2W_dir", "cone_width"):
        assert {"units", "long_name", "description"} <= set(dataset[name].attrs)
    path = write_dataset(dataset, tmp_path / "maps.nc")
    xr.testing.assert_identical(dataset, open_study(path))


def test_second_order_work_figures(dataset, tmp_path):
    figure = second_order_work_map_figure(dataset)
    assert len(figure.axes) == 2 * 4  # four cases, each with a colour bar
    # The exact cone bounds are drawn where the cone exists.
    bounds = [line for ax in figure.axes for line in ax.get_lines() if line.get_gid() == "cone_bound"]
    assert any(np.isfinite(line.get_ydata()).any() for line in bounds)
    polar = second_order_work_polar_figure(dataset)
    assert any(line.get_gid() == "polar:Hill loss" for line in polar.axes[0].get_lines())
    state = state_map_figure(dataset)
    assert len([a for a in state.axes if a.get_title()]) == 2  # the two mcnamara cases
    paths = draw_figures(dataset, tmp_path, stem="maps")
    assert sorted(p.name for p in paths) == [
        "maps_second_order_work_map.png", "maps_second_order_work_polar.png", "maps_state_map.png"]
    assert all(p.stat().st_size > 20_000 for p in paths)


def test_figures_without_the_map_variables_say_what_to_add(dataset):
    with pytest.raises(ValueError, match="directions"):
        second_order_work_map_figure(dataset.drop_vars("d2W_dir"))
    with pytest.raises(ValueError, match="grid"):
        state_map_figure(dataset.drop_vars("map_hill"))


@pytest.mark.parametrize(
    "section, field",
    [
        ("[map]\ndirections = 2", "map.directions"),
        ("[map]\ndirections = true", "map.directions"),
        ("[map]\ngrid = { D1 = [0.0, 0.1], D2 = [0.0, 0.1, 5] }", "map.grid.D1"),
        ("[map]\ngrid = { D1 = [0.1, 0.0, 5], D2 = [0.0, 0.1, 5] }", "map.grid.D1"),
        ("[map]\ngrid = { D1 = [0.0, 0.1, 5], D3 = [0.0, 0.1, 5] }", "map.grid.D3"),
        ("[map]\nsteps = 3", "map.steps"),
        ("[map]", "map"),
    ],
)
def test_bad_map_sections_name_the_field(section, field):
    text = STUDY.split("[map]")[0] + section + "\n"
    with pytest.raises(StudyFileError) as error:
        parse_study(text)
    assert field in error.value.fields
