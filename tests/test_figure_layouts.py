"""Figures that fit the sweep: curves, fans and parameter planes (ncstab.plotting).

The path figure kinds choose by the sweep's shape (up to 12 cases: a curve
each; more over two swept parameters: a field over the parameter plane; more
over one: a fan with its envelope).  Checked on synthetic path Datasets with
the archive's variables, built here from formulas, so that every drawn value
has an exact expected value: along each path u1* = 0.6 t, F1* = c u1* with
c = (law number) x (first swept parameter), alpha = pi/4 + 0.2 t; a limit
point located at t = 1/2 in the cases whose last swept parameter is above
its median.  Figures are checked as objects (artist counts, gids, drawn
arrays), rendered by Agg, never shown.
"""

from __future__ import annotations

import io
import math

import matplotlib

matplotlib.use("Agg")

import numpy as np
import pytest
import xarray as xr
from matplotlib.collections import LineCollection, PathCollection, QuadMesh
from matplotlib.legend import Legend

from ncstab.plotting import FIGURE_KINDS, draw_figures
from ncstab.plotting.fans import ENVELOPE_BINS, LABELLED_CASES, MAX_FAN_LINES, envelope
from ncstab.plotting.sweep_shape import MAX_CURVES, sweep_shape

ALPHA0 = math.pi / 4
STEPS = 9
#: Drawn arrays are the Dataset's values, or products of two of them: equal to rounding.
EXACT = 1e-12


def synthetic_sweep(sweep: dict[str, np.ndarray], laws: tuple[str, ...] = ("mcnamara",),
                    failed: tuple[tuple[int, ...], ...] = ()) -> xr.Dataset:
    """A path Dataset (the archive's variables) of straight paths, see the module docstring.

    ``failed`` cases (index tuples over (law, *sweep)) stop after 4 states with
    ``failed:max_steps``.
    """
    names = list(sweep)
    grids = np.meshgrid(*[np.asarray(v, float) for v in sweep.values()], indexing="ij")
    shape = (len(laws), *grids[0].shape)
    slope = np.arange(1, len(laws) + 1).reshape((-1,) + (1,) * len(names)) * grids[0]
    t = np.linspace(0.0, 1.0, STEPS)
    n_steps = np.full(shape, STEPS)
    status = np.full(shape, "finished", dtype=object)
    for index in failed:
        n_steps[index], status[index] = 4, "failed:max_steps"
    valid = np.arange(STEPS) < n_steps[..., None]
    u1 = np.where(valid, 0.6 * t, np.nan)
    F1 = slope[..., None] * u1
    u = np.stack([u1, -0.1 * (1 + grids[-1][..., None]) * u1], axis=-1)  # paths differ case by case
    F = np.stack([F1, np.where(valid, 0.0, np.nan)], axis=-1)
    step_dims = ["law", *names, "step"]
    located = np.broadcast_to(grids[-1] > np.median(grids[-1]), shape) & (n_steps == STEPS)
    at = np.where(located, 0.5, np.nan)
    K = np.where(located[..., None, None], np.array([[0.0, 0.0], [0.0, 1.0]]), np.nan)
    data = {
        "u": ([*step_dims, "dof"], u),
        "F": ([*step_dims, "dof"], F),
        "alpha": (step_dims, np.where(valid, ALPHA0 + 0.2 * t, np.nan)),
        "s": (step_dims, np.where(valid, t, np.nan)),
        "stage": (step_dims, np.where(valid, 0.0, np.nan)),
        "det_K": (step_dims, np.where(valid, 1.0 - t, np.nan)),
        "hill": (step_dims, np.where(valid, 0.5 - t, np.nan)),
        "d2W": (step_dims, np.where(valid, 1.0 - t, np.nan)),
        "n_steps": (step_dims[:-1], n_steps),
        "status": (step_dims[:-1], status.astype(str)),
        "limit_point_s": (step_dims[:-1], at),
        "limit_point_alpha": (step_dims[:-1], ALPHA0 + 0.2 * at),
        "limit_point_u": ([*step_dims[:-1], "dof"], np.stack([0.6 * at, -0.06 * at], axis=-1)),
        "limit_point_F": ([*step_dims[:-1], "dof"], np.stack([0.6 * at * slope, 0.0 * at], axis=-1)),
        "limit_point_K": ([*step_dims[:-1], "i", "j"], K),
    }
    coords = {"law": list(laws), "dof": [1, 2], **{n: np.asarray(v, float) for n, v in sweep.items()}}
    return xr.Dataset(data, coords=coords, attrs={"normal": "deformable", "parameter_alpha0": ALPHA0})


