"""Stability diagrams (issue 6): cells equal single-case runs, the mask, the figure, the study."""

from __future__ import annotations

import math
import re
from pathlib import Path

import matplotlib.image as mpimg
import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

import ncstab
from ncstab.cli import main
from ncstab.paths import PathOptions, SystemSpec
from ncstab.plotting import FIGURE_KINDS
from ncstab.plotting.diagrams import (
    DIAGRAM_EVENTS,
    STRICTLY_BEFORE,
    hill_before_limit,
    stability_diagram_figure,
)
from ncstab.studies import load_study, open_study

ROOT = Path(__file__).resolve().parents[1]
STUDY = ROOT / "studies" / "stability_diagram.toml"

#: The programme of studies/stability_diagram.toml.
PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]
OPTIONS = PathOptions(max_step=0.05)
LAWS = ["cundall_strack", "mcnamara"]
#: Chosen so that both laws reach their events in some cells and not in others.
GAMMA = [0.3, 0.45, 0.6, 0.9, 1.4]
LATERAL = [0.0, 0.4, 0.65, 0.8]
#: Event quantities compared between a diagram cell and its single-case run.
#: The engine advances every case with its own step size, so a case does not
#: depend on the others of the batch: the only difference allowed is round-off
#: in the vectorised linear algebra, far below 1e-12.
CELL_TOLERANCE = 1e-12


def _follow(gamma, lateral, laws=LAWS):
    return ncstab.follow(
        SystemSpec(secondary_contacts="ignore"),
        laws,
        PROGRAMME,
        {"gamma": gamma, "F2_lateral": lateral, "alpha0": math.pi / 4},
        OPTIONS,
    )


@pytest.fixture(scope="module")
def diagram():
    return _follow(GAMMA, LATERAL).to_dataset()


def test_the_small_diagram_has_events_and_cells_without(diagram):
    for law in LAWS:
        limit = diagram["limit_point_s"].sel(law=law)
        assert 0 < int(limit.notnull().sum()) < limit.size, law
    assert hill_before_limit(diagram).sel(law="cundall_strack").any()


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("gamma, lateral", [(0.45, 0.8), (0.6, 0.65), (0.9, 0.4), (0.3, 0.0)])
def test_diagram_cells_equal_single_case_runs(diagram, law, gamma, lateral):
    cell = diagram.sel(law=law, gamma=gamma, F2_lateral=lateral)
    single = _follow(gamma, lateral, [law]).to_dataset().isel(law=0)
    assert str(cell["status"].values) == str(single["status"].values)
    for event in DIAGRAM_EVENTS:
        for name in (f"{event}_s", f"{event}_F", f"{event}_alpha"):
            np.testing.assert_allclose(
                cell[name].values, single[name].values, rtol=0, atol=CELL_TOLERANCE, equal_nan=True, err_msg=name
            )


def test_hill_before_limit_is_hill_loss_strictly_before_the_limit_point(diagram):
    mask = hill_before_limit(diagram)
    assert mask.dims == diagram["status"].dims and mask.dtype == bool
    hill, limit = diagram["hill_loss_s"].values, diagram["limit_point_s"].values
    expected = np.isfinite(hill) & (~np.isfinite(limit) | (hill < limit - STRICTLY_BEFORE))
    np.testing.assert_array_equal(mask.values, expected)
    # Hyperelastic: K is symmetric on the path (seed Eq. 41), so Hill's condition
    # and det K are lost at the same state: never strictly before.
    mcnamara = diagram.sel(law="mcnamara")
    assert not mask.sel(law="mcnamara").any()
    both = mcnamara["limit_point_s"].notnull().values
    np.testing.assert_array_equal(mcnamara["hill_loss_s"].notnull().values, both)
    np.testing.assert_allclose(
        mcnamara["hill_loss_s"].values[both], mcnamara["limit_point_s"].values[both], rtol=0, atol=STRICTLY_BEFORE
    )


def _runs(collection):
    """The hatched rectangles of a collection: the closed sub-paths of its compound path(s)."""
    return [polygon for path in collection.get_paths() for polygon in path.to_polygons()]


def _hatched_cells(axes, gid):
    """Number of grid cells covered by the hatched rectangles of a panel (unit = one cell)."""
    collections = [c for c in axes.collections if c.get_gid() == gid]
    if not collections:
        return 0.0
    (collection,) = collections
    x_cell = np.diff(axes.get_xlim())[0] / len(GAMMA)
    y_cell = np.diff(axes.get_ylim())[0] / len(LATERAL)
    total = 0.0
    for vertices in _runs(collection):
        total += np.ptp(vertices[:, 0]) * np.ptp(vertices[:, 1])
    return total / (x_cell * y_cell)


