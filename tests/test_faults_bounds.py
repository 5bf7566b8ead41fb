"""The fault catalogue, bounded work and input validation: packings too big to analyse,
direction files too long or lying in their header, a cache that cannot be written, DEM
files that are junk.  Each ends in one line and a documented exit code
(docs/when-things-go-wrong.md, "Limits"); the Python API raises a named error."""

from __future__ import annotations

import os

import netCDF4
import numpy as np
import pytest
from fault_helpers import assert_one_line, run_cli

import ncstab.sizes as sizes_module
from ncstab.operators import analysis_size
from ncstab.operators.packing_directions import MAX_DIRECTIONS
from ncstab.systems.packing import PackingError, triangular_lattice, write_packing
from ncstab.systems.packing_readers import read_csv, read_dump, read_lammps, read_yade


@pytest.fixture
def lattice(tmp_path):
    """A 3 x 3 triangular lattice, its bottom row held."""
    packing = triangular_lattice(3, 3, fix_bottom=True)
    return write_packing(packing, tmp_path / "p.nc"), packing


# --- packings too big: estimated before any factorization -----------------------------------------

def test_a_packing_that_cannot_fit_the_memory_is_refused_naming_it_and_the_estimate(lattice, monkeypatch, capfd):
    path, packing = lattice
    # 1 MB available: the model's 200 MB constant alone exceeds it
    monkeypatch.setattr(sizes_module, "available_memory", lambda: 1_000_000)
    code, out, err = run_cli(["analyse", path, "--law", "mcnamara", "-o", path.parent / "a.nc"], capfd)
    assert code == 2
    assert_one_line(err, "p.nc", r"\d GB of memory", "available")
    assert not (path.parent / "a.nc").exists()


def test_a_long_analysis_says_how_long_on_one_line(lattice, monkeypatch, capfd):
    path, _ = lattice
    monkeypatch.setattr(analysis_size, "ANNOUNCED_SECONDS", 0.0)
    code, out, err = run_cli(["analyse", path, "--law", "mcnamara", "-o", path.parent / "a.nc"], capfd)
    assert code == 0
    assert_one_line(err, "p.nc", "takes about", "estimate")


def test_the_cost_model_reproduces_its_measurements():
    # the table of the module's docstring: within the factor 3 the estimate promises
    for dofs, seconds, peak in ((29_700, 4.4, 321e6), (119_400, 26.5, 1_038e6)):
        cost = analysis_size.analysis_cost(dofs)
        assert seconds / 3 < cost.seconds < 3 * seconds, cost
        assert peak / 3 < cost.memory_bytes < 3 * peak
    # ten million grains (30 million dofs): hundreds of GB, refused on any ordinary machine
    assert analysis_size.analysis_cost(30_000_000).memory_bytes > 200e9


def test_modes_over_the_limit_are_refused(lattice, capfd):
    path, _ = lattice
    code, _, err = run_cli(["analyse", path, "--law", "mcnamara", "--modes", analysis_size.MAX_MODES + 1], capfd)
    assert code == 2
    assert_one_line(err, "--modes", str(analysis_size.MAX_MODES))


def test_a_fill_value_in_a_packing_is_refused_naming_the_variable_and_entry(tmp_path, capfd):
    path = tmp_path / "fill.nc"
    with netCDF4.Dataset(path, "w") as handle:
        handle.createDimension("grain", 3)
        handle.createDimension("contact", 1)
        for name in ("x", "y", "radius"):
            handle.createVariable(name, "f8", ("grain",))[:] = [0.0, 1.0, 0.5] if name != "radius" else 0.5
        handle.variables["y"][2] = np.ma.masked  # never written: the fill value 9.97e36
        handle.createVariable("fixed", "i1", ("grain",))[:] = [1, 0, 0]
        handle.createVariable("grain_a", "i4", ("contact",))[:] = [0]
        handle.createVariable("grain_b", "i4", ("contact",))[:] = [1]
    code, _, err = run_cli(["analyse", path, "--law", "mcnamara"], capfd)
    assert code == 2
    assert_one_line(err, "fill.nc", "'y'", "entry 2", "fill")


# --- directions: bounded, checked from the header -------------------------------------------------

