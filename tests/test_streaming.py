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

import itertools
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
from ncstab.studies import streaming_encode
from ncstab.studies.streaming import ArchiveStream, BlockLayout, encode_chunk

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
def layouts(draw):
    shape = tuple(draw(st.lists(st.integers(1, 7), min_size=0, max_size=4)))
    max_cases = draw(st.integers(1, 40))
    return shape, max_cases


@settings(max_examples=300, deadline=None)
@given(layouts())
def test_blocks_are_boxes_that_tile_the_sweep_in_flat_order(case):
    """Every HDF5 chunk of a streamed archive must belong to one chunk of cases:
    blocks are flat runs that are also boxes of the sweep, aligned on the chunk
    grid, no larger than asked, and the runs of whole blocks cover every case once."""
    shape, max_cases = case
    layout = BlockLayout.for_grid(shape, max_cases)
    size = math.prod(shape)
    covered = []
    for block in layout.blocks(0, size):
        assert len(block.origin) == len(block.shape) == len(shape)
        if shape:
            flat = np.ravel_multi_index(
                np.meshgrid(*[np.arange(o, o + n) for o, n in zip(block.origin, block.shape)], indexing="ij"), shape
            ).ravel()
            assert all(o % c == 0 for o, c in zip(block.origin, layout.chunk)), "on the chunk grid"
            assert all(n <= c for n, c in zip(block.shape, layout.chunk))
        else:
            flat = np.array([0])
        assert np.array_equal(flat, np.arange(block.start, block.stop)), "a block is a flat run"
        assert block.stop - block.start <= max(max_cases, layout.tail)
        covered.extend(flat.tolist())
    assert covered == list(range(size))
    assert layout.block_cases <= max_cases or layout.extent == 1
    runs = layout.runs(max_cases)
    assert runs[0][0] == 0 and runs[-1][1] == size
    assert all(a[1] == b[0] for a, b in itertools.pairwise(runs))
    assert all(stop - start <= max(max_cases, layout.block_cases) for start, stop in runs)


def test_blocks_are_as_large_as_allowed():
    assert BlockLayout.for_grid((256, 256), 1024).chunk == (4, 256)
    assert BlockLayout.for_grid((64, 64), 1024).chunk == (16, 64)
    assert BlockLayout.for_grid((65537,), 1024).chunk == (1024,)  # a short last block
    assert BlockLayout.for_grid((3, 5, 7), 40).chunk == (1, 5, 7)
    assert BlockLayout.for_grid((), 10).chunk == ()


def test_a_run_that_cuts_a_block_is_refused():
    layout = BlockLayout.for_grid((4, 6), 12)  # blocks of 2 rows
    with pytest.raises(ValueError, match=r"cases 6:24 do not start on a block of 12 cases"):
        layout.blocks(6, 24)
    with pytest.raises(ValueError, match=r"cases 0:18 do not end on a block of 12 cases"):
        layout.blocks(0, 18)
    with pytest.raises(ValueError, match=r"cases 3:27 are not within a sweep of shape \(4, 6\)"):
        layout.blocks(3, 27)


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


def test_a_last_block_shorter_than_the_others_is_written_whole(tmp_path):
    """Three cases in blocks of two: the archive's last HDF5 chunk along the sweep
    reaches past the sweep, and only its first case is in the file."""
    study = parse_study(STUDIES["rigid"])
    output = tmp_path / "rigid.nc"
    run_study_chunked(study, output, chunk_cases=2)
    with netCDF4.Dataset(output) as nc:
        assert nc.variables["u"].chunking()[:2] == [1, 2]
    xr.testing.assert_identical(_without_time_stamp(open_study(output)), _without_time_stamp(_reference(study, tmp_path)))


def test_hdf5_chunks_that_split_steps_and_trailing_dimensions_read_back_whole(tmp_path, monkeypatch):
    """With HDF5 chunks of about 6 elements, ``step``, ``theta`` (8 values) and
    ``map_D2`` (4 values) are cut into windows of 3, the last one short: the
    encoder pads it, the archive holds exactly the values."""
    monkeypatch.setattr(streaming_encode, "CHUNK_ELEMENTS", 6)
    study = parse_study(STUDIES["maps"])
    output = tmp_path / "maps.nc"
    run_study_chunked(study, output, chunk_cases=3)
    with netCDF4.Dataset(output) as nc:
        def chunking(name):
            return dict(zip(nc.variables[name].dimensions, nc.variables[name].chunking()))

        assert chunking("d2W_dir")["theta"] == 3 and chunking("map_hill")["map_D2"] == 3
        assert chunking("hill")["step"] == 3
    xr.testing.assert_identical(_without_time_stamp(open_study(output)), _without_time_stamp(_reference(study, tmp_path)))


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


def _stream(study, path):
    grid = ParameterGrid.from_mapping(study.parameters)
    return ArchiveStream(path, tuple(study.laws), grid, BlockLayout.for_grid(grid.shape, 4)), tuple(grid.sweep)


def test_a_chunk_of_the_wrong_size_is_refused(tmp_path):
    study = parse_study(STUDIES["three_dims"])
    chunk = run_chunk(study, "weakly_hypoelastic", 0, 3)
    stream, sweep = _stream(study, tmp_path / "a.nc")
    with pytest.raises(ValueError, match=r"a chunk of cases 0:4 needs dimensions law = 1 and case = 4"):
        encode_chunk(chunk, "weakly_hypoelastic", 0, 4, stream.layout, sweep)
    with pytest.raises(ValueError, match=r"cases 0:3 do not end on a block of 4 cases"):
        encode_chunk(chunk, "weakly_hypoelastic", 0, 3, stream.layout, sweep)


def test_closing_before_every_law_is_in_is_refused(tmp_path):
    study = parse_study(STUDIES["maps"])
    stream, sweep = _stream(study, tmp_path / "a.nc")
    stream.append(encode_chunk(run_chunk(study, "mcnamara", 0, 4), "mcnamara", 0, 4, stream.layout, sweep))
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

    Peak of traced allocations (numpy's included).  Measured: 1.231 MB for
    one chunk of 64 cases, 1.266 MB for four (1.03x; with the hyperslab writes
    this layout replaced, 1.013 and 1.081 MB); the in-process run,
    which holds every case, goes from 1.01 MB to 2.71 MB (2.7x), as did the
    whole-archive assembly this replaced, and a loop that keeps the previous
    chunk while computing the next (found by this test) gave 1.5x.  The bound
    (1.3x) leaves room for allocator noise and catches either.
    """
    _peak_of_chunked_run(_sweep_of_copies(1, 64), tmp_path / "warm.nc", 64)  # compile the law first
    one = _peak_of_chunked_run(_sweep_of_copies(1, 64), tmp_path / "one.nc", 64)
    four = _peak_of_chunked_run(_sweep_of_copies(4, 64), tmp_path / "four.nc", 64)
    assert four < 1.3 * one, (one, four)
