"""The archives pass a CF checker (issue 19): the IOOS compliance checker, CF-1.10.

Each kind of archive ncstab writes -- the reduced diamond with two laws and
chosen variables, cycle stages (Green's paradox), a general model with a load
parameter and inertia (Ziegler's follower load), and a ring of two laws with a
``contact`` dimension and every event table, streamed chunk by chunk -- is checked by
``compliance_checker`` (``cf:1.10``, every check, at every priority): every
scored check must score full marks.  The checker takes seconds on an archive
of some 100 variables (its checks are quadratic in their number; see the
fixture below for the two thirds of its time that are a cache missed), so the
kinds are few and each covers several features.

One check does not run on our archives: ``check_coordinate_variables_strict_monotonicity``
takes ``numpy.diff`` of every coordinate variable and raises on a string-valued
one (``law``, and the dof names of ``dof``, ``i``, ``j``), which CF-1.10 allows
as labels (NUG coordinate variables; CF 6.1).  The checker reports that as an
exception of its own, not as a failure; this test asserts that it is the only
one, and makes the check itself on the numeric coordinate variables.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import netCDF4
import numpy as np
import pytest

from ncstab.studies import load_study, parse_study, run_study, run_study_chunked, write_dataset

compliance_checker = pytest.importorskip("compliance_checker.runner", reason="pip install '.[test]'")

STUDIES = Path(__file__).resolve().parents[1] / "studies"

#: The reduced diamond, two laws, gamma swept, D1* driven far enough that limit
#: points, Hill's condition and controllability are lost; chosen variables only
#: (the lean archive's machinery).
CHOSEN = """
[study]
name = "cf_chosen"
[system]
secondary_contacts = "ignore"
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.5, 2.0]
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.6 }
[output]
figures = []
variables = ["u", "F", "det_K", "hill"]
"""
#: The checker's own exception (see the module docstring).
STRING_COORDINATES = "check_coordinate_variables_strict_monotonicity"


def _archive(kind: str, directory: Path) -> Path:
    path = directory / f"{kind}.nc"
    if kind == "chosen_variables":
        write_dataset(run_study(parse_study(CHOSEN)), path)
    elif kind == "ring_streamed":
        run_study_chunked(load_study(STUDIES / "ring_hexagonal.toml"), path, chunk_cases=1)
    else:
        write_dataset(run_study(load_study(STUDIES / f"{kind}.toml")), path)
    return path


@pytest.fixture(autouse=True)
def _geophysical_variables_found_once(monkeypatch):
    """The checker's ``_find_geophysical_vars`` means to cache its answer per dataset but
    looks it up under another key than it stores it (6.1.0: ``.get(ds)`` against
    ``[str(ds)]``), so it is derived again by each of nine checks: two thirds of the
    checker's time on our archives.  Cached here under one key (the answer depends on
    the open dataset alone, which no check changes)."""
    from compliance_checker.cf import cf_base, util

    def found_once(self, ds, refresh=False):
        key = ("ncstab", id(ds))
        if refresh or key not in self._geophysical_vars:
            self._geophysical_vars[key] = util.get_geophysical_variables(ds)
        return self._geophysical_vars[key]

    monkeypatch.setattr(cf_base.CFBaseCheck, "_find_geophysical_vars", found_once)


def _checker_results(path: Path):
    """The checker's results and its exceptions, for ``cf:1.10``."""
    suite = compliance_checker.CheckSuite()
    with warnings.catch_warnings():  # the checker's own dependencies warn on import
        warnings.simplefilter("ignore")
        suite.load_all_available_checkers()
        dataset = suite.load_dataset(str(path))
        try:
            results, errors = suite.run_all(dataset, ["cf:1.10"], skip_checks=[])["cf:1.10"]
        finally:
            dataset.close()
    return results, errors


def _short_of_full_marks(result) -> bool:
    value = result.value
    if isinstance(value, tuple):
        return value[0] != value[1]
    return value is not True


@pytest.mark.filterwarnings("ignore")
@pytest.mark.parametrize(
    "kind", ["chosen_variables", "green_paradox", "ziegler_follower", "ring_streamed"]
)
def test_an_archive_passes_the_cf_checker(kind: str, tmp_path: Path) -> None:
    path = _archive(kind, tmp_path)
    results, errors = _checker_results(path)
    assert len(results) > 10  # the checker ran its checks
    failures = {result.name: result.msgs for result in results if _short_of_full_marks(result)}
    assert failures == {}
    assert set(errors) <= {STRING_COORDINATES}, errors
    with netCDF4.Dataset(path) as handle:  # the check the checker could not make
        for name, variable in handle.variables.items():
            if name in handle.dimensions and variable.ndim == 1 and variable.dtype != str:
                step = np.diff(variable[:].astype(float))
                assert np.all(step > 0) or np.all(step < 0), name


def test_the_checker_finds_what_it_should(tmp_path: Path) -> None:
    """The test can fail: the same archive without its ``history`` and with a variable
    whose units CF does not know scores short of full marks, naming both."""
    path = _archive("chosen_variables", tmp_path)
    with netCDF4.Dataset(path, "a") as handle:
        handle.delncattr("history")
        handle.variables["det_K"].setncattr("units", "furlongs per fortnight squared")
    results, _ = _checker_results(path)
    messages = " ".join(" ".join(result.msgs) for result in results if _short_of_full_marks(result))
    assert "history" in messages
    assert "det_K" in messages
