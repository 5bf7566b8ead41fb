"""The archive written chunk by chunk (ncstab.studies.streaming) is the in-process archive.

Each study below exercises one shape of archive: cycles (the ``cycle``
dimension and its auxiliary coordinates), maps (``theta``, ``map_D1``,
``map_D2``), the pure-shear limit, a single case (no swept dimension) and three
swept dimensions whose chunk borders fall inside rows.  The streamed archive
must be identical -- bit for bit, ``xarray.testing.assert_identical``, not a
tolerance -- to the archive of the plain in-process run, but for the
``created`` time stamp.
"""

from __future__ import annotations

import math
import tracemalloc

import netCDF4
import numpy as np
import pytest
import xarray as xr
from hypothesis import given, settings
from hypothesis import strategies as st

from ncstab.paths import ParameterGrid
from ncstab.studies import open_study, parse_study, run_study, run_study_chunked, write_dataset
from ncstab.studies.archive import COMPRESSION
from ncstab.studies.chunked import run_chunk
from ncstab.studies.streaming import ArchiveStream, hyperslabs

PREAMBLE = """
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
"""
TWO_STAGES = """
[[loading]]
hold = { F1 = 0.0 }
drive = { F2 = "F2_lateral" }
[[loading]]
hold = { F2 = "current" }
drive = { D1 = 0.1 }
[options]
max_step = 0.05
"""
STUDIES = {
    "cycles": """
[study]
name = "cycles"
[system]
alpha0 = "pi/4"
secondary_contacts = "ignore"
[laws]
names = ["cundall_strack", "mcnamara"]
[parameters]
gamma = 0.5
radius = [0.02, 0.05, 0.1]
[[loading]]
cycle = { center = ["radius", 0.0], turns = 2, direction = 1 }
[[loading]]
cycle = { center = ["radius", 0.0], turns = 1, direction = -1 }
[options]
max_step = 0.5
""",
    "maps": """
[study]
name = "maps"
""" + PREAMBLE + """
[laws]
names = ["weakly_hypoelastic", "mcnamara"]
[parameters]
gamma = [0.5, 1.0]
F2_lateral = [0.5, 0.75]
""" + TWO_STAGES + """
[map]
directions = 8
grid = { D1 = [-0.1, 0.3, 5], D2 = [0.0, 0.3, 4] }
""",
    "rigid": """
[study]
name = "rigid"
[system]
normal = "rigid"
secondary_contacts = "activate"
[laws]
names = ["cundall_strack", "turco"]
[parameters]
alpha0 = [0.7, 0.785398, 0.9]
[[loading]]
hold = { F2 = 0.0 }
drive = { F1 = 1.0 }
""",
    "single": """
[study]
name = "single"
""" + PREAMBLE + """
[laws]
names = ["turco"]
[parameters]
gamma = 0.5
F2_lateral = 0.3
""" + TWO_STAGES,
    "three_dims": """
[study]
name = "three_dims"
[system]
secondary_contacts = "ignore"
[laws]
names = ["weakly_hypoelastic"]
[parameters]
alpha0 = [0.7, 0.8]
gamma = [0.5, 1.0, 2.0]
F2_lateral = [0.0, 0.2]
""" + TWO_STAGES,
}


@st.composite
def ranges(draw):
    shape = tuple(draw(st.lists(st.integers(1, 5), min_size=0, max_size=4)))
    size = math.prod(shape)
    start = draw(st.integers(0, size))
    stop = draw(st.integers(start, size))
    return shape, start, stop


@settings(max_examples=300, deadline=None)
@given(ranges())
def test_hyperslabs_cover_exactly_the_cases_in_order(case):
    shape, start, stop = case
    covered = []
    boxes = list(hyperslabs(start, stop, shape))
    for first, box in boxes:
        assert len(box) == len(shape)
        flat = np.ravel_multi_index(
            np.meshgrid(*[np.arange(s.start, s.stop) for s in box], indexing="ij"), shape
        ).ravel() if shape else np.array([0])
        assert flat[0] == first and np.array_equal(flat, np.arange(first, first + flat.size)), "a box is a flat run"
        covered.extend(flat.tolist())
    assert covered == list(range(start, stop))
    assert len(boxes) <= max(1, 2 * len(shape) - 1)


def test_hyperslabs_refuse_a_range_outside_the_array():
    with pytest.raises(ValueError, match=r"cases 3:7 are not within an array of shape \(2, 3\)"):
        list(hyperslabs(3, 7, (2, 3)))


def _reference(study, directory):
    path = directory / f"{study.name}_reference.nc"
    write_dataset(run_study(study), path)
    return open_study(path)


def _without_time_stamp(dataset: xr.Dataset) -> xr.Dataset:
    dataset = dataset.copy()
    assert dataset.attrs.pop("created")
    return dataset


