"""Figures of path Datasets (ncstab.plotting): files and what is drawn in them.

Figures are checked as objects (curves per case, axis labels, legend texts,
event markers at the located coordinates, closed-form overlays equal to the
seed's formulas) and as PNG files (size, not blank, many colours, written
atomically).  Nothing is shown: the figures are plain matplotlib Figures,
rendered by the Agg canvas.
"""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")

import matplotlib.image as mpimg
import matplotlib.pyplot as plt
import numpy as np
import pytest
import xarray as xr
from matplotlib.colors import to_rgba
from matplotlib.figure import Figure

from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.plotting import (
    FIGURE_KINDS,
    draw_figures,
    plot_load_displacement,
    plot_load_displacement_rotation,
    plot_load_rotation,
    plot_stability,
)
from mpl_toolkits.mplot3d import proj3d

from ncstab.plotting.curves import BRANCH_COLOURS
from ncstab.plotting.curves_3d import VIEW
from ncstab.plotting.stability_curves import D2W_EXPLANATION
from ncstab.plotting.style import case_colours, format_parameter, law_display_name, symbolic_text
from ncstab.systems.closed_forms import (
    diamond_displacements,
    mcnamara_branch_length,
    mcnamara_load_rotation,
    pure_shear_blocking_alpha,
    pure_shear_load_rotation,
)

ALPHA0 = np.pi / 4
KINDS = ["load_rotation", "load_displacement", "load_displacement_rotation", "stability"]
#: Coarser steps than the default: the figures need tens of states, not hundreds.
OPTIONS = PathOptions(max_step=0.05)
#: Closed-form overlays are evaluated by the same numpy expressions as the
#: reference here: equal to rounding.
OVERLAY_TOL = 1e-12


# --- datasets, each followed once (about 6 s in all) ----------------------------------------


@pytest.fixture(scope="module")
def uniaxial() -> xr.Dataset:
    """F2 = 0, Delta_1* driven to 0.3: hyperelastic and hypoelastic, gamma in {0.5, 2}."""
    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        ["mcnamara", "cundall_strack"],
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.3}}],
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0},
        OPTIONS,
    )
    return path.to_dataset()


@pytest.fixture(scope="module")
def preloaded() -> xr.Dataset:
    """Lateral preload F2* = 0.75, then Delta_1* driven with F2 held: a limit point (seed Fig. 9-11)."""
    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        ["mcnamara"],
        [
            {"hold": {"F1": 0.0}, "drive": {"F2": 0.75}},
            {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
        ],
        {"gamma": 0.5, "alpha0": ALPHA0},
        OPTIONS,
    )
    return path.to_dataset()


@pytest.fixture(scope="module")
def rigid() -> xr.Dataset:
    """Pure-shear limit, F1 driven to 1 (2R k_t): blocked at the secondary contact (seed Figs. 14-15)."""
    path = follow(
        SystemSpec(normal="rigid"),
        ["mcnamara", "turco"],
        [{"hold": {"F2": 0.0}, "drive": {"F1": 1.0}}],
        {"alpha0": ALPHA0},
        OPTIONS,
    )
    return path.to_dataset()


@pytest.fixture(scope="module")
def fold() -> xr.Dataset:
    """Seed Figs. 3-5: McNamara, gamma = 2, F2 = 0, Delta_1* driven to 0.5, past the maximum of alpha."""
    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        ["mcnamara"],
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.5}}],
        {"gamma": 2.0, "alpha0": ALPHA0},
        OPTIONS,
    )
    return path.to_dataset()


@pytest.fixture(scope="module")
def pure_shear() -> xr.Dataset:
    """Seed Figs. 14-15 with the two laws whose pure-shear limit is the same (seed Eq. 60)."""
    path = follow(
        SystemSpec(normal="rigid"),
        ["cundall_strack", "mcnamara"],
        [{"hold": {"F2": 0.0}, "drive": {"F1": 1.0}}],
        {"alpha0": ALPHA0},
        OPTIONS,
    )
    return path.to_dataset()