def test_figure_panels_hatching_and_labels(diagram):
    figure = stability_diagram_figure(diagram)
    panels = {a.get_gid(): a for a in figure.axes if str(a.get_gid()).startswith("diagram:")}
    assert sorted(panels) == sorted(f"diagram:{e}:{law}" for e in DIAGRAM_EVENTS for law in LAWS)
    assert sorted(a.get_gid() for a in figure.axes if str(a.get_gid()).startswith("colorbar:")) == sorted(
        f"colorbar:{e}" for e in DIAGRAM_EVENTS)
    mask = hill_before_limit(diagram)
    for law in LAWS:
        # GAMMA is not evenly spaced, so compare cell by cell: each hatched run
        # covers masked cells only, and the runs add up to the masked cells.
        panel = panels[f"diagram:limit_point:{law}"]
        collections = [c for c in panel.collections if c.get_gid() == f"hill_before_limit:{law}"]
        covered = np.zeros((len(LATERAL), len(GAMMA)), bool)
        for collection in collections:
            for vertices in _runs(collection):
                (x0, y0), (x1, y1) = vertices.min(0), vertices.max(0)
                gx = np.array(GAMMA)
                gy = np.array(LATERAL)
                covered[np.ix_((gy > y0) & (gy < y1), (gx > x0) & (gx < x1))] = True
        np.testing.assert_array_equal(covered, mask.sel(law=law).transpose("F2_lateral", "gamma").values)
    bottom = panels["diagram:hill_loss:mcnamara"]
    assert "k_t/k_n" in bottom.get_xlabel() and r"\gamma" in bottom.get_xlabel()
    assert "F_2^*" in bottom.get_ylabel() and "McNamara" in bottom.get_ylabel()
    assert "Hill" in panels["diagram:hill_loss:cundall_strack"].get_title()
    legend_texts = [t.get_text() for legend in figure.legends for t in legend.get_texts()]
    assert any("not reached" in t for t in legend_texts)
    assert any("strictly before the limit point" in t for t in legend_texts)


def test_figure_renders_to_a_non_trivial_png(diagram, tmp_path):
    figure = stability_diagram_figure(diagram)
    FigureCanvasAgg(figure)
    png = tmp_path / "diagram.png"
    figure.savefig(png, dpi=80)
    image = mpimg.imread(png)
    rgb = image[..., :3].reshape(-1, 3)
    assert image.shape[0] > 400 and image.shape[1] > 500
    assert (rgb.sum(axis=1) < 2.5).mean() > 0.05  # panels, not a blank canvas
    assert len(np.unique((rgb * 255).astype(np.uint8), axis=0)) > 50  # a colour field


def test_failed_cases_are_hatched_and_counted(diagram):
    broken = diagram.copy()
    status = broken["status"].values.astype(object)
    status[0, 0, 0] = "failed:max_steps"
    broken["status"] = (broken["status"].dims, status.astype(str))
    figure = stability_diagram_figure(broken)
    legend_texts = [t.get_text() for legend in figure.legends for t in legend.get_texts()]
    assert any("failed case (1 of 40" in t for t in legend_texts)
    panel = next(a for a in figure.axes if a.get_gid() == "diagram:hill_loss:cundall_strack")
    assert any(c.get_gid() == "failed:cundall_strack" for c in panel.collections)


def test_other_than_two_sweep_dimensions_is_refused(diagram):
    with pytest.raises(ValueError, match=r"exactly two swept parameters.*\['gamma'\]"):
        stability_diagram_figure(diagram.isel(F2_lateral=0))
    three = diagram.expand_dims(alpha0=[0.7])
    three["status"] = three["status"].transpose("law", "alpha0", ...)
    with pytest.raises(ValueError, match=r"alpha0"):
        stability_diagram_figure(three)


def test_registered_as_a_figure_kind():
    assert FIGURE_KINDS["stability_diagram"] is stability_diagram_figure


def _reduced_study_text(n: int = 4) -> str:
    """The shipped study on an n x n grid (the full 64 x 64 grid takes about a minute)."""
    text, count = re.subn(r"num = 64\b", f"num = {n}", STUDY.read_text())
    assert count == 2  # the gamma and F2_lateral ranges
    return text


def test_shipped_study_is_the_full_diagram():
    study = load_study(STUDY)
    assert study.figures == ("stability_diagram",) or list(study.figures) == ["stability_diagram"]
    assert list(study.laws) == ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"]
    # Ranges in the file: numpy.linspace's values exactly.
    np.testing.assert_array_equal(study.parameters["gamma"], np.linspace(0.1, 2.0, 64))
    np.testing.assert_array_equal(study.parameters["F2_lateral"], np.linspace(0.0, 0.8, 64))


@pytest.mark.slow
def test_shipped_study_runs_on_a_reduced_grid_and_draws(tmp_path, capsys):
    """What tests/test_cli_run.py does for the other studies, on a 3 x 3 grid."""
    study = tmp_path / "stability_diagram.toml"
    study.write_text(_reduced_study_text(3))
    output = tmp_path / "stability_diagram.nc"
    assert main(["run", str(study), "-o", str(output), "--quiet"]) == 0
    assert "FAILED" not in capsys.readouterr().out
    ds = open_study(output)
    assert ds["status"].dims == ("law", "gamma", "F2_lateral") and ds["status"].shape == (4, 3, 3)
    assert not np.char.startswith(ds["status"].values.astype(str), "failed").any()
    png = tmp_path / "stability_diagram_stability_diagram.png"
    image = mpimg.imread(png)
    assert image.shape[0] >= 600 and image.shape[1] >= 800
    rgb = image[..., :3].reshape(-1, 3)
    assert (rgb.sum(axis=1) < 2.5).mean() > 0.02
