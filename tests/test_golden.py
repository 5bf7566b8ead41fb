"""Golden archives: today's studies give the archives written before the general model.

``tests/golden/*.nc`` were written by ``tests/golden/make_golden.py`` from the
main branch before the model layer became general (issue 13).  Rerunning each
study must give an identical Dataset (``xarray.testing.assert_identical``:
values bit for bit, dimensions, coordinates and attributes), the ``created``
time stamp aside.  Any difference is a bug, or a decision documented in
CHANGELOG.md together with new golden files.
"""

from __future__ import annotations

from pathlib import Path

import pytest
import xarray as xr

from ncstab.studies import load_study, open_study, run_study
from ncstab.studies.archive import normalise_dataset

GOLDEN = Path(__file__).parent / "golden"
STUDIES = sorted((GOLDEN / "studies").glob("*.toml"))
#: Attributes that legitimately differ from run to run.
VOLATILE = ("created",)


def _without_volatile(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    for name in VOLATILE:
        dataset.attrs.pop(name, None)
    return dataset


@pytest.mark.parametrize("study_file", STUDIES, ids=[p.stem for p in STUDIES])
def test_a_study_gives_its_golden_archive(study_file: Path) -> None:
    study = load_study(study_file)
    golden = open_study(GOLDEN / f"{study.name}.nc")
    computed = normalise_dataset(run_study(study))
    xr.testing.assert_identical(_without_volatile(computed), _without_volatile(golden))