@pytest.fixture(autouse=True)
def no_pyplot_figures():
    """No test leaves a pyplot figure behind (the figures are not pyplot figures at all)."""
    yield
    assert plt.get_fignums() == []


# --- helpers --------------------------------------------------------------------------------


def lines_with(axes, prefix: str) -> list:
    """Line2D artists of axes whose gid starts with prefix."""
    return [line for line in axes.get_lines() if (line.get_gid() or "").startswith(prefix)]


def legend_texts(figure: Figure) -> list[str]:
    legends = [a.get_legend() for a in figure.axes if a.get_legend() is not None] + list(
        figure.legends
    )
    assert len(legends) == 1
    return [text.get_text() for text in legends[0].get_texts()]


def case_data(dataset: xr.Dataset, law: str, **coords) -> xr.Dataset:
    case = dataset.sel(law=law, **coords)
    return case.isel(step=slice(0, int(case["n_steps"])))


# --- registry and files ---------------------------------------------------------------------


def test_registry_names_the_four_path_kinds():
    assert list(FIGURE_KINDS)[:4] == KINDS
    assert FIGURE_KINDS["load_rotation"] is plot_load_rotation
    assert FIGURE_KINDS["stability"] is plot_stability


@pytest.mark.parametrize("name", ["uniaxial", "preloaded", "rigid"])
def test_every_kind_is_written_as_a_png_with_content(name, request, tmp_path):
    dataset = request.getfixturevalue(name)
    dpi = 60
    written = draw_figures(dataset, tmp_path / "figures", kinds=KINDS, stem=name, dpi=dpi)
    assert written == [tmp_path / "figures" / f"{name}_{kind}.png" for kind in KINDS]
    # Only the PNGs: no temporary file is left beside them.
    assert sorted(p.name for p in (tmp_path / "figures").iterdir()) == sorted(
        p.name for p in written
    )
    for path in written:
        image = mpimg.imread(path)
        height = 6.6 if path.stem.endswith("_stability") else 4.8  # three stacked panels: taller
        assert image.shape[:2] == (round(height * dpi), round(6.4 * dpi))
        rgb = image[..., :3]
        # Not blank: a white page with a few lines has a small deviation;
        # curves, text and grid of a figure give well above 0.05, and many colours.
        assert rgb.std() > 0.05
        colours = np.unique((rgb.reshape(-1, 3) * 255).astype(np.uint8), axis=0)
        assert len(colours) > 50


def test_kinds_default_to_the_dataset_attribute_then_to_two(uniaxial, tmp_path):
    dataset = uniaxial.copy()
    dataset.attrs = {**uniaxial.attrs, "figures": "stability, load_rotation", "study_name": "fig06"}
    written = draw_figures(dataset, tmp_path, dpi=30)
    assert [p.name for p in written] == ["fig06_stability.png", "fig06_load_rotation.png"]
    dataset.attrs = {k: v for k, v in uniaxial.attrs.items() if k not in ("figures", "study_name")}
    written = draw_figures(dataset, tmp_path / "new" / "dir", dpi=30)
    assert [p.name for p in written] == ["ncstab_load_displacement.png", "ncstab_load_rotation.png"]
    assert all(p.exists() for p in written)


def test_unknown_kind_is_rejected_before_anything_is_drawn(uniaxial, tmp_path):
    with pytest.raises(ValueError, match="'bode_plot'") as error:
        draw_figures(uniaxial, tmp_path, kinds=["load_rotation", "bode_plot"])
    for kind in KINDS:
        assert kind in str(error.value)
    assert list(tmp_path.iterdir()) == []


def test_a_failing_save_leaves_no_file_behind(uniaxial, tmp_path, monkeypatch):
    def broken(self, *args, **kwargs):
        raise OSError("disk full")

    monkeypatch.setattr(Figure, "savefig", broken)
    with pytest.raises(OSError, match="disk full"):
        draw_figures(uniaxial, tmp_path, kinds="load_rotation")
    assert list(tmp_path.iterdir()) == []