@pytest.fixture(autouse=True)
def no_best_legend_placement(monkeypatch):
    """No figure places a legend with loc="best" (it tests every artist: seconds for thousands)."""

    def refuse(*args, **kwargs):
        raise AssertionError('a legend was placed with loc="best"')

    monkeypatch.setattr(Legend, "_find_best_position", refuse)


def rendered(figure) -> None:
    """Draw the figure (Agg, into memory): legends are placed, everything is laid out."""
    figure.savefig(io.BytesIO(), format="png", dpi=40)


def paths(figure) -> list:
    return [line for axes in figure.axes for line in axes.get_lines() if (line.get_gid() or "").startswith("path:")]


# --- which figure ---------------------------------------------------------------------------------


@pytest.mark.parametrize(
    "sweep, laws, layout",
    [
        ({"gamma": [0.5]}, ("mcnamara",), "curves"),
        ({"gamma": [0.5, 2.0]}, ("mcnamara", "turco"), "curves"),
        ({"gamma": np.linspace(0.1, 2, 12)}, ("mcnamara",), "curves"),
        ({"gamma": np.linspace(0.1, 2, 13)}, ("mcnamara",), "fan"),
        ({"gamma": np.linspace(0.1, 2, 100)}, ("mcnamara",), "fan"),
        ({"gamma": [1.0], "F2_lateral": np.linspace(0, 0.8, 100)}, ("mcnamara",), "fan"),  # 1 x 100: 1-D
        ({"gamma": np.linspace(0.1, 2, 4), "F2_lateral": np.linspace(0, 0.8, 4)}, ("mcnamara",), "parameter_plane"),
        ({"gamma": np.linspace(0.1, 2, 64), "F2_lateral": np.linspace(0, 0.8, 64)}, ("mcnamara",), "parameter_plane"),
        ({"gamma": [0.5, 1], "F2_lateral": [0, 0.4], "alpha0": [0.5, 0.7, 0.9, 1.1]}, ("mcnamara",), "fan"),
    ],
)
def test_the_layout_follows_the_sweep_shape(sweep, laws, layout):
    shape = sweep_shape(synthetic_sweep(sweep, laws))
    assert shape.layout == layout
    assert shape.n_cases == len(laws) * math.prod(len(v) for v in sweep.values())
    assert (shape.n_cases <= MAX_CURVES) == (layout == "curves")


def test_one_case_is_one_curve_with_its_event():
    dataset = synthetic_sweep({"gamma": [0.5], "F2_lateral": [0.8]})
    figure = FIGURE_KINDS["load_displacement"](dataset)
    rendered(figure)
    (line,) = paths(figure)
    np.testing.assert_array_equal(line.get_xdata(), 0.6 * np.linspace(0, 1, STEPS))
    np.testing.assert_allclose(line.get_ydata(), 0.5 * 0.6 * np.linspace(0, 1, STEPS), rtol=0, atol=EXACT)
    events = [ln for ln in figure.axes[0].get_lines() if (ln.get_gid() or "").startswith("event:limit_point:")]
    assert len(events) == 0  # the limit point of this formula is in cases above the median only: none here


