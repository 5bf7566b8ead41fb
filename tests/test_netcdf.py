"""Running a study and its NetCDF archive: round trip, atomic writes, failed cases.

The study (``tests/data/good_studies/roundtrip.toml``, 8 cases, about 1 s) has
finished, stopped (``stopped:hill_loss``) and failed (``failed:bad_stage_start``)
cases, so every kind of status, message and event field goes through the archive.
"""

from __future__ import annotations

import os
import re
import stat
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import xarray as xr

import ncstab
from ncstab.paths import follow
from ncstab.paths.variables import VARIABLES
from ncstab.studies.archive import COMPRESSION
from ncstab.studies import (
    load_study,
    open_study,
    parse_study,
    run_study,
    write_dataset,
)

GOOD = Path(__file__).parent / "data" / "good_studies"
STUDY_FILE = GOOD / "roundtrip.toml"
#: Attributes that differ from run to run.
VOLATILE_ATTRS = ("created",)


@pytest.fixture(scope="module")
def study():
    return load_study(STUDY_FILE)


@pytest.fixture(scope="module")
def dataset(study):
    return run_study(study)


@pytest.fixture
def archive(dataset, tmp_path):
    return write_dataset(dataset, tmp_path / "roundtrip.nc")


def statuses(dataset: xr.Dataset) -> dict[tuple[str, float, float], str]:
    status = dataset["status"]
    return {
        (law, gamma, f2): str(status.sel(law=law, gamma=gamma, F2_lateral=f2).item())
        for law in dataset["law"].values
        for gamma in dataset["gamma"].values
        for f2 in dataset["F2_lateral"].values
    }