def test_an_archive_read_back_from_netcdf_is_drawn(rigid, tmp_path):
    rigid.to_netcdf(tmp_path / "rigid.nc")
    with xr.open_dataset(tmp_path / "rigid.nc") as dataset:
        written = draw_figures(dataset, tmp_path, kinds="load_rotation,load_displacement", dpi=30)
    assert all(p.exists() for p in written)


# --- load-rotation: curves, labels, legend, closed forms ------------------------------------


def test_load_rotation_draws_one_curve_per_case_with_its_valid_steps(uniaxial):
    figure = plot_load_rotation(uniaxial)
    axes = figure.axes[0]
    paths = lines_with(axes, "path:")
    assert len(paths) == 4  # 2 laws x 2 gammas
    labels = [line.get_label() for line in paths]
    assert labels == [
        r"McNamara et al. 2008 (hyperelastic), $\gamma$ = 0.5",
        r"McNamara et al. 2008 (hyperelastic), $\gamma$ = 2",
        r"Cundall–Strack (hypoelastic), $\gamma$ = 0.5",
        r"Cundall–Strack (hypoelastic), $\gamma$ = 2",
    ]
    case = case_data(uniaxial, "cundall_strack", gamma=2.0)
    line = paths[3]
    np.testing.assert_array_equal(line.get_xdata(), case["alpha"].values)
    np.testing.assert_array_equal(line.get_ydata(), case["F"].sel(dof="D1").values)
    assert r"$\alpha$" in axes.get_xlabel() and "(rad)" in axes.get_xlabel()
    assert axes.get_ylabel() == r"$F_1^* = F_1/(2R\,k_n)$"
    # A law x gamma grid: one colour per gamma, one line style per law; every case its own pair.
    assert len({to_rgba(line.get_color()) for line in paths}) == 2
    assert len({str(line.get_linestyle()) for line in paths}) == 2
    assert len({(to_rgba(line.get_color()), str(line.get_linestyle())) for line in paths}) == 4


def test_load_rotation_overlays_eq48_on_the_hyperelastic_cases_only(uniaxial):
    figure = plot_load_rotation(uniaxial)
    axes = figure.axes[0]
    overlays = lines_with(axes, "closed_form:")
    # Both branches of Eq. (48) for the two McNamara cases; none for Cundall-Strack.
    assert sorted(line.get_gid().split(":")[1] for line in overlays) == ["+", "+", "-", "-"]
    assert all("McNamara" in line.get_gid() for line in overlays)
    paths = {line.get_label(): line for line in lines_with(axes, "path:")}
    for line in overlays:
        _, branch, label = line.get_gid().split(":", 2)
        gamma = 0.5 if label.endswith("0.5") else 2.0
        alpha, F1 = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        expected = mcnamara_load_rotation(
            alpha, gamma, ALPHA0, 0.0, branch=-1 if branch == "-" else 1
        )
        np.testing.assert_allclose(F1, expected, rtol=0, atol=OVERLAY_TOL, equal_nan=True)
        # Over the computed alpha range, in the colour of its curve, dashed.
        case = case_data(uniaxial, "mcnamara", gamma=gamma)
        assert alpha.min() == pytest.approx(float(case["alpha"].min()), abs=1e-12)
        assert alpha.max() == pytest.approx(float(case["alpha"].max()), abs=1e-12)
        assert to_rgba(line.get_color())[:3] == to_rgba(paths[label].get_color())[:3]
        assert line.get_linestyle() == "--"
    # The computed path lies on the - branch (the path stays before the turning point).
    case = case_data(uniaxial, "mcnamara", gamma=0.5)
    alpha = case["alpha"].values
    np.testing.assert_allclose(
        case["F"].sel(dof="D1").values, mcnamara_load_rotation(alpha, 0.5, ALPHA0), rtol=0, atol=1e-10
    )