def test_four_cases_are_four_curves_and_their_events():
    dataset = synthetic_sweep({"gamma": [0.5, 2.0], "F2_lateral": [0.0, 0.8]})
    figure = FIGURE_KINDS["load_rotation"](dataset)
    rendered(figure)
    lines = paths(figure)
    assert len(lines) == 4
    assert not any(isinstance(c, (LineCollection, QuadMesh)) for c in figure.axes[0].collections)
    # Limit points located where F2_lateral = 0.8 (above the median): 2 markers, at alpha(1/2), F1 = 0.3 c.
    markers = [ln for ln in figure.axes[0].get_lines() if (ln.get_gid() or "").startswith("event:limit_point:")]
    assert sorted((m.get_xdata()[0], m.get_ydata()[0]) for m in markers) == [
        (ALPHA0 + 0.1, 0.3 * 0.5), (ALPHA0 + 0.1, 0.3 * 2.0)]
    legends = [a.get_legend() for a in figure.axes if a.get_legend()] + list(figure.legends)
    (legend,) = legends
    texts = [text.get_text() for text in legend.get_texts()]
    assert texts[:4] == [r"$\gamma$ = 0.5, $F_2^*$ = 0", r"$\gamma$ = 0.5, $F_2^*$ = 0.8",
                         r"$\gamma$ = 2, $F_2^*$ = 0", r"$\gamma$ = 2, $F_2^*$ = 0.8"]
    assert "limit point (det K = 0)" in texts


# --- a 1-D sweep of 100: the fan ------------------------------------------------------------------


@pytest.fixture(scope="module")
def fan_dataset() -> xr.Dataset:
    return synthetic_sweep({"gamma": np.linspace(0.1, 2.0, 100)}, failed=((0, 3),))


def test_a_sweep_of_100_is_a_fan_with_its_envelope_and_five_labelled_cases(fan_dataset):
    figure = FIGURE_KINDS["load_displacement"](fan_dataset)
    rendered(figure)
    (axes,) = [a for a in figure.axes if a.get_gid() != "colorbar" and a.collections]
    (fan,) = [c for c in axes.collections if c.get_gid() == "fan:mcnamara"]
    assert isinstance(fan, LineCollection) and fan.get_rasterized()
    segments = fan.get_segments()
    assert len(segments) == 100  # under MAX_FAN_LINES: every path
    gamma = np.linspace(0.1, 2.0, 100)
    for k in (0, 3, 57):
        n = 4 if k == 3 else STEPS  # the failed case keeps its 4 states
        x, y = segments[k][:, 0], segments[k][:, 1]
        np.testing.assert_array_equal(x[:n], 0.6 * np.linspace(0, 1, STEPS)[:n])
        np.testing.assert_allclose(y[:n], gamma[k] * x[:n], rtol=0, atol=EXACT)
        assert np.isnan(x[n:]).all()  # the rest of the padded path is not drawn
    # The envelope of the straight lines F1 = gamma u1: gamma_min u1 and gamma_max u1 at each grid value.
    bounds = [ln for ln in axes.get_lines() if ln.get_gid() == "envelope_line:mcnamara"]
    assert len(bounds) == 2
    lower, upper = bounds
    grid = np.asarray(lower.get_xdata())
    assert grid.size == ENVELOPE_BINS and grid[0] == 0.0 and grid[-1] == pytest.approx(0.6, abs=EXACT)
    np.testing.assert_allclose(lower.get_ydata(), 0.1 * grid, rtol=0, atol=EXACT)
    np.testing.assert_allclose(upper.get_ydata(), 2.0 * grid, rtol=0, atol=EXACT)
    labelled = [ln.get_gid() for ln in axes.get_lines() if (ln.get_gid() or "").startswith("path:")]
    assert labelled == [r"path:$\gamma$ = 0.1", r"path:$\gamma$ = 0.5798", r"path:$\gamma$ = 1.06",
                        r"path:$\gamma$ = 1.52", r"path:$\gamma$ = 2"]
    assert len(labelled) == LABELLED_CASES
    # Limit points: the cases above the median of the (only) swept parameter, one scatter.
    (points,) = [c for c in axes.collections if c.get_gid() == "events:limit_point:mcnamara"]
    offsets = points.get_offsets()
    above = gamma > np.median(gamma)
    assert len(offsets) == int(above.sum())
    np.testing.assert_allclose(offsets[:, 1], 0.3 * gamma[above], rtol=0, atol=EXACT)
    assert [a.get_gid() for a in figure.axes].count("colorbar") == 1
    (legend,) = figure.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert "envelope of all 100 paths per law" in texts and "limit point (det K = 0)" in texts
    assert any("failed cases (1;" in t for t in texts)


