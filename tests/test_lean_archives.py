"""Lean archives (issue 19): ``[output] variables``, the lean default of large sweeps,
the events left out and put back, K computed again, and the CF attributes of an archive."""

from __future__ import annotations

import netCDF4
import numpy as np
import pytest
import xarray as xr

from ncstab.cli import main
from ncstab.paths.programme import EVENTS
from ncstab.studies import (
    StudyFileError,
    open_study,
    parse_study,
    run_study,
    run_study_chunked,
    tangent_operators,
    write_dataset,
)
from ncstab.studies.archive_selection import (
    EVENTS_LEFT_OUT,
    LEAN_LEFT_OUT,
    archive_selection,
    event_variables,
    study_variable_names,
)

#: The diamond under Cundall-Strack, 40 gamma x 30 alpha0 = 1,200 cases (> 1,000: lean by
#: default), D1* driven to 0.3: secondary contacts are met, no other event is.  ~5 s.
LARGE = """
[study]
name = "lean_sweep"
[system]
secondary_contacts = "ignore"
[laws]
names = ["cundall_strack"]
[parameters]
gamma = {{ start = 0.2, stop = 2.0, num = {n_gamma} }}
alpha0 = {{ start = 0.6, stop = 0.95, num = {n_alpha0} }}
[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = 0.3 }}
[output]
figures = []
{output}
"""
#: Two laws, two cases each: a cheap study for explicit selections.
SMALL = """
[study]
name = "lean_small"
[system]
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.5, 2.0]
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.3 }
[output]
figures = []
"""


def large(output: str = "", n_gamma: int = 40, n_alpha0: int = 30) -> str:
    return LARGE.format(n_gamma=n_gamma, n_alpha0=n_alpha0, output=output)