def test_legend_has_the_cases_one_closed_form_and_one_entry_per_event_kind(uniaxial):
    texts = legend_texts(plot_load_rotation(uniaxial))
    # 2 laws x 2 gammas: each law (its line style) and each gamma (its colour) once.
    assert texts[:4] == [
        "McNamara et al. 2008 (hyperelastic)",
        "Cundall–Strack (hypoelastic)",
        r"$\gamma$ = 0.5",
        r"$\gamma$ = 2",
    ]
    assert texts[4] == "closed form (seed Eq. 48)"
    # Four cases each meet the secondary contact (recorded, ignored): one entry.
    assert texts[5:] == ["secondary contact"]
    assert len(lines_with(plot_load_rotation(uniaxial).axes[0], "event:secondary_contact:")) == 4


def test_load_displacement_maps_the_closed_form_through_eq46(uniaxial):
    axes = plot_load_displacement(uniaxial).axes[0]
    assert axes.get_xlabel() == r"$\Delta_1^* = \Delta_1/2R$"
    (overlay,) = [
        line for line in lines_with(axes, "closed_form:-:") if line.get_gid().endswith("= 2")
    ]
    D1, F1 = np.asarray(overlay.get_xdata()), np.asarray(overlay.get_ydata())
    # The overlay is sampled on the same alpha grid in both figures: rebuild it
    # from the load-rotation overlay with Eq. (48) and (46).
    rotation_axes = plot_load_rotation(uniaxial).axes[0]
    (rotation,) = [
        line
        for line in lines_with(rotation_axes, "closed_form:-:")
        if line.get_gid().endswith("= 2")
    ]
    alpha = np.asarray(rotation.get_xdata())
    F1_expected = mcnamara_load_rotation(alpha, 2.0, ALPHA0)
    D1_expected, _ = diamond_displacements(
        alpha, mcnamara_branch_length(alpha, F1_expected, 0.0), ALPHA0
    )
    np.testing.assert_allclose(F1, F1_expected, rtol=0, atol=OVERLAY_TOL)
    np.testing.assert_allclose(D1, D1_expected, rtol=0, atol=OVERLAY_TOL)
    legend = legend_texts(axes.figure)
    assert "closed form (seed Eq. 46, 48)" in legend


# --- events ---------------------------------------------------------------------------------


def test_limit_point_is_marked_where_it_was_located(preloaded):
    case = preloaded.isel(law=0)
    alpha = float(case["limit_point_alpha"])
    F1 = float(case["limit_point_F"].sel(dof="D1"))
    D1 = float(case["limit_point_u"].sel(dof="D1"))
    assert np.isfinite([alpha, F1, D1]).all()
    for plot, x in ((plot_load_rotation, alpha), (plot_load_displacement, D1)):
        figure = plot(preloaded)
        (marker,) = lines_with(figure.axes[0], "event:limit_point:")
        assert marker.get_marker() == "o"
        assert (marker.get_xdata()[0], marker.get_ydata()[0]) == (x, F1)
        texts = legend_texts(figure)
        assert "limit point (det K = 0)" in texts and "loss of Hill's condition" in texts
    (marker,) = lines_with(plot_load_rotation(preloaded).axes[0], "event:hill_loss:")
    assert marker.get_marker() == "s"


def test_preloaded_overlay_is_eq53_over_the_last_stage_with_the_held_lateral_force(preloaded):
    axes = plot_load_rotation(preloaded).axes[0]
    case = case_data(preloaded, "mcnamara")
    last = case["stage"].values == case["stage"].values.max()
    F2 = case["F"].sel(dof="D2").values[last]
    assert np.ptp(F2) < 1e-10 and F2[0] == pytest.approx(0.75, abs=1e-10)
    overlays = lines_with(axes, "closed_form:")
    assert len(overlays) == 2
    for line in overlays:
        branch = -1 if line.get_gid().startswith("closed_form:-:") else 1
        alpha = np.asarray(line.get_xdata())
        expected = mcnamara_load_rotation(alpha, 0.5, ALPHA0, np.median(F2), branch=branch)
        np.testing.assert_allclose(
            line.get_ydata(), expected, rtol=0, atol=OVERLAY_TOL, equal_nan=True
        )
        assert alpha.min() == pytest.approx(case["alpha"].values[last].min(), abs=1e-12)
    assert "closed form (seed Eq. 53)" in legend_texts(axes.figure)


