"""``load_level``: the load parameter under a name that works as an attribute.

``ds.load`` is xarray's ``Dataset.load`` method, so the archive's ``load`` variable
is read ``ds["load"]``; every new archive also holds it as ``load_level``, and an
archive written before it existed gets it on reading (issue 41).
"""

from __future__ import annotations

import numpy as np
import xarray as xr

from ncstab.studies import open_study, parse_study, run_study, write_dataset
from ncstab.studies.archive import LOAD_ALIAS

ZIEGLER = """
[study]
name = "ziegler_load_level"
[system]
name = "ziegler"
load = "follower"
[[loading]]
drive = { P = 1.0 }
"""


def _without_created(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    dataset.attrs.pop("created", None)
    return dataset


def test_new_archives_hold_the_load_under_both_names(tmp_path):
    ds = run_study(parse_study(ZIEGLER))
    assert callable(ds.load)  # xarray's method, not the variable
    assert LOAD_ALIAS == "load_level"
    np.testing.assert_array_equal(ds.load_level.values, ds["load"].values)  # the same numbers, NaN padding too
    assert ds.load_level.dims == ds["load"].dims
    assert ds.load_level.attrs["units"] == "1" and "Dataset.load" in ds.load_level.attrs["description"]
    write_dataset(ds, tmp_path / "new.nc")
    xr.testing.assert_identical(_without_created(open_study(tmp_path / "new.nc")), _without_created(ds))


def test_an_older_archive_reads_with_the_alias(tmp_path):
    ds = run_study(parse_study(ZIEGLER))
    write_dataset(ds.drop_vars(LOAD_ALIAS), tmp_path / "old.nc")  # as written before the alias
    back = open_study(tmp_path / "old.nc")
    np.testing.assert_array_equal(back.load_level.values, back["load"].values)
    xr.testing.assert_identical(back[LOAD_ALIAS], ds[LOAD_ALIAS])


def test_a_system_without_a_load_parameter_has_neither():
    ds = run_study(parse_study(ZIEGLER.replace('name = "ziegler"\nload = "follower"', 'name = "diamond"')
                               .replace("drive = { P = 1.0 }", "hold = { F2 = 0.0 }\ndrive = { D1 = 0.1 }")
                               .replace("[[loading]]", '[laws]\nnames = ["mcnamara"]\n[parameters]\ngamma = 1.0\n[[loading]]')))
    assert "load" not in ds.data_vars and LOAD_ALIAS not in ds.data_vars
