"""``[output] extrema``: the first extremum of a state variable, located by root finding.

The bar (issue 41): seed Fig. 3, the hyperelastic diamond of McNamara et al. (2008),
gamma = 2, F2* = 0, alpha0 = pi/4, reaches its largest rotation where the two
branches of seed Eq. (48) meet: their discriminant 1 + 4 gamma (alpha0 - alpha) /
tan alpha vanishes, tan alpha = 4 gamma (alpha - alpha0); there F1* = 1/cos alpha
(Eq. 48) and l* = 1/2 (Eq. 46, first line), so Delta1* = cos alpha0 - cos(alpha)/2
(Eq. 46, third line).  The expected values come from an independent root solve of
that equation here, not from the code under test.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import matplotlib
import numpy as np
import pytest
import xarray as xr
from scipy.optimize import brentq

from ncstab.cli import main
from ncstab.paths.api import follow
from ncstab.paths.extrema import extremum, extremum_choices, locate_extremum
from ncstab.studies import (
    StudyFileError,
    load_study,
    open_study,
    parse_study,
    run_study,
    write_dataset,
)

matplotlib.use("Agg")

ROOT = Path(__file__).resolve().parents[1]
FIG03 = ROOT / "studies" / "seed" / "fig03_05_mcnamara_gamma2.toml"
GAMMA, ALPHA0 = 2.0, np.pi / 4
#: The issue's value of alpha_max, printed to 12 decimals.
ISSUE_ALPHA_MAX = 0.966395898960
#: The bar: alpha_max, Delta1* and F1* each to 1e-8.  Measured: 6e-14, 1.5e-12 and
#: 9.5e-12 (the equilibrium is re-solved to newton_tol-size residuals, the root in
#: the arclength to 1e-14; F1* = 1/cos alpha amplifies by |d F1/d sigma| ~ 10).
BAR = 1e-8
#: Rate-form law: the root of a path integrated from the stored state before it
#: (RK4, 64 pieces) with two different stored-state spacings; measured 4.5e-13 in u,
#: 1.6e-12 in s.  1e-9 leaves a margin of 1000 and catches a located grid point
#: (sample_step 0.02 against 0.002: 1e-4 apart).
REFOLLOW_TOL = 1e-9


def alpha_max(gamma: float = GAMMA, alpha0: float = ALPHA0) -> float:
    """The root of tan alpha = 4 gamma (alpha - alpha0) in (alpha0, arccos(1/(2 sqrt gamma)))."""
    upper = float(np.arccos(1 / (2 * np.sqrt(gamma))))  # where tan a - 4 gamma (a - a0) is least
    return brentq(lambda a: np.tan(a) - 4 * gamma * (a - alpha0), alpha0, upper, xtol=1e-16, rtol=1e-15)


@pytest.fixture(scope="module")
def fig03() -> xr.Dataset:
    return run_study(load_study(FIG03))


def test_the_seed_study_asks_for_the_maximum_rotation():
    assert load_study(FIG03).extrema == ("alpha",)


def test_fig03_maximum_rotation_against_the_closed_form(fig03):
    expected = alpha_max()
    assert abs(expected - ISSUE_ALPHA_MAX) < 1e-12  # the issue's printed digits
    case = fig03.isel(law=0)
    assert int(case["extremum_alpha_stage"]) == 0
    np.testing.assert_allclose(float(case["extremum_alpha_alpha"]), expected, rtol=0, atol=BAR)
    u, F = case["extremum_alpha_u"].values, case["extremum_alpha_F"].values
    np.testing.assert_allclose(u[0], np.cos(ALPHA0) - np.cos(expected) / 2, rtol=0, atol=BAR)
    np.testing.assert_allclose(F[0], 1 / np.cos(expected), rtol=0, atol=BAR)
    # the rest of the state: l* = 1/2, Delta2* = sin alpha0 - sin(alpha)/2, F2* held at 0
    np.testing.assert_allclose(float(case["extremum_alpha_l"]), 0.5, rtol=0, atol=BAR)
    np.testing.assert_allclose(u[1], np.sin(ALPHA0) - np.sin(expected) / 2, rtol=0, atol=BAR)
    np.testing.assert_allclose(F[1], 0.0, rtol=0, atol=1e-12)
    # located between the stored states that bracket it, above every stored alpha
    s, lower, upper = (float(case[f"extremum_alpha_{k}"]) for k in ("s", "s_lower", "s_upper"))
    assert lower < s < upper
    assert float(case["extremum_alpha_alpha"]) >= float(case["alpha"].max()) - 1e-15


def test_fig03_a_variable_without_an_extremum_has_none(fig03):
    ds = run_study(parse_study(FIG03.read_text().replace('extrema = ["alpha"]', 'extrema = ["u:D2", "F:F2", "N"]')))
    # D2* grows all along; F2* is held at 0 (its rate is rounding: no sign, no extremum)
    for event in ("extremum_u_D2", "extremum_F_F2"):
        assert int(ds[f"{event}_stage"].isel(law=0)) == -1
        assert np.isnan(ds[f"{event}_u"].values).all()
    # N* = -(l* - 1) is greatest where l* is least: not at alpha_max (l* goes on shrinking)
    assert "extremum_N_s" in ds
    # the other variables are those of the study without extrema
    for name in ("u", "F", "alpha", "limit_point_s"):
        xr.testing.assert_identical(ds[name], fig03[name])


UNREDUCED = """
[study]
name = "axes"
[system]
name = "diamond"
reduction = "axes"
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = 2.0
[[loading]]
hold = { F_left = 0.0, F_right = 0.0 }
drive = { D_top = 0.5, D_bottom = 0.5 }
"""


def test_general_model_with_two_driven_dofs_and_a_rate_form_law():
    """The four-grain diamond driven top and bottom together: the same closed form for
    McNamara (a general model, lambda from 0 to 1); Cundall-Strack's (rate-form) maximum
    of D_left does not depend on where the states are stored."""
    study = parse_study(UNREDUCED)
    coarse = follow(study.system, list(study.law_definitions), study.programme, study.parameters, study.options)
    definition = coarse.model.definition
    assert "alpha:top_left" in extremum_choices(definition)
    mcnamara = locate_extremum(coarse, extremum("alpha:top_left", definition))[0]
    expected = alpha_max()
    np.testing.assert_allclose(np.abs(mcnamara["alpha"][0]), expected, rtol=0, atol=BAR)
    np.testing.assert_allclose(mcnamara["u"][0, :2], np.cos(ALPHA0) - np.cos(expected) / 2, rtol=0, atol=BAR)
    np.testing.assert_allclose(mcnamara["F"][0, :2], 1 / np.cos(expected), rtol=0, atol=BAR)

    fine_options = dataclasses.replace(study.options, sample_step=0.002)
    fine = follow(study.system, list(study.law_definitions), study.programme, study.parameters, fine_options)
    spec = extremum("u:D_left", definition)
    a, b = (locate_extremum(path, spec)[1] for path in (coarse, fine))
    assert a["found"][0] and b["found"][0]
    np.testing.assert_allclose(a["u"], b["u"], rtol=0, atol=REFOLLOW_TOL)
    np.testing.assert_allclose(a["s"], b["s"], rtol=0, atol=REFOLLOW_TOL)
    stored = fine.results[1].steps["u"][0, : fine.results[1].n_steps[0], 2]
    assert a["u"][0, 2] >= stored.max() - 1e-12  # a maximum of D_left
    assert a["u"][0, 2] - stored.max() < 1e-6  # and the fine path's stored states come close


def test_the_archive_reads_back_identical(fig03, tmp_path):
    write_dataset(fig03, tmp_path / "fig03.nc")
    back = open_study(tmp_path / "fig03.nc")
    for name in ("extremum_alpha_s", "extremum_alpha_u", "extremum_alpha_stage"):
        xr.testing.assert_identical(back[name], fig03[name])
    assert fig03["extremum_alpha_s"].attrs["units"] == "1"
    assert "first extremum of alpha" in fig03["extremum_alpha_s"].attrs["description"]


def test_info_lists_the_extremum_with_the_force_at_it(fig03, tmp_path, capsys):
    """``ncstab info`` lists ``extremum_alpha`` like the other events, with F1 there: F1* = 1/cos
    alpha_max (the closed form, to the 6 digits info prints)."""
    from ncstab.cli import main

    write_dataset(fig03, tmp_path / "fig03.nc")
    assert main(["info", str(tmp_path / "fig03.nc")]) == 0
    out = capsys.readouterr().out
    line = next(line for line in out.splitlines() if "extremum_alpha:" in line)
    assert "found in 1 of 1 cases" in line
    assert f"F1 = {1 / np.cos(alpha_max()):.6g}" in line


def test_the_seed_figures_mark_the_extremum(fig03):
    from ncstab.plotting import (
        plot_load_displacement,
        plot_load_displacement_rotation,
        plot_load_rotation,
    )

    expected = alpha_max()
    for plot, at in ((plot_load_rotation, expected), (plot_load_displacement, np.cos(ALPHA0) - np.cos(expected) / 2)):
        axes = plot(fig03).axes[0]
        marks = [line for line in axes.get_lines() if (line.get_gid() or "").startswith("event:extremum_alpha:")]
        assert len(marks) == 1
        np.testing.assert_allclose(marks[0].get_xdata(), [at], rtol=0, atol=BAR)
        np.testing.assert_allclose(marks[0].get_ydata(), [1 / np.cos(expected)], rtol=0, atol=BAR)
    axes = plot_load_displacement_rotation(fig03).axes[0]
    assert any((line.get_gid() or "").startswith("event:extremum_alpha:") for line in axes.get_lines())


@pytest.mark.parametrize(
    ("value", "expected"),
    [
        ('["beta"]', "unknown state variable 'beta'"),
        ('["u:D9"]', "unknown state variable 'u:D9'"),
        ('"alpha"', "expected an array of state variable names"),
        ('["alpha", "alpha"]', "'alpha' is listed twice"),
    ],
)
def test_a_bad_extremum_names_the_field(value, expected):
    text = FIG03.read_text().replace('extrema = ["alpha"]', f"extrema = {value}")
    with pytest.raises(StudyFileError) as info:
        parse_study(text)
    assert any(field == "output.extrema" and expected in message for field, message in info.value.errors)


def test_the_pure_shear_limit_is_refused():
    text = FIG03.read_text().replace('secondary_contacts = "ignore"', 'secondary_contacts = "ignore"\nnormal = "rigid"')
    text = text.replace("[parameters]\ngamma = 2.0\n", "")
    with pytest.raises(StudyFileError) as info:
        parse_study(text)
    assert any(field == "output.extrema" and "pure-shear" in message for field, message in info.value.errors)


def test_the_command_line_exits_2_naming_the_field(tmp_path, capsys):
    study = tmp_path / "bad.toml"
    study.write_text(FIG03.read_text().replace('extrema = ["alpha"]', 'extrema = ["alpah"]'))
    assert main(["run", str(study), "-o", str(tmp_path / "never.nc")]) == 2
    err = capsys.readouterr().err
    assert "output.extrema" in err and "did you mean 'alpha'" in err and "Traceback" not in err
    assert not (tmp_path / "never.nc").exists()


def test_a_sweep_of_gamma_against_the_closed_form_whole_and_in_chunks(tmp_path):
    """Seed Fig. 8's family: alpha has a maximum only for gamma large enough (NaN where
    tan alpha = 4 gamma (alpha - alpha0) has no root, seed Eq. 48's branches never meet);
    a run in chunks locates the same extrema."""
    from ncstab.studies.chunked import run_study_chunked
    from ncstab.systems.closed_forms import mcnamara_turning_alpha

    text = (ROOT / "studies" / "seed" / "fig08_mcnamara_gamma_family.toml").read_text()
    study = parse_study(text.replace("[output]\n", '[output]\nextrema = ["alpha"]\n'))
    whole = run_study(study)
    gamma = whole["gamma"].values
    expected = mcnamara_turning_alpha(gamma, ALPHA0)
    assert np.isfinite(expected).sum() == 2  # gamma = 1.75 and 2 (a root needs gamma above ~1.55)
    located = whole["extremum_alpha_alpha"].isel(law=0).values
    np.testing.assert_array_equal(np.isnan(located), np.isnan(expected))
    np.testing.assert_allclose(located, expected, rtol=0, atol=BAR)
    chunked = open_study(run_study_chunked(study, tmp_path / "chunked.nc", chunk_cases=3))
    for name in whole.data_vars:
        if str(name).startswith("extremum_"):
            xr.testing.assert_identical(chunked[name], whole[name])