def test_3d_figure_has_the_curve_events_and_closed_form(preloaded):
    figure = plot_load_displacement_rotation(preloaded)
    (axes,) = figure.axes
    assert axes.name == "3d"
    (path,) = lines_with(axes, "path:")
    case = case_data(preloaded, "mcnamara")
    x, y, z = path.get_data_3d()
    np.testing.assert_array_equal(x, case["u"].sel(dof="D1").values)
    np.testing.assert_array_equal(y, case["alpha"].values)
    np.testing.assert_array_equal(z, case["F"].sel(dof="D1").values)
    (marker,) = lines_with(axes, "event:limit_point:")
    assert tuple(np.ravel(c)[0] for c in marker.get_data_3d()) == (
        float(case["limit_point_u"].sel(dof="D1")),
        float(case["limit_point_alpha"]),
        float(case["limit_point_F"].sel(dof="D1")),
    )
    assert lines_with(axes, "closed_form:-:")
    assert axes.get_zlabel() == r"$F_1^* = F_1/(2R\,k_n)$"
    assert "closed form (seed Eq. 46, 53)" in legend_texts(figure)


def test_stability_panels_show_the_indicators_and_their_zero_crossing(preloaded):
    figure = plot_stability(preloaded)
    panels = figure.axes
    assert len(panels) == 3
    assert [p.get_ylabel() for p in panels] == [
        r"$\det K^*$",
        r"$\lambda_{\min}(K^*_{\mathrm{sym}})$",
        "$d^2W$\n(normalised)",
    ]
    case = case_data(preloaded, "mcnamara")
    for axes, name in zip(panels[:2], ("det_K", "hill")):
        (path,) = lines_with(axes, "path:")
        np.testing.assert_array_equal(path.get_ydata(), case[name].values)
        np.testing.assert_array_equal(path.get_xdata(), case["u"].sel(dof="D1").values)
        assert any(list(line.get_ydata()) == [0.0, 0.0] for line in axes.get_lines())  # zero line
    # det K and the Hill eigenvalue vanish at the located limit point (hyperelastic:
    # K symmetric, the two coincide); the markers sit there.
    for axes in panels[:2]:
        (marker,) = lines_with(axes, "event:limit_point:")
        assert marker.get_xdata()[0] == float(case["limit_point_u"].sel(dof="D1"))
        assert abs(marker.get_ydata()[0]) < 1e-8
    assert panels[2].get_ylim() == (-1.1, 1.1)


def test_d2w_is_explained_broken_where_it_jumps_and_not_marked_there(preloaded):
    axes = plot_stability(preloaded).axes[2]
    assert axes.get_title(loc="left") == D2W_EXPLANATION
    case = case_data(preloaded, "mcnamara")
    (path,) = lines_with(axes, "path:")
    y, x = np.asarray(path.get_ydata()), np.asarray(path.get_xdata())
    drawn = ~np.isnan(y)
    # Every stored value is drawn, in order; the line breaks (a NaN) at each jump.
    np.testing.assert_array_equal(y[drawn], case["d2W"].values)
    np.testing.assert_array_equal(x[drawn], case["u"].sel(dof="D1").values)
    breaks = np.flatnonzero(~drawn) - np.arange((~drawn).sum())  # index of the state after each break
    stage, s, d2w = case["stage"].values, case["s"].values, case["d2W"].values
    limit = float(case["limit_point_s"])
    expected = set(np.flatnonzero(np.diff(stage) != 0) + 1)  # stage 1 -> stage 2
    (at,) = np.flatnonzero((s[:-1] <= limit) & (limit <= s[1:])) + 1
    assert d2w[at - 1] > 0 > d2w[at]  # d2W jumps at the limit point: dF turns back
    expected.add(int(at))
    assert sorted(breaks) == sorted(expected)
    # No marker on the jump: neither the limit point nor Hill's loss (located there too).
    assert not lines_with(axes, "event:limit_point:") and not lines_with(axes, "event:hill_loss:")