def without_created(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    dataset.attrs.pop("created", None)
    return dataset


@pytest.fixture(scope="module")
def lean_and_full(tmp_path_factory):
    """The large sweep written with the default (lean) and with variables = "all", read back."""
    directory = tmp_path_factory.mktemp("lean")
    lean, full = run_study(parse_study(large())), run_study(parse_study(large('variables = "all"')))
    write_dataset(lean, directory / "lean.nc")
    write_dataset(full, directory / "full.nc")
    return lean, full, directory


# -- [output] variables ------------------------------------------------------------------


def test_an_archive_holds_exactly_the_selected_variables(tmp_path):
    study = parse_study(SMALL.replace("figures = []", 'figures = []\nvariables = ["u", "F", "limit_point"]'))
    dataset = run_study(study)
    limit_point = {name for name in dataset.data_vars if name.startswith("limit_point_")}
    assert limit_point >= {"limit_point_s", "limit_point_u", "limit_point_F", "limit_point_K", "limit_point_T"}
    assert set(dataset.data_vars) == {"u", "F", "status", "message", "n_steps"} | limit_point
    assert "K" in dataset.attrs["variables_left_out"].split(", ")
    write_dataset(dataset, tmp_path / "selected.nc")
    xr.testing.assert_identical(open_study(tmp_path / "selected.nc"), dataset)


def test_an_event_variable_is_selected_by_its_full_name():
    study = parse_study(SMALL.replace("figures = []", 'figures = []\nvariables = ["hill", "limit_point_F"]'))
    assert set(run_study(study).data_vars) == {"hill", "limit_point_F", "status", "message", "n_steps"}


def test_an_unknown_variable_is_an_error_of_output_variables_with_a_suggestion():
    with pytest.raises(StudyFileError) as raised:
        parse_study(SMALL.replace("figures = []", 'figures = []\nvariables = ["u", "K_sim", "limit_pont"]'))
    assert raised.value.fields == ["output.variables", "output.variables"]
    assert "unknown variable 'K_sim' (did you mean 'K_sym'?)" in str(raised.value)
    assert "unknown variable 'limit_pont' (did you mean 'limit_point'?)" in str(raised.value)


def test_a_variable_the_system_does_not_have_is_unknown():
    with pytest.raises(StudyFileError, match="unknown variable 'load'"):
        parse_study(SMALL.replace("figures = []", 'figures = []\nvariables = ["load"]'))


def test_ncstab_run_exits_2_on_an_unknown_variable_and_writes_nothing(tmp_path, capsys):
    study = tmp_path / "bad.toml"
    study.write_text(SMALL.replace("figures = []", 'figures = []\nvariables = ["det_k"]'))
    assert main(["run", str(study), "-o", str(tmp_path / "never.nc")]) == 2
    err = capsys.readouterr().err
    assert "output.variables" in err and "did you mean 'det_K'" in err and "Traceback" not in err
    assert not (tmp_path / "never.nc").exists()


def test_a_figure_that_draws_a_left_out_variable_is_refused():
    text = SMALL.replace("figures = []", 'figures = ["stability"]\nvariables = ["u", "F", "hill"]')
    with pytest.raises(StudyFileError) as raised:
        parse_study(text)
    assert raised.value.fields == ["output.variables"]
    assert "figure 'stability' draws det_K, d2W, stage" in str(raised.value)


@pytest.mark.parametrize("value", ['"some"', "3", '["u", "u"]', "[1]"])
def test_a_malformed_selection_is_refused(value):
    with pytest.raises(StudyFileError) as raised:
        parse_study(SMALL.replace("figures = []", f"figures = []\nvariables = {value}"))
    assert raised.value.fields == ["output.variables"]


def test_the_variables_a_study_declares_are_those_its_run_stores():
    """study_variable_names, used to check a selection, says what path_dataset makes."""
    for text in (SMALL, large(n_gamma=2, n_alpha0=2)):
        study = parse_study(text)
        names = study_variable_names(study.system, study.programme, study.map, study.spectrum)
        full = run_study(parse_study(text.replace("figures = []", 'figures = []\nvariables = "all"')))
        assert sorted(names) == sorted(full.data_vars)


# -- the default --------------------------------------------------------------------------


def test_up_to_1000_cases_per_law_the_default_keeps_every_variable():
    assert archive_selection(parse_study(large(n_gamma=40, n_alpha0=25))).kept is None
    lean = archive_selection(parse_study(large(n_gamma=41, n_alpha0=25)))
    assert lean.kept is not None and lean.leave_out_unseen_events
    dataset = run_study(parse_study(SMALL))
    assert {"K", "K_sym", "K_skew"} <= set(dataset.data_vars)
    assert all(f"{event}_s" in dataset for event in EVENTS)
    assert "variables_left_out" not in dataset.attrs and EVENTS_LEFT_OUT not in dataset.attrs


def test_a_large_sweep_is_lean_by_default(lean_and_full):
    lean, full, directory = lean_and_full
    met = [event for event in EVENTS if bool((full[f"{event}_stage"] >= 0).any())]
    assert met == ["secondary_contact"]  # the study meets one event: the others are left out
    unmet = [event for event in EVENTS if event not in met]
    left_out = set(LEAN_LEFT_OUT) | {name for event in unmet for name in event_variables(event, full.data_vars)}
    assert set(full.data_vars) - set(lean.data_vars) == left_out
    assert set(lean.data_vars) <= set(full.data_vars)
    assert lean.attrs[EVENTS_LEFT_OUT] == ", ".join(unmet)
    assert lean.attrs["variables_left_out"] == "K, K_sym, K_skew"
    for name in lean.data_vars:  # what is kept is what the full archive holds
        xr.testing.assert_identical(lean[name], full[name])
    xr.testing.assert_identical(open_study(directory / "lean.nc"), lean)


def test_a_lean_archive_is_smaller(lean_and_full):
    _, _, directory = lean_and_full
    assert (directory / "lean.nc").stat().st_size < 0.7 * (directory / "full.nc").stat().st_size


def test_the_streamed_archive_makes_the_same_selection(lean_and_full, tmp_path):
    lean, _, directory = lean_and_full
    run_study_chunked(parse_study(large()), tmp_path / "streamed.nc", chunk_cases=300)
    streamed = open_study(tmp_path / "streamed.nc")
    xr.testing.assert_identical(without_created(streamed), without_created(open_study(directory / "lean.nc")))


def test_a_streamed_archive_keeps_an_explicit_selection(tmp_path):
    study = parse_study(SMALL.replace("figures = []", 'figures = []\nvariables = ["u", "hill_loss"]'))
    run_study_chunked(study, tmp_path / "streamed.nc", chunk_cases=2)
    streamed = open_study(tmp_path / "streamed.nc")
    xr.testing.assert_identical(without_created(streamed), without_created(run_study(study)))
    assert set(streamed.data_vars) == {"u", "status", "message", "n_steps"} | {
        name for name in streamed.data_vars if name.startswith("hill_loss_")
    }


def test_a_figure_that_draws_K_keeps_it_in_a_lean_archive():
    selection = archive_selection(parse_study(large().replace("figures = []", 'figures = ["second_order_work_polar"]')))
    assert selection.kept is not None and "K" in selection.kept and "K_sym" not in selection.kept


def test_an_event_a_figure_draws_is_kept_even_if_no_case_meets_it():
    study = parse_study("""
[study]
name = "damping"
[system]
name = "ziegler"
load = "follower"
[parameters]
b1 = { start = 0.01, stop = 0.5, num = 40 }
b2 = { start = 0.01, stop = 0.5, num = 30 }
[[loading]]
drive = { P = 3.0 }
[output]
figures = ["damping_map"]
""")
    selection = archive_selection(study)
    assert selection.leave_out_unseen_events and selection.needed_events == {"flutter_onset"}


# -- events put back, K computed again ---------------------------------------------------


def test_fill_missing_events_puts_back_the_tables_of_the_full_archive(lean_and_full):
    lean, full, directory = lean_and_full
    filled = open_study(directory / "lean.nc", fill_missing_events=True)
    assert EVENTS_LEFT_OUT not in filled.attrs
    assert set(filled.data_vars) == set(full.data_vars) - set(LEAN_LEFT_OUT)
    for event in lean.attrs[EVENTS_LEFT_OUT].split(", "):
        for name in event_variables(event, full.data_vars):
            xr.testing.assert_identical(filled[name], full[name])
    unchanged = open_study(directory / "lean.nc")
    assert "limit_point_s" not in unchanged and EVENTS_LEFT_OUT in unchanged.attrs


def test_K_is_computed_again_from_a_lean_archive(lean_and_full):
    """Cundall-Strack: K from u and the stored internal variable T (seed Eq. 38), to rounding."""
    lean, full, _ = lean_and_full
    K = tangent_operators(lean)
    assert K.dims == full["K"].dims
    np.testing.assert_array_equal(np.isnan(K.values), np.isnan(full["K"].values))
    np.testing.assert_allclose(K.values, full["K"].values, rtol=1e-12, atol=1e-13)


# -- CF attributes ----------------------------------------------------------------------


def _check_cf(path) -> None:
    with netCDF4.Dataset(path) as handle:
        assert handle.getncattr("Conventions") == "CF-1.10"
        for name, variable in handle.variables.items():
            attributes = variable.ncattrs()
            assert "long_name" in attributes, name
            numeric = variable.dtype != str
            if numeric:
                assert "units" in attributes, name
            is_dimension = name in handle.dimensions
            if numeric and variable.dtype.kind in "iu" and not is_dimension and name not in ("cycle_stage", "cycle_direction"):
                assert "_FillValue" in attributes, name
                assert variable.getncattr("_FillValue") in (-1, -2147483647), name
            if is_dimension:
                assert "_FillValue" not in attributes, name


def test_every_variable_of_an_archive_has_units_long_name_and_integers_a_fill_value(lean_and_full, tmp_path):
    _, _, directory = lean_and_full
    _check_cf(directory / "full.nc")
    study = parse_study(SMALL)
    run_study_chunked(study, tmp_path / "streamed.nc", chunk_cases=1)
    _check_cf(tmp_path / "streamed.nc")
    back = open_study(tmp_path / "streamed.nc")
    assert back["stage"].dtype == np.int32 and back["n_steps"].dtype == np.int32
    assert int(back["stage"].min()) == -1  # the padding reads back as -1, not NaN