def test_a_fan_draws_at_most_max_fan_lines_paths_but_envelopes_them_all():
    n = MAX_FAN_LINES + 904  # 5,000 cases: every second path drawn
    gamma = np.linspace(0.1, 2.0, n)
    figure = FIGURE_KINDS["load_rotation"](synthetic_sweep({"gamma": gamma}))
    axes = next(a for a in figure.axes if any(c.get_gid() == "fan:mcnamara" for c in a.collections))
    (fan,) = [c for c in axes.collections if c.get_gid() == "fan:mcnamara"]
    assert len(fan.get_segments()) == math.ceil(n / 2) <= MAX_FAN_LINES
    lower, upper = [ln for ln in axes.get_lines() if ln.get_gid() == "envelope_line:mcnamara"]
    grid = np.asarray(upper.get_xdata())  # alpha; the extreme cases are both drawn and enveloped
    t = (grid - ALPHA0) / 0.2
    np.testing.assert_allclose(upper.get_ydata(), gamma[-1] * 0.6 * t, rtol=0, atol=1e-10)
    np.testing.assert_allclose(lower.get_ydata(), gamma[0] * 0.6 * t, rtol=0, atol=1e-10)


def test_the_stability_fan_has_three_rows_per_law_and_breaks_nothing(fan_dataset):
    dataset = xr.concat([fan_dataset, fan_dataset.assign_coords(law=["turco"])], "law")
    figure = FIGURE_KINDS["stability"](dataset)
    rendered(figure)
    fans = [c for a in figure.axes for c in a.collections if (c.get_gid() or "").startswith("fan:")]
    assert sorted(c.get_gid() for c in fans) == ["fan:mcnamara"] * 3 + ["fan:turco"] * 3