@pytest.mark.parametrize("name", sorted(STUDIES))
@pytest.mark.parametrize("chunk_cases", [1, 4])
def test_a_streamed_archive_is_the_in_process_archive(name, chunk_cases, tmp_path):
    study = parse_study(STUDIES[name])
    reference = _reference(study, tmp_path)
    output = tmp_path / "out" / f"{name}.nc"
    run_study_chunked(study, output, chunk_cases=chunk_cases)
    xr.testing.assert_identical(_without_time_stamp(open_study(output)), _without_time_stamp(reference))
    assert [p.name for p in output.parent.iterdir()] == [output.name], "no part or temporary is left"


def test_the_steps_past_a_short_case_read_nan_and_its_stages_minus_one(tmp_path):
    study = parse_study(STUDIES["three_dims"])
    output = tmp_path / "three.nc"
    run_study_chunked(study, output, chunk_cases=5)
    archive = open_study(output)
    n_steps = archive["n_steps"].values
    assert np.unique(n_steps).size > 1, "cases of different lengths, or padding goes untested"
    padded = np.arange(archive.sizes["step"]) >= n_steps[..., None]
    assert np.all(np.isnan(archive["u"].values[padded]))
    assert np.all(archive["stage"].values[padded] == -1)
    assert np.all(archive["stage"].values[~padded] >= 0)
    with netCDF4.Dataset(output) as nc:  # compressed as write_dataset compresses, step unlimited
        assert nc.dimensions["step"].isunlimited()
        for name in ("u", "K", "stage"):
            filters = nc.variables[name].filters()
            assert filters["zlib"] and filters["shuffle"] and filters["complevel"] == COMPRESSION["complevel"], name


def test_a_chunk_of_the_wrong_size_is_refused(tmp_path):
    study = parse_study(STUDIES["three_dims"])
    chunk = run_chunk(study, "weakly_hypoelastic", 0, 3)
    stream = ArchiveStream(tmp_path / "a.nc", ("weakly_hypoelastic",), ParameterGrid.from_mapping(study.parameters))
    with pytest.raises(ValueError, match=r"a chunk of cases 0:4 needs dimensions law = 1 and case = 4"):
        stream.append(chunk, "weakly_hypoelastic", 0, 4)
    stream.abort()


def test_closing_before_every_law_is_in_is_refused(tmp_path):
    study = parse_study(STUDIES["maps"])
    stream = ArchiveStream(tmp_path / "a.nc", tuple(study.laws), ParameterGrid.from_mapping(study.parameters))
    stream.append(run_chunk(study, "mcnamara", 0, 4), "mcnamara", 0, 4)
    with pytest.raises(ValueError, match="no chunk of law.s. weakly_hypoelastic was appended"):
        stream.close()
    stream.abort()


def _peak_of_chunked_run(study_text: str, path, chunk_cases: int) -> int:
    study = parse_study(study_text)
    tracemalloc.start()
    try:
        run_study_chunked(study, path, chunk_cases=chunk_cases)
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def _sweep_of_copies(copies: int, cases: int) -> str:
    """``copies`` near-identical rows (alpha0 apart by 1e-7) of ``cases`` cases each."""
    gamma = [round(0.5 + 0.02 * k, 3) for k in range(cases)]
    alpha0 = [round(0.8 + 1e-7 * k, 8) for k in range(copies)]
    return (
        STUDIES["three_dims"]
        .replace("alpha0 = [0.7, 0.8]", f"alpha0 = {alpha0}")
        .replace("gamma = [0.5, 1.0, 2.0]", f"gamma = {gamma}")
        .replace("F2_lateral = [0.0, 0.2]", "F2_lateral = [0.0]")
        .replace("max_step = 0.05", "max_step = 0.02")
    )


def test_the_memory_of_a_chunked_run_does_not_grow_with_the_sweep(tmp_path):
    """Four chunks of the same cases hold no more memory than one.

    Peak of traced allocations (numpy's included).  Measured: 1.013 MB for
    one chunk of 64 cases, 1.081 MB for four (1.07x); the in-process run,
    which holds every case, goes from 1.01 MB to 2.71 MB (2.7x), as did the
    whole-archive assembly this replaced, and a loop that keeps the previous
    chunk while computing the next (found by this test) gave 1.5x.  The bound
    (1.3x) leaves room for allocator noise and catches either.
    """
    _peak_of_chunked_run(_sweep_of_copies(1, 64), tmp_path / "warm.nc", 64)  # compile the law first
    one = _peak_of_chunked_run(_sweep_of_copies(1, 64), tmp_path / "one.nc", 64)
    four = _peak_of_chunked_run(_sweep_of_copies(4, 64), tmp_path / "four.nc", 64)
    assert four < 1.3 * one, (one, four)