# --- seed figures that show the paper's point -----------------------------------------------


def test_a_path_past_the_maximum_of_alpha_is_coloured_by_branch_of_eq48(fold):
    case = case_data(fold, "mcnamara")
    alpha, F1 = case["alpha"].values, case["F"].sel(dof="D1").values
    k = int(np.argmax(alpha))
    assert 0 < k < alpha.size - 1  # the path passes the maximum of alpha
    for plot, x_of in ((plot_load_rotation, alpha), (plot_load_displacement, case["u"].sel(dof="D1").values)):
        axes = plot(fold).axes[0]
        (minus,) = lines_with(axes, "path:-:")
        (plus,) = lines_with(axes, "path:+:")
        assert to_rgba(minus.get_color())[:3] == to_rgba(BRANCH_COLOURS[-1])[:3]
        assert to_rgba(plus.get_color())[:3] == to_rgba(BRANCH_COLOURS[1])[:3]
        n = len(minus.get_xdata())
        # The two pieces are the path, in order, sharing the state where they join.
        np.testing.assert_array_equal(np.concatenate([minus.get_xdata(), plus.get_xdata()[1:]]), x_of)
        assert minus.get_xdata()[-1] == plus.get_xdata()[0]
        # Each state is on the root of Eq. (48) of its colour: F1 sin(a)cos(a) - sin(a) = -+sqrt(delta)
        # (exactly the branch sign; states within 1e-6 of the fold, where the roots meet, excepted).
        root = F1 * np.sin(alpha) * np.cos(alpha) - np.sin(alpha)
        sign = np.where(np.arange(alpha.size) < n - 1, -1, 1)
        clear = np.abs(root) > 1e-6
        assert clear.sum() >= alpha.size - 2
        np.testing.assert_array_equal(np.sign(root[clear]), sign[clear])
        for branch, colour in (("-", BRANCH_COLOURS[-1]), ("+", BRANCH_COLOURS[1])):
            (overlay,) = lines_with(axes, f"closed_form:{branch}:")
            assert to_rgba(overlay.get_color())[:3] == to_rgba(colour)[:3]
        assert abs(n - 1 - k) <= 1  # the colours change at the maximum of alpha
    # The apparent crossing of Fig. 4 is pointed at: where the branches meet.
    axes = plot_load_displacement(fold).axes[0]
    (note,) = [text for text in axes.texts if text.get_gid() == "branch_junction"]
    (plus,) = lines_with(axes, "path:+:")
    assert note.xy == (plus.get_xdata()[0], plus.get_ydata()[0])
    assert "not a bifurcation" in note.get_text()


def test_the_3d_view_shows_the_fold_in_alpha(fold):
    axes = plot_load_displacement_rotation(fold).axes[0]
    assert (axes.elev, axes.azim) == VIEW
    pieces = lines_with(axes, "path:")
    assert [p.get_gid().split(":")[1] for p in pieces] == ["-", "+"]
    xyz = [np.concatenate([np.asarray(p.get_data_3d()[i]) for p in pieces]) for i in range(3)]
    screen_x, _, _ = proj3d.proj_transform(*xyz, axes.get_proj())
    # Seen from VIEW the path goes across the page and comes back: the fold is in sight, by
    # more than 4 % of the path's width on the page (alpha turns back by a fifth of its range;
    # the former view, azimuth -56, showed it edge-on: 0 %).
    k = int(np.argmax(screen_x))
    assert 0 < k < screen_x.size - 1
    assert screen_x[k] - screen_x[-1] > 0.04 * np.ptp(screen_x)