def test_too_many_csv_directions_are_refused_naming_the_file_and_limit(lattice, capfd):
    path, packing = lattice
    name = packing.dof_names()[0]
    directions = path.parent / "d.csv"
    directions.write_text(f"{name}\n" + "1\n" * (MAX_DIRECTIONS + 1))
    code, _, err = run_cli(["analyse", path, "--law", "mcnamara", "--directions", directions], capfd)
    assert code == 2
    assert_one_line(err, "d.csv", f"{MAX_DIRECTIONS + 1} directions", f"limit of {MAX_DIRECTIONS}")


def _npy_header(path, shape, descr="<f8"):
    """A .npy file of a header only (its data never written): what a lying header looks like."""
    with open(path, "wb") as handle:
        np.lib.format.write_array_header_1_0(handle, {"descr": descr, "fortran_order": False, "shape": shape})
    return path


def test_a_npy_header_claiming_a_billion_rows_is_refused_before_allocating(lattice, capfd):
    path, packing = lattice
    directions = _npy_header(path.parent / "d.npy", (10 ** 9, packing.n_dof))
    code, _, err = run_cli(["analyse", path, "--law", "mcnamara", "--directions", directions], capfd)
    assert code == 2
    assert_one_line(err, "d.npy", "1000000000 directions", "limit")


def test_a_complex_npy_of_directions_is_refused(lattice, capfd):
    path, packing = lattice
    directions = path.parent / "c.npy"
    np.save(directions, np.ones((1, packing.n_dof)) * (1 + 1j))
    code, _, err = run_cli(["analyse", path, "--law", "mcnamara", "--directions", directions], capfd)
    assert code == 2
    assert_one_line(err, "c.npy", "complex")


# --- the cache -----------------------------------------------------------------------------------

def test_cache_compile_with_the_cache_dir_a_file_fails_at_once(tmp_path, monkeypatch, capfd):
    import time

    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(blocker))
    start = time.monotonic()
    code, _, err = run_cli(["cache", "compile"], capfd)
    assert code == 3
    assert time.monotonic() - start < 5  # compiling takes minutes: nothing was compiled
    assert_one_line(err, "a-file", "nothing can be cached")
    assert blocker.read_text() == "not a folder"


# --- the DEM readers' Python API: PackingError naming the file and line -------------------------

DUMP = "ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n2\nITEM: ATOMS id type x y radius\n1 1 0 0 0.5\n{row}\n"


@pytest.mark.parametrize("reader, text, words", [
    (read_lammps, DUMP.format(row="2 1 1 0 x"), ["line 7", "2 1 1 0 x"]),
    (read_lammps, DUMP.format(row="2 1 1"), ["line 7", "3 values"]),
    (read_lammps, b"\xff\xfe\x00junk", ["line 1", "UTF-8"]),
    (lambda path: read_dump(path, timestep=3), "ITEM: TIMESTEP\n", ["line 2", "timestep"]),
    (read_yade, b"B 1 0 0 \xff", ["UTF-8"]),
    (read_csv, "x,y,radius\n", ["no grains"]),
    (read_csv, "x,y,radius\n0,0,0.5\n# a comment\n1,0,zz\n", ["line 4", "zz"]),
    (read_csv, "id,x,y,radius\n1.5,0,0,0.5\n2,1,0,0.5\n", ["grain id 1.5", "not an integer"]),
], ids=["junk-field", "short-row", "binary", "truncated", "yade-binary", "header-only", "csv-junk", "fractional-id"])
def test_junk_dem_files_raise_a_packing_error_naming_file_and_line(tmp_path, reader, text, words):
    path = tmp_path / "dem.txt"
    if isinstance(text, bytes):
        path.write_bytes(text)
    else:
        path.write_text(text)
    with pytest.raises(PackingError) as caught:
        reader(path)
    message = str(caught.value)
    assert "dem.txt" in message
    for word in words:
        assert word in message, message


def test_reading_a_fifo_is_refused_without_blocking(tmp_path):
    fifo = tmp_path / "grains.csv"
    os.mkfifo(fifo)
    with pytest.raises(PackingError, match="not a regular file"):
        read_csv(fifo)  # would block forever if it were opened