def test_envelope_of_a_path_turning_back_and_of_a_segment_along_y():
    # x goes 0 -> 1 -> 0.5: at x = 0.5 the path has the values 0.5 (going) and 2 (back).
    grid, lower, upper = envelope(np.array([[0.0, 1.0, 0.5]]), np.array([[0.0, 1.0, 2.0]]), bins=3)
    np.testing.assert_array_equal(grid, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(lower, [0.0, 0.5, 1.0])
    np.testing.assert_array_equal(upper, [0.0, 2.0, 1.0])
    # A segment along y at x = 1 (from 1 to 3): both ends count at x = 1.
    grid, lower, upper = envelope(np.array([[0.0, 1.0, 1.0, np.nan]]), np.array([[0.0, 1.0, 3.0, np.nan]]), bins=3)
    np.testing.assert_array_equal(upper, [0.0, 0.5, 3.0])


# --- a 2-D sweep of 64 x 64: the parameter plane --------------------------------------------------


@pytest.fixture(scope="module")
def plane_dataset() -> xr.Dataset:
    sweep = {"gamma": np.linspace(0.1, 2.0, 64), "F2_lateral": np.linspace(0.0, 0.8, 64)}
    return synthetic_sweep(sweep, laws=("cundall_strack", "mcnamara"), failed=((0, 5, 7), (1, 0, 0), (1, 1, 0)))


def test_a_64_by_64_sweep_is_a_field_over_the_parameter_plane(plane_dataset):
    figure = FIGURE_KINDS["load_displacement"](plane_dataset)
    rendered(figure)
    panels = {a.get_gid(): a for a in figure.axes if str(a.get_gid()).startswith("plane:")}
    assert sorted(panels) == sorted(f"plane:{c}:{law}" for c in ("end", "limit_point")
                                    for law in ("cundall_strack", "mcnamara"))
    assert sorted(a.get_gid() for a in figure.axes if str(a.get_gid()).startswith("colorbar:")) == [
        "colorbar:end", "colorbar:limit_point"]
    assert not paths(figure)  # no curves at all
    gamma, lateral = np.meshgrid(np.linspace(0.1, 2.0, 64), np.linspace(0.0, 0.8, 64))  # (y, x) = (F2, gamma)
    for number, law in enumerate(("cundall_strack", "mcnamara"), start=1):
        (end,) = [c for c in panels[f"plane:end:{law}"].collections if isinstance(c, QuadMesh)]
        field = np.ma.filled(end.get_array(), np.nan).reshape(64, 64)
        failed = np.zeros((64, 64), bool)
        if law == "cundall_strack":
            failed[7, 5] = True  # (F2 index, gamma index)
        else:
            failed[0, 0] = failed[0, 1] = True
        # End of the path: F1* = 0.6 c; a failed case ends after 4 of 9 states: 0.6 c 3/8.
        expected = np.where(failed, 0.6 * 3 / 8, 0.6) * number * gamma
        np.testing.assert_allclose(field, expected, rtol=0, atol=EXACT)
        (limit,) = [c for c in panels[f"plane:limit_point:{law}"].collections if isinstance(c, QuadMesh)]
        field = np.ma.filled(limit.get_array(), np.nan).reshape(64, 64)
        reached = (lateral > np.median(lateral)) & ~failed
        np.testing.assert_allclose(field[reached], 0.3 * number * gamma[reached], rtol=0, atol=EXACT)
        assert np.isnan(field[~reached]).all()  # light grey: not located
        assert limit.get_rasterized()
        # Failed cases cross-hatched: one compound path, one closed run per row of failed cells.
        (hatched,) = [c for c in panels[f"plane:end:{law}"].collections if c.get_gid() == f"failed:{law}"]
        assert isinstance(hatched, PathCollection) and hatched.get_hatch() == "xxx"
        (compound,) = hatched.get_paths()
        assert len(compound.to_polygons()) == 1


def test_a_plane_of_rotations_and_the_stability_diagram(plane_dataset):
    figure = FIGURE_KINDS["load_rotation"](plane_dataset)
    panel = next(a for a in figure.axes if a.get_gid() == "plane:limit_point:mcnamara")
    (mesh,) = [c for c in panel.collections if isinstance(c, QuadMesh)]
    values = np.ma.filled(mesh.get_array(), np.nan)
    np.testing.assert_allclose(values[np.isfinite(values)], ALPHA0 + 0.1, rtol=0, atol=EXACT)
    figure = FIGURE_KINDS["stability"](plane_dataset)
    assert any(str(a.get_gid()).startswith("diagram:limit_point:") for a in figure.axes)


def test_every_layout_is_drawn_to_png_files(plane_dataset, fan_dataset, tmp_path):
    for name, dataset in (("plane", plane_dataset), ("fan", fan_dataset)):
        dataset = dataset.assign_attrs(study_name=name)
        ticks = []
        written = draw_figures(dataset, tmp_path, kinds=list(FIGURE_KINDS)[:4], dpi=30,
                               progress=lambda done, total, path: ticks.append((done, total, path.name)))
        assert [p.name for p in written] == [f"{name}_{k}.png" for k in list(FIGURE_KINDS)[:4]]
        assert ticks == [(k + 1, 4, p.name) for k, p in enumerate(written)]  # one tick per figure
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(
        f"{n}_{k}.png" for n in ("plane", "fan") for k in list(FIGURE_KINDS)[:4])


def test_progress_true_shows_a_bar_of_figures_on_standard_error(fan_dataset, tmp_path, capsys):
    draw_figures(fan_dataset, tmp_path, kinds="load_rotation,load_displacement", dpi=20, progress=True)
    captured = capsys.readouterr()
    assert captured.out == ""
    assert "figures" in captured.err and "2/2" in captured.err


def test_an_archive_without_an_event_table_is_drawn_as_never_located(plane_dataset):
    """A lean archive leaves out the tables of events that never occur."""
    lean = plane_dataset.drop_vars([name for name in plane_dataset.data_vars if name.startswith("limit_point_")])
    figure = FIGURE_KINDS["load_displacement"](lean)
    assert sorted(a.get_gid() for a in figure.axes if str(a.get_gid()).startswith("plane:")) == [
        "plane:end:cundall_strack", "plane:end:mcnamara"]
    figure = FIGURE_KINDS["stability"](lean)
    panel = next(a for a in figure.axes if a.get_gid() == "diagram:limit_point:mcnamara")
    (mesh,) = [c for c in panel.collections if isinstance(c, QuadMesh)]
    assert np.ma.getmaskarray(mesh.get_array()).all()  # light grey everywhere: never located
    rendered(figure)