def without_volatile_attrs(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    for name in VOLATILE_ATTRS:
        dataset.attrs.pop(name, None)
    return dataset


# --- the run ---------------------------------------------------------------------------------


def test_the_study_has_finished_stopped_and_failed_cases(dataset):
    assert dataset["status"].dims == ("law", "gamma", "F2_lateral")
    found = statuses(dataset)
    # F2 preloaded to 0.25 is where stage 3 holds it: every case finishes.
    assert {s for (_, _, f2), s in found.items() if f2 == 0.25} == {"finished"}
    # Cundall--Strack with gamma = 0.5 loses Hill's condition in stage 2 (stop_at).
    assert found[("cundall_strack", 0.5, 0.75)] == "stopped:hill_loss"
    # The others reach stage 3 with F2 = 0.75, not the 0.25 it holds.
    for key in [("mcnamara", 0.5, 0.75), ("mcnamara", 2.0, 0.75), ("cundall_strack", 2.0, 0.75)]:
        assert found[key] == "failed:bad_stage_start"


def test_run_adds_the_study_attributes(dataset, study):
    assert dataset.attrs["study"] == study.text == STUDY_FILE.read_text(encoding="utf-8")
    assert dataset.attrs["study_name"] == "roundtrip"
    assert dataset.attrs["study_description"] == study.description
    assert dataset.attrs["figures"] == "load_displacement,stability"
    assert dataset.attrs["Conventions"] == "CF-1.10"
    assert dataset.attrs["ncstab_version"] == ncstab.__version__
    assert dataset.attrs["parameter_alpha0"] == np.pi / 4


def test_run_is_otherwise_the_path_dataset(dataset, study):
    direct = follow(
        study.system, list(study.laws), study.programme, study.parameters, study.options,
        study_text=study.text,
    ).to_dataset()
    added = ("study_name", "study_description", "figures")
    assert set(dataset.attrs) - set(direct.attrs) == set(added)
    expected = without_volatile_attrs(direct)
    expected.attrs.update({k: dataset.attrs[k] for k in added})
    xr.testing.assert_identical(without_volatile_attrs(dataset), expected)
    for name, variable in direct.variables.items():
        assert dataset[name].dtype == variable.dtype, name


def test_the_same_study_run_twice_gives_identical_data(dataset, study):
    again = run_study(study)
    xr.testing.assert_identical(without_volatile_attrs(again), without_volatile_attrs(dataset))


# --- round trip ------------------------------------------------------------------------------


def test_round_trip_is_identical(dataset, archive):
    back = open_study(archive)
    xr.testing.assert_identical(dataset, back)
    # assert_identical compares values, not dtypes: check those too.
    assert set(back.variables) == set(dataset.variables)
    for name, variable in dataset.variables.items():
        assert back[name].dtype == variable.dtype, name
    assert back["law"].values.tolist() == ["mcnamara", "cundall_strack"]
    assert back["law_class"].values.tolist() == ["hyperelastic", "strongly hypoelastic"]
    assert statuses(back) == statuses(dataset)
    assert back.attrs == dataset.attrs


def test_top_level_open_study_is_the_same_function(archive, dataset):
    xr.testing.assert_identical(ncstab.open_study(archive), dataset)


def test_events_survive_the_round_trip(dataset, archive):
    back = open_study(archive)
    case = {"law": "cundall_strack", "gamma": 0.5, "F2_lateral": 0.75}
    assert np.isfinite(back["hill_loss_s"].sel(case).item())
    assert back["hill_loss_stage"].sel(case).item() == 1
    np.testing.assert_array_equal(back["hill_loss_u"].sel(case).values, dataset["hill_loss_u"].sel(case).values)
    # Events not found are NaN (and stage -1), not zero.
    assert np.isnan(back["limit_point_s"].values).all()
    assert (back["limit_point_stage"].values == -1).all()


def test_an_opened_archive_is_in_memory_and_the_file_closed(dataset, archive):
    back = open_study(archive)
    archive.write_bytes(b"not a netcdf file any more")
    np.testing.assert_array_equal(back["u"].values, dataset["u"].values)


def test_writing_an_opened_archive_again_gives_the_same_archive(archive, tmp_path):
    first = open_study(archive)
    second = open_study(write_dataset(first, tmp_path / "again.nc"))
    xr.testing.assert_identical(first, second)


def test_a_study_with_cycles_round_trips(tmp_path):
    dataset = run_study(load_study(GOOD / "cycle.toml"))
    assert dataset.sizes["cycle"] == 2 and dataset["cycle_work"].dims == ("law", "radius", "cycle")
    back = open_study(write_dataset(dataset, tmp_path / "cycle.nc"))
    xr.testing.assert_identical(dataset, back)
    for name, variable in dataset.variables.items():
        assert back[name].dtype == variable.dtype, name


def test_a_pure_shear_study_runs_without_gamma_and_round_trips(tmp_path):
    study = parse_study(
        """
[study]
name = "pure_shear"
[system]
normal = "rigid"
alpha0 = "pi/4"
[laws]
names = ["mcnamara", "cundall_strack"]
[[loading]]
hold = { F2 = 0.0 }
drive = { F1 = 0.1 }
"""
    )
    dataset = run_study(study)
    assert dataset.attrs["force_unit"] == "2R k_t" and dataset.attrs["normal"] == "rigid"
    assert "2R k_t" in dataset["F"].attrs["description"]
    back = open_study(write_dataset(dataset, tmp_path / "pure_shear.nc"))
    xr.testing.assert_identical(dataset, back)


def test_an_archive_without_any_stored_state_round_trips(tmp_path):
    # Every case fails at the start of its first stage: zero stored states.
    study = parse_study(
        """
[study]
name = "nothing"
[system]
secondary_contacts = "ignore"
[laws]
names = ["mcnamara"]
[parameters]
gamma = [0.5, 1.0]
[[loading]]
hold = { F2 = 0.3 }
drive = { D1 = 0.1 }
"""
    )
    dataset = run_study(study)
    assert dataset.sizes["step"] == 0
    back = open_study(write_dataset(dataset, tmp_path / "nothing.nc"))
    xr.testing.assert_identical(dataset, back)
    assert back["status"].values.tolist() == [["failed:bad_stage_start"] * 2]


# --- what is in the file ---------------------------------------------------------------------


def test_the_file_is_compressed_and_self_describing(dataset, archive):
    with netCDF4.Dataset(archive) as nc:  # what ncdump -h shows
        assert nc.data_model == "NETCDF4"
        assert nc.getncattr("study") == dataset.attrs["study"]
        assert nc.getncattr("Conventions") == "CF-1.10"
        for name in ("u", "F", "K", "det_K", "hill", "stage"):
            filters = nc.variables[name].filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == COMPRESSION["complevel"], name
        for name in ("status", "message", "law", "law_class"):
            assert nc.variables[name].dtype is str, name  # NetCDF strings, readable as text
        described = [name for name in VARIABLES if name in nc.variables]
        assert len(described) >= 20
        for name in described:
            units, long_name, description = VARIABLES[name]
            variable = nc.variables[name]
            assert variable.getncattr("long_name") == long_name
            assert variable.getncattr("description") == description
            if units:
                assert variable.getncattr("units") == units
        assert nc.variables["gamma"].getncattr("units") == "1"
        assert nc.variables["status"][:].tolist() == dataset["status"].values.tolist()


def test_string_variables_are_plain_unicode_in_memory(dataset, archive):
    back = open_study(archive)
    for name in ("status", "message", "law", "law_class"):
        assert dataset[name].dtype.kind == "U" and back[name].dtype.kind == "U", name


# --- atomic writes ---------------------------------------------------------------------------


def test_write_creates_parent_directories_and_a_normal_file(dataset, tmp_path):
    path = write_dataset(dataset, tmp_path / "a" / "b" / "out.nc")
    assert path == tmp_path / "a" / "b" / "out.nc" and path.is_file()
    assert os.listdir(path.parent) == ["out.nc"]
    mask = os.umask(0o022)
    os.umask(mask)
    assert stat.S_IMODE(path.stat().st_mode) == 0o666 & ~mask


def test_an_unserialisable_attribute_leaves_no_file_and_spares_the_old_archive(dataset, archive):
    good = archive.read_bytes()
    bad = dataset.copy()
    bad.attrs["not_netcdf"] = {"a": 1}
    with pytest.raises(TypeError):
        write_dataset(bad, archive)
    assert archive.read_bytes() == good
    assert os.listdir(archive.parent) == [archive.name]
    with pytest.raises(TypeError):
        write_dataset(bad, archive.parent / "new.nc")
    assert os.listdir(archive.parent) == [archive.name]


@pytest.mark.parametrize("interruption", [RuntimeError("disk full"), KeyboardInterrupt()])
def test_an_interrupted_write_leaves_no_half_file(dataset, archive, monkeypatch, interruption):
    good = archive.read_bytes()
    temporaries = []

    def interrupted(self, path, *args, **kwargs):
        Path(path).write_bytes(b"half an archive")
        temporaries.append(Path(path))
        raise interruption

    monkeypatch.setattr(xr.Dataset, "to_netcdf", interrupted)
    with pytest.raises(type(interruption)):
        write_dataset(dataset, archive)
    assert temporaries and temporaries[0].parent == archive.parent and temporaries[0] != archive
    assert not temporaries[0].exists()
    assert archive.read_bytes() == good
    assert os.listdir(archive.parent) == [archive.name]


# --- failed cases ----------------------------------------------------------------------------


def test_a_case_of_a_sweep_is_the_case_run_alone(dataset, study):
    # Cases of a sweep are independent: neighbours that change stage at other
    # steps do not change a case.  Same steps, numbers equal to rounding
    # (1e-13: numpy's vectorised functions may round differently by array length).
    alone = parse_study(
        study.text.replace('names = ["mcnamara", "cundall_strack"]', 'names = ["mcnamara"]')
        .replace("gamma = [0.5, 2.0]", "gamma = 0.5")
        .replace("F2_lateral = [0.25, 0.75]", "F2_lateral = 0.75")
    )
    single = run_study(alone).isel(law=0)
    case = dataset.sel(law="mcnamara", gamma=0.5, F2_lateral=0.75)
    n = int(case["n_steps"])
    assert int(single["n_steps"]) == n
    assert str(single["status"].values) == str(case["status"].values)
    np.testing.assert_array_equal(single["stage"].values[:n], case["stage"].values[:n])
    for name in ("u", "F", "s", "K"):
        np.testing.assert_allclose(single[name].values[:n], case[name].values[:n], rtol=0, atol=1e-13)


def test_a_sweep_with_failed_cases_writes_every_other_case(dataset, archive):
    back = open_study(archive)
    n_steps = back["n_steps"]
    for (law, gamma, f2), status in statuses(back).items():
        case = {"law": law, "gamma": gamma, "F2_lateral": f2}
        n = int(n_steps.sel(case).item())
        message = str(back["message"].sel(case).item())
        u = back["u"].sel(case).values
        # Every case keeps the states it reached; padding after them is NaN.
        assert n >= 2
        assert np.isfinite(u[:n]).all() and np.isnan(u[n:]).all()
        stage = back["stage"].sel(case).values
        if status == "finished":
            assert message == "finished all 3 loading stage(s)"
            assert stage[n - 1] == 2
            assert abs(u[n - 1, 0] - 0.06) < 1e-9  # the last target, D1 = 0.05 + 1e-2
        elif status == "failed:bad_stage_start":
            assert "stage 3" in message and "F2" in message
            assert stage[n - 1] == 1  # kept its first two stages, ended there
            assert abs(u[n - 1, 0] - 0.05) < 1e-9
        else:
            assert status == "stopped:hill_loss" and "hill_loss" in message
            assert back["s"].sel(case).values[n - 1] == back["hill_loss_s"].sel(case).item()
    assert (back["stage"].values[np.isnan(back["s"].values)] == -1).all()


# --- docs/archive.md stays true --------------------------------------------------------------


def test_the_archive_page_describes_every_variable_as_the_dataset_does():
    from ncstab.paths.variables import EVENT_FIELDS

    text = (Path(__file__).parent.parent / "docs" / "archive.md").read_text(encoding="utf-8")

    def row(name: str) -> list[str]:
        match = re.search(rf"^\| `{re.escape(name)}` \|(.*)\|\s*$", text, re.MULTILINE)
        assert match, f"docs/archive.md has no row for {name}"
        return [cell.strip() for cell in match.group(1).split(" | ")]

    def unescape(cell: str) -> str:
        return cell.replace("\\|", "|").replace("&lt;", "<").replace("&gt;", ">")

    for name, (units, long_name, description) in VARIABLES.items():
        _, _, documented_units, documented_long_name, documented_description = row(name)
        assert documented_units == (f"`{units}`" if units else "—"), name
        assert unescape(documented_long_name) == long_name, name
        assert unescape(documented_description) == description, name
    for suffix, (units, long_name, description) in EVENT_FIELDS.items():
        _, _, documented_units, documented_long_name, _ = row(f"<event>_{suffix}")
        assert documented_units == f"`{units}`", suffix
        assert unescape(documented_long_name) == long_name.format(event="<event>"), suffix