def test_cundall_strack_and_mcnamara_coincide_in_pure_shear_and_both_show(pure_shear):
    # The premise (seed Eq. 60): both paths are the rotational model's first branch, Eq. (62),
    # up to the blocking contact (checked against the closed form; the engine samples the two
    # laws at different arclengths, so their stored states differ).
    for law in ("cundall_strack", "mcnamara"):
        case = case_data(pure_shear, law)
        alpha, F1 = case["alpha"].values, case["F"].sel(dof="D1").values
        first = alpha < float(pure_shear_blocking_alpha(ALPHA0, "rotational")) - 1e-9
        np.testing.assert_allclose(
            F1[first], pure_shear_load_rotation(alpha[first], ALPHA0, 0.0, "rotational"), rtol=0, atol=1e-9
        )
    figure = plot_load_rotation(pure_shear)
    axes = figure.axes[0]
    first, second = lines_with(axes, "path:")
    assert "Cundall" in first.get_gid() and "McNamara" in second.get_gid()
    assert first.get_linestyle() == "-" and second.get_linestyle() == "--"  # dashed over it
    assert second.get_zorder() > first.get_zorder()
    assert to_rgba(first.get_color())[:3] != to_rgba(second.get_color())[:3]
    texts = legend_texts(figure)
    assert texts[1] == (
        "McNamara et al. 2008 (hyperelastic):\nsame path as Cundall–Strack in pure shear (seed Eq. 60)"
    )
    # The closed form (Eq. 62, blocking Eq. 66) is drawn once, with the first case.
    assert len(lines_with(axes, "closed_form:first:")) == 1
    assert len(lines_with(axes, "closed_form:blocking:")) == 1


def test_titles_and_legends_write_the_symbols(preloaded, uniaxial):
    dataset = preloaded.assign_attrs(study_description="Seed: gamma = 0.5, F2* = 0.75, alpha0 = pi/4")
    assert plot_load_rotation(dataset).get_suptitle() == (
        "Seed: γ = 0.5, F₂* = 0.75, α₀ = π/4\n$F_1^*$ against $\\alpha$"
    )
    assert plot_load_displacement(dataset).get_suptitle().endswith("$F_1^*$ against $\\Delta_1^*$")
    # Without a description: the kind's title and the fixed parameters, in symbols.
    assert plot_load_rotation(uniaxial).get_suptitle() == (
        "Load–rotation response, $\\alpha_0$ = π/4\n$F_1^*$ against $\\alpha$"
    )
    assert symbolic_text("alpha0 = pi/4, F1* at Delta1* = 0.2; alphabet") == (
        "α₀ = π/4, F₁* at Δ₁* = 0.2; alphabet"
    )


# --- the pure-shear limit -------------------------------------------------------------------


def test_rigid_load_rotation_is_eq62_65_with_the_blocking_branches(rigid):
    axes = plot_load_rotation(rigid).axes[0]
    assert axes.get_ylabel() == r"$\hat F_1 = F_1/(2R\,k_t)$"
    for law, model in (("McNamara", "rotational"), ("Turco", "translational")):
        (first,) = [
            line for line in lines_with(axes, "closed_form:first:") if law in line.get_gid()
        ]
        alpha = np.asarray(first.get_xdata())
        np.testing.assert_allclose(
            first.get_ydata(),
            pure_shear_load_rotation(alpha, ALPHA0, 0.0, model),
            rtol=0,
            atol=OVERLAY_TOL,
        )
        blocking_alpha = float(pure_shear_blocking_alpha(ALPHA0, model))
        assert alpha.max() == pytest.approx(blocking_alpha, abs=1e-12)
        (blocking,) = [
            line for line in lines_with(axes, "closed_form:blocking:") if law in line.get_gid()
        ]
        assert list(blocking.get_xdata()) == [blocking_alpha, blocking_alpha]
    # The computed paths are blocked there: alpha stops at alpha_max (pi/3 for McNamara).
    case = case_data(rigid, "mcnamara")
    assert float(case["alpha"].max()) == pytest.approx(np.pi / 3, abs=1e-9)
    assert "closed form (seed Eq. 62, 65, 66, 68)" in legend_texts(axes.figure)


