"""Stability boundaries as curves (issue 40) against closed forms and located events."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.optimize import brentq

from ncstab.boundaries import BoundaryError, boundary


def hurwitz_flutter_load(b1: float, b2: float) -> float:
    """The follower load where H3 = a1 a2 a3 - a1^2 a4 - a0 a3^2 of Ziegler's characteristic
    polynomial 2 s^4 + (b1 + 6 b2) s^3 + (7 - 2P + b1 b2) s^2 + (b1 + b2) s + 1 vanishes.

    Written here independently of ncstab (Routh-Hurwitz for a quartic, a0 s^4 + ... + a4):
    H3 is linear in a2 = 7 - 2P + b1 b2, so P has a closed form; brentq confirms it.
    """
    a0, a1, a3, a4 = 2.0, b1 + 6.0 * b2, b1 + b2, 1.0

    def h3(P: float) -> float:
        a2 = 7.0 - 2.0 * P + b1 * b2
        return a1 * a2 * a3 - a1**2 * a4 - a0 * a3**2

    a2 = (a1**2 * a4 + a0 * a3**2) / (a1 * a3)
    closed = (7.0 + b1 * b2 - a2) / 2.0
    root = brentq(h3, closed - 1.0, closed + 1.0, xtol=1e-15, rtol=1e-15)
    assert abs(root - closed) <= 1e-12 * abs(closed)
    return closed


@pytest.mark.parametrize("along, fixed", [("b1", {"b2": 0.1}), ("b2", {"b1": 0.1})])
def test_ziegler_flutter_boundary_matches_routh_hurwitz(along, fixed):
    # Tolerance 1e-8 relative: the corrector converges to |G| <= 1e-11 and the
    # flutter load is a well-conditioned root of the extended system (omega ~ 1).
    parameters = {**fixed, along: 0.01}
    result = boundary("ziegler", None, [{"drive": {"P": 3.0}}], parameters,
                      event="flutter_onset", parameter=along, start=0.01, stop=1.0)
    count = int(result.n_points.values.ravel()[0])
    values = result[f"boundary_{along}"].values.reshape(-1)[:count]
    loads = result.boundary_load.values.reshape(-1)[:count]
    assert result.status.values.ravel()[0] == "finished"
    assert count >= 20
    assert values[0] == pytest.approx(0.01, abs=1e-12) and values[-1] == pytest.approx(1.0, abs=1e-12)
    assert np.max(np.diff(values)) < 0.1  # the points cover the range
    b1 = values if along == "b1" else np.full(count, fixed["b1"])
    b2 = values if along == "b2" else np.full(count, fixed["b2"])
    expected = np.array([hurwitz_flutter_load(x, y) for x, y in zip(b1, b2)])
    assert np.max(np.abs(loads - expected) / expected) < 1e-8
    notes = result.boundary_note.values.reshape(-1)
    assert notes[0] == "start" and notes[count - 1] == "end"


def test_curve_family_over_a_sweep():
    result = boundary("ziegler", None, [{"drive": {"P": 3.0}}], {"b1": 0.01, "b2": [0.05, 0.2]},
                      event="flutter_onset", parameter="b1", start=0.01, stop=0.5)
    assert result.boundary_load.dims == ("law", "b2", "point")
    for k, b2 in enumerate([0.05, 0.2]):
        count = int(result.n_points.values[0, k])
        b1 = result.boundary_b1.values[0, k, :count]
        loads = result.boundary_load.values[0, k, :count]
        expected = np.array([hurwitz_flutter_load(x, b2) for x in b1])
        assert np.max(np.abs(loads - expected) / expected) < 1e-8
    for name in result.variables:
        attrs = result[name].attrs
        if name not in result.dims:
            assert {"units", "long_name", "description"} <= set(attrs), name


@pytest.mark.parametrize("field, kwargs", [
    ("boundary.event", {"event": "limit_point"}),  # det K = 1 under a follower load
    ("boundary.event", {"event": "no_such_event"}),
    ("boundary.parameter", {"parameter": "b3"}),
    ("boundary.stop", {"stop": 0.01}),
])
def test_bad_boundaries_name_their_field(field, kwargs):
    arguments = {"event": "flutter_onset", "parameter": "b1", "start": 0.01, "stop": 1.0, **kwargs}
    with pytest.raises(BoundaryError) as error:
        boundary("ziegler", None, [{"drive": {"P": 3.0}}], {"b1": 0.01, "b2": 0.1}, **arguments)
    assert error.value.field == field


DIAMOND = """
[study]
name = "diamond_limit_boundary"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara"]
[parameters]
gamma = {gamma}
F2_lateral = 0.75
[[loading]]
hold = {{ F1 = 0.0 }}
drive = {{ F2 = "F2_lateral" }}
[[loading]]
hold = {{ F2 = "current" }}
drive = {{ D1 = 0.6 }}
"""


def test_diamond_limit_point_boundary_matches_the_located_events_of_a_sweep():
    # The boundary (det K = 0 continued in gamma, F2* = 0.75 held) against an ordinary
    # study sweeping gamma at the curve's own values: both locate det K = 0 on the same
    # equilibrium set, the engine by root finding along each path (event_tol), the
    # boundary by Newton on the extended system; 1e-8 is far above either tolerance.
    from ncstab.studies import parse_study, run_study

    text = DIAMOND.format(gamma=0.4) + '[boundary]\nevent = "limit_point"\nparameter = "gamma"\nstart = 0.4\nstop = 0.5\n'
    curve = run_study(parse_study(text))
    count = int(curve.n_points.values.ravel()[0])
    assert curve.status.values.ravel()[0] == "finished" and count >= 20
    gamma = curve.boundary_gamma.values.ravel()[:count]
    assert gamma[0] == pytest.approx(0.4) and gamma[-1] == pytest.approx(0.5)
    sweep = run_study(parse_study(DIAMOND.format(gamma="[" + ", ".join(repr(float(g)) for g in gamma) + "]")))
    located_u = sweep.limit_point_u.values.reshape(count, 2)
    located_F = sweep.limit_point_F.values.reshape(count, 2)
    assert np.max(np.abs(curve.boundary_u.values.reshape(-1, 2)[:count] - located_u)) < 1e-8
    assert np.max(np.abs(curve.boundary_F.values.reshape(-1, 2)[:count] - located_F) / np.abs(located_F)) < 1e-8
    assert np.allclose(curve.boundary_F.values.reshape(-1, 2)[:count, 1], 0.75, atol=1e-10)  # F2 held


def test_diamond_boundary_reports_its_fold():
    # Past gamma ~ 0.518 the path meets no limit point before D1* = 0.6: the curve turns back.
    result = boundary("diamond", ["mcnamara"], [{"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
                                                {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}],
                      {"gamma": 0.4, "F2_lateral": 0.75}, event="limit_point", parameter="gamma",
                      start=0.4, stop=1.0, secondary_contacts="ignore")
    count = int(result.n_points.values.ravel()[0])
    notes = list(result.boundary_note.values.ravel()[:count])
    gamma = result.boundary_gamma.values.ravel()[:count]
    fold = notes.index("fold")
    assert 0.5 < gamma[fold] < 0.53 and gamma[fold] == pytest.approx(gamma.max(), abs=1e-3)
    assert "boundary_load" not in result and result.boundary_u.dims[-1] == "dof"


def test_hill_loss_boundary_of_a_hyperelastic_law_meets_its_limit_point():
    # Seed Eq. (41): K is symmetric on the path of a hyperelastic law, so Hill's
    # condition and det K are lost at the same state: the two boundaries coincide.
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
    kwargs = {"parameter": "gamma", "start": 0.4, "stop": 0.45, "secondary_contacts": "ignore"}
    hill = boundary("diamond", ["mcnamara"], programme, {"gamma": 0.4, "F2_lateral": 0.75}, event="hill_loss", **kwargs)
    limit = boundary("diamond", ["mcnamara"], programme, {"gamma": 0.4, "F2_lateral": 0.75}, event="limit_point", **kwargs)
    for result in (hill, limit):
        assert result.status.values.ravel()[0] == "finished"
    end_hill = hill.boundary_u.values.reshape(-1, 2)[int(hill.n_points.values.ravel()[0]) - 1]
    end_limit = limit.boundary_u.values.reshape(-1, 2)[int(limit.n_points.values.ravel()[0]) - 1]
    assert np.max(np.abs(end_hill - end_limit)) < 1e-8


ZIEGLER_STUDY = """
[study]
name = "bad_boundary"
[system]
name = "ziegler"
[parameters]
b1 = 0.1
b2 = 0.1
[[loading]]
drive = {{ P = 3.0 }}
[boundary]
{boundary}
"""


@pytest.mark.parametrize("table, field", [
    ('event = "limit_point"\nparameter = "b1"\nstart = 0.01\nstop = 1.0', "boundary.event"),
    ('event = "flutter_onset"\nparameter = "b3"\nstart = 0.01\nstop = 1.0', "boundary.parameter"),
    ('event = "flutter_onset"\nparameter = "b1"\nstart = 0.5\nstop = 0.5', "boundary.stop"),
    ('event = "flutter"\nparameter = "b1"\nstart = 0.1\nstop = 0.5', "boundary.event"),
])
def test_bad_boundary_sections_exit_2_naming_the_field(tmp_path, table, field):
    from ncstab.cli import main

    study = tmp_path / "bad.toml"
    study.write_text(ZIEGLER_STUDY.format(boundary=table))
    output = tmp_path / "bad.nc"
    import contextlib
    import io

    errors = io.StringIO()
    with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
        code = main(["run", str(study), "-o", str(output)])
    assert code == 2 and field in errors.getvalue() and not output.exists()


def test_rate_form_boundary_is_shot_along_paths():
    # Cundall-Strack is hypoelastic: its state at det K = 0 depends on the loading history,
    # so each point is the event located on a whole path; the curve then agrees with an
    # ordinary sweep at its own gamma values to rounding, and its ends are the edges where
    # the paths stop meeting a limit point before D1* = 0.6 (bisected to 1e-4 in gamma).
    from ncstab.studies import parse_study, run_study

    text = DIAMOND.replace("mcnamara", "cundall_strack").replace("F2_lateral = 0.75", "F2_lateral = 0.8")
    curve = run_study(parse_study(text.format(gamma=0.5) + '[boundary]\nevent = "limit_point"\nparameter = "gamma"\nstart = 0.5\nstop = 0.9\n'))
    count = int(curve.n_points.values.ravel()[0])
    assert curve.status.values.ravel()[0] == "finished" and count >= 20
    gamma = curve.boundary_gamma.values.ravel()[:count]
    notes = curve.boundary_note.values.ravel()[:count]
    assert notes[0] == "edge" and notes[-1] == "edge" and 0.5 < gamma[0] < gamma[-1] < 0.9
    sweep = run_study(parse_study(text.format(gamma="[" + ", ".join(repr(float(g)) for g in gamma) + "]")))
    located = sweep.limit_point_F.values.reshape(count, 2)
    assert np.max(np.abs(curve.boundary_F.values.reshape(-1, 2)[:count] - located)) < 1e-12


def test_shipped_study_runs_writes_and_draws(tmp_path):
    import xarray as xr

    from ncstab.plotting import draw_figures
    from ncstab.studies import load_study, open_study, run_study, write_dataset

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    study = load_study(root / "studies" / "ziegler_flutter_boundary.toml")
    dataset = run_study(study)
    write_dataset(dataset, tmp_path / "z.nc")
    xr.testing.assert_identical(open_study(tmp_path / "z.nc"), dataset)
    (written,) = draw_figures(dataset, tmp_path)
    assert written.name == "ziegler_flutter_boundary_boundary.png" and written.stat().st_size > 10_000
    for k, b2 in enumerate(dataset.b2.values):
        count = int(dataset.n_points.values[0, k])
        b1 = dataset.boundary_b1.values[0, k, :count]
        expected = np.array([hurwitz_flutter_load(x, b2) for x in b1])
        assert np.max(np.abs(dataset.boundary_load.values[0, k, :count] / expected - 1)) < 1e-8


def test_boundary_over_the_pixel_diagram(tmp_path):
    from matplotlib.figure import Figure

    import ncstab
    from ncstab.plotting.boundaries import boundary_over_diagram_figure

    curve = boundary("ziegler", None, [{"drive": {"P": 3.0}}], {"b1": 0.05, "b2": [0.1]},
                     event="flutter_onset", parameter="b1", start=0.05, stop=0.5)
    grid = ncstab.follow("ziegler", None, [{"drive": {"P": 2.5}, "stop_at": ["flutter_onset"]}],
                         {"b1": list(np.linspace(0.05, 0.5, 8)), "b2": [0.1]}).to_dataset()
    figure = boundary_over_diagram_figure(curve, grid, Figure())
    axes = figure.axes[0]
    assert len(axes.lines) == 2  # the curve and the cells of the sweep
    figure.savefig(tmp_path / "over.png")
    assert (tmp_path / "over.png").stat().st_size > 5_000


@pytest.mark.parametrize("load, event, expected", [
    # follower: K_sym = [[2 - P, (P - 2)/2], [(P - 2)/2, 1]] is singular at P = 2 whatever the damping
    ("follower", "hill_loss", 2.0),
    # dead load: det K = P^2 - 3P + 1 = 0 at P = (3 - sqrt 5)/2 (Ziegler's divergence load);
    # on the trivial path it is a root s = 0 of M s^2 + C s + K and a bifurcation of the load stage
    ("dead", "divergence", (3.0 - np.sqrt(5.0)) / 2.0),
    ("dead", "bifurcation", (3.0 - np.sqrt(5.0)) / 2.0),
    ("dead", "hill_loss", (3.0 - np.sqrt(5.0)) / 2.0),  # K symmetric under a dead load
])
def test_static_boundaries_of_ziegler_are_independent_of_the_damping(load, event, expected):
    from ncstab.paths.options import SystemSpec

    result = boundary(SystemSpec("ziegler", load=load), None, [{"drive": {"P": 3.0}}], {"b1": 0.1, "b2": 0.1},
                      event=event, parameter="b1", start=0.1, stop=0.5)
    count = int(result.n_points.values.ravel()[0])
    assert result.status.values.ravel()[0] == "finished" and count >= 20
    assert np.max(np.abs(result.boundary_load.values.ravel()[:count] - expected)) < 1e-10
    assert np.max(np.abs(result.boundary_u.values.reshape(-1, 2)[:count])) < 1e-10  # the trivial state


def test_a_boundary_study_is_not_run_in_chunks(tmp_path):
    import contextlib
    import io

    from ncstab.cli import main

    root = __import__("pathlib").Path(__file__).resolve().parents[1]
    errors = io.StringIO()
    with contextlib.redirect_stderr(errors), contextlib.redirect_stdout(io.StringIO()):
        code = main(["run", str(root / "studies" / "ziegler_flutter_boundary.toml"), "-o", str(tmp_path / "z.nc"), "--workers", "2"])
    assert code == 2 and "[boundary]" in errors.getvalue() and not (tmp_path / "z.nc").exists()


def test_a_curve_starts_where_the_event_is_first_met_and_follows_its_folds():
    # No limit point before D1* = 0.6 for gamma < 0.34 at F2* = 0.75: the curve starts at the
    # first of 40 sampled gamma where a path meets one, and is followed through both folds.
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
    result = boundary("diamond", ["mcnamara"], programme, {"gamma": 0.3, "F2_lateral": 0.75}, event="limit_point",
                      parameter="gamma", start=0.1, stop=0.5, secondary_contacts="ignore")
    count = int(result.n_points.values.ravel()[0])
    notes = list(result.boundary_note.values.ravel()[:count])
    gamma = result.boundary_gamma.values.ravel()[:count]
    assert notes[0].startswith("start: no limit_point") and gamma[0] == pytest.approx(0.34)
    assert notes.count("fold") == 2 and notes[-1] == "end" and gamma[-1] == pytest.approx(0.5)


def test_each_law_of_a_study_has_its_own_curve():
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
    kwargs = {"event": "limit_point", "parameter": "gamma", "start": 0.5, "stop": 0.9, "secondary_contacts": "ignore"}
    both = boundary("diamond", ["mcnamara", "cundall_strack"], programme, {"gamma": 0.5, "F2_lateral": 0.8}, **kwargs)
    for k, law in enumerate(["mcnamara", "cundall_strack"]):
        alone = boundary("diamond", [law], programme, {"gamma": 0.5, "F2_lateral": 0.8}, **kwargs)
        assert both.status.values[k] == alone.status.values[0]
        count = int(alone.n_points.values[0])
        assert int(both.n_points.values[k]) == count
        np.testing.assert_array_equal(both.boundary_F.values[k, :count], alone.boundary_F.values[0, :count])
    assert both.status.values[1] == "finished" and both.n_points.values[1] >= 20