def test_rigid_load_displacement_blocks_at_cos_alpha0_minus_one_half(rigid):
    axes = plot_load_displacement(rigid).axes[0]
    blocking = lines_with(axes, "closed_form:blocking:")
    assert len(blocking) == 2
    for line in blocking:
        assert line.get_xdata()[0] == pytest.approx(
            (np.sqrt(2) - 1) / 2, abs=1e-15
        )  # seed Eq. (67)


def test_rigid_stability_says_the_indicators_are_not_defined(rigid):
    figure = plot_stability(rigid)
    for axes in figure.axes:
        assert not lines_with(axes, "path:")
        notes = [t.get_text() for t in axes.texts]
        assert notes == ["not defined in the pure-shear limit"]


# --- failed cases, labels, colours ----------------------------------------------------------


def test_a_failed_case_is_drawn_dashed_grey_without_closed_form(uniaxial, tmp_path):
    dataset = uniaxial.copy(deep=True)
    dataset["status"] = dataset["status"].astype("U40")  # room for a longer status
    dataset["status"].loc[{"law": "mcnamara", "gamma": 2.0}] = "failed:newton"
    dataset["n_steps"].loc[{"law": "mcnamara", "gamma": 2.0}] = 5
    axes = plot_load_rotation(dataset).axes[0]
    (failed,) = [line for line in lines_with(axes, "path:") if "failed" in line.get_label()]
    assert (
        failed.get_label() == r"McNamara et al. 2008 (hyperelastic), $\gamma$ = 2 — failed (newton)"
    )
    assert len(failed.get_xdata()) == 5
    assert failed.get_linestyle() == "--" and to_rgba(failed.get_color()) == to_rgba("0.6")
    assert not [line for line in lines_with(axes, "closed_form:") if "failed" in line.get_gid()]
    assert len(draw_figures(dataset, tmp_path, kinds=KINDS, dpi=30)) == 4


def test_display_names_and_parameter_values():
    assert law_display_name("cundall_strack") == "Cundall–Strack (hypoelastic)"
    assert law_display_name("turco+no_tension") == "Turco et al. 2019 (hyperelastic), no tension"
    assert format_parameter("alpha0", np.pi / 4) == r"$\alpha_0$ = π/4"
    assert format_parameter("alpha0", 0.7) == r"$\alpha_0$ = 0.7"
    assert format_parameter("gamma", np.float64(1.25)) == r"$\gamma$ = 1.25"
    assert format_parameter("F2_lateral", 0.75) == r"$F_2^*$ = 0.75"  # a force: its symbol
    assert format_parameter("D12_max", 0.1) == r"$\Delta_{12}^*$ = 0.1"
    assert format_parameter("radius", 0.05) == "radius = 0.05"


@pytest.mark.parametrize("laws", [["mcnamara"] * 8, ["mcnamara", "turco"] * 6])
def test_eight_and_more_curves_get_distinct_colours(laws):
    colours = case_colours(laws, len(laws))
    assert len({to_rgba(c) for c in colours}) == len(laws)


def test_a_given_figure_is_drawn_into(uniaxial):
    figure = Figure(figsize=(4, 3))
    assert plot_load_displacement(uniaxial, figure) is figure
    assert len(lines_with(figure.axes[0], "path:")) == 4


def test_more_than_twelve_cases_are_a_fan_not_twenty_curves(uniaxial):
    # 20 copies of one case along a new sweep dimension: a fan with five labelled cases.
    one = uniaxial.isel(law=[0], gamma=[0])
    dataset = xr.concat([one.assign_coords(gamma=[g]) for g in np.linspace(0.1, 2.0, 20)], "gamma")
    figure = plot_load_rotation(dataset)
    panel = next(a for a in figure.axes if a.collections)
    (fan,) = [c for c in panel.collections if c.get_gid() == "fan:mcnamara"]
    assert len(fan.get_segments()) == 20
    assert len(lines_with(panel, "path:")) == 5
    (legend,) = figure.legends
    texts = [t.get_text() for t in legend.get_texts()]
    assert texts[:2] == ["envelope of all 20 paths per law", r"$\gamma$ = 0.1"]
