"""``ncstab analyse`` (issue 38): the archive's contract, exit codes, and the 10,000-grain bar.

The archive's K (coordinate form) is checked against the library's K exactly
(same numbers written and read: 0 difference), and its Hill eigenvalue
against an independent ``scipy.sparse.linalg.eigsh`` of the archived K_sym to
1e-6 (the issue's bar; ARPACK at tol 1e-12 on an O(1) spectrum).
"""

from __future__ import annotations

import time
from pathlib import Path

import netCDF4
import numpy as np
import pytest
import scipy.sparse.linalg as splinalg
import xarray as xr
from scipy import sparse

from ncstab.cli import main
from ncstab.systems.packing import triangular_lattice, write_packing


def _write_raw(path: Path, **values) -> Path:
    """A packing file written variable by variable (malformed ones included)."""
    with netCDF4.Dataset(path, "w") as handle:
        handle.createDimension("grain", len(values["x"]))
        handle.createDimension("contact", len(values["grain_a"]))
        for name, array in values.items():
            dim = "grain" if name in ("x", "y", "radius", "fixed") else "contact"
            array = np.asarray(array)
            handle.createVariable(name, array.dtype, (dim,))[:] = array
    return path


GOOD = {"x": np.array([0.0, 1.0, 0.5]), "y": np.array([0.0, 0.0, 0.9]), "radius": np.full(3, 0.5),
        "fixed": np.array([1, 0, 0], dtype=np.int8), "grain_a": np.array([0, 1, 0], dtype=np.int32),
        "grain_b": np.array([1, 2, 2], dtype=np.int32)}


@pytest.mark.parametrize("name, value, words", [
    ("grain_b", np.array([1, 7, 2], dtype=np.int32), ["'grain_b'", "entry 1", "7"]),
    ("grain_a", np.array([0, 2, 0], dtype=np.int32), ["'grain_b'", "entry 1", "itself"]),
    ("radius", np.array([0.5, 0.5, -0.1]), ["'radius'", "entry 2", "-0.1"]),
    ("y", np.array([0.0, np.nan, 0.9]), ["'y'", "entry 1", "nan"]),
])
def test_a_malformed_packing_is_exit_2_naming_the_variable_and_entry(tmp_path, monkeypatch, capsys, name, value,
                                                                     words) -> None:
    monkeypatch.chdir(tmp_path)
    _write_raw(tmp_path / "bad.nc", **{**GOOD, name: value})
    assert main(["analyse", "bad.nc", "--law", "mcnamara"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert all(word in err for word in words), err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.nc"]  # nothing written


def test_missing_variables_unknown_laws_and_unwritable_outputs(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    values = dict(GOOD)
    del values["fixed"]
    _write_raw(tmp_path / "nofixed.nc", **values)
    assert main(["analyse", "nofixed.nc", "--law", "mcnamara"]) == 2
    assert "'fixed' is missing" in capsys.readouterr().err
    _write_raw(tmp_path / "good.nc", **GOOD)
    assert main(["analyse", "good.nc", "--law", "no_such_law"]) == 2
    assert "--law" in capsys.readouterr().err
    assert main(["analyse", "missing.nc", "--law", "mcnamara"]) == 2
    assert "no such packing file: missing.nc" in capsys.readouterr().err
    (tmp_path / "afile").write_text("")
    assert main(["analyse", "good.nc", "--law", "mcnamara", "-o", "afile/out.nc"]) == 3
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "afile" in err
    assert not (tmp_path / "results").exists()


def test_the_archive_has_the_contract_variables_with_their_attributes(tmp_path, monkeypatch, capsys) -> None:
    from ncstab.laws.registry import law_definition
    from ncstab.operators.packing_analysis import packing_tangent
    from ncstab.systems.packing import read_packing

    monkeypatch.chdir(tmp_path)
    packing = triangular_lattice(5, 6, fix_bottom=True, jitter=0.1)
    rng = np.random.default_rng(4)
    packing = packing.with_forces(rng.uniform(0, 0.05, packing.n_contacts), rng.uniform(-0.01, 0.01, packing.n_contacts))
    write_packing(packing, tmp_path / "lattice.nc")
    assert main(["analyse", "lattice.nc", "--law", "cundall_strack", "--gamma", "0.5", "--modes", "3"]) == 0
    archive = tmp_path / "results" / "lattice_analysis.nc"
    assert str(archive.relative_to(tmp_path)) in capsys.readouterr().out
    with xr.open_dataset(archive) as ds:
        for name in ["hill", "negative_eigenvalues", "zero_eigenvalues", "det_K_sign", "mode_eigenvalue", "mode",
                     "participation", "K_row", "K_col", "K_value"]:
            assert name in ds.variables, name
        for name, variable in ds.variables.items():
            assert {"units", "long_name", "description"} <= set(variable.attrs), name
        assert "tolerance" in ds.negative_eigenvalues.attrs and "tolerance" in ds.zero_eigenvalues.attrs
        assert ds.mode.dims == ("mode", "grain", "component") and ds.mode.shape == (3, packing.n_grains, 3)
        assert ds.participation.dims == ("mode", "grain")
        n = 3 * int(np.sum(~packing.fixed))
        K = sparse.coo_matrix((ds.K_value.values, (ds.K_row.values, ds.K_col.values)), shape=(n, n)).toarray()
        hill = float(ds.hill)
        modes = ds.mode.values[:, ~packing.fixed].reshape(3, -1)
        values = ds.mode_eigenvalue.values
    expected = packing_tangent(read_packing(tmp_path / "lattice.nc"), law_definition("cundall_strack"), 0.5).K
    assert np.array_equal(K, expected.toarray())
    S = (K + K.T) / 2
    assert abs(hill - np.linalg.eigvalsh(S)[0]) <= 1e-10
    assert np.allclose(S @ modes.T, modes.T * values, atol=1e-10)


def test_ncstab_analyse_lazily_exported(tmp_path) -> None:
    import ncstab

    ds = ncstab.analyse(triangular_lattice(4, 4), "mcnamara", 1.0, modes=4)
    assert int(ds.zero_eigenvalues) == 3 and int(ds.negative_eigenvalues) == 0


def test_ten_thousand_grains_hill_equals_an_independent_eigsh(tmp_path, monkeypatch, capsys) -> None:
    """The issue's bar: 10,000 grains, bottom row fixed; the archived hill against eigsh of the archived K."""
    monkeypatch.chdir(tmp_path)
    packing = triangular_lattice(100, 100, fix_bottom=True)
    rng = np.random.default_rng(1)
    packing = packing.with_forces(np.full(packing.n_contacts, 0.01), rng.choice([-0.002, 0.002], packing.n_contacts))
    write_packing(packing, tmp_path / "big.nc")
    start = time.perf_counter()
    assert main(["analyse", "big.nc", "--law", "cundall_strack", "--gamma", "0.5", "-o", "big_out.nc"]) == 0
    elapsed = time.perf_counter() - start
    with xr.open_dataset(tmp_path / "big_out.nc") as ds:
        n = ds.sizes["dof"]
        K = sparse.csc_matrix((ds.K_value.values, (ds.K_row.values, ds.K_col.values)), shape=(n, n))
        hill = float(ds.hill)
    assert n == 3 * 9900
    S = ((K + K.T) / 2).tocsc()
    independent = splinalg.eigsh(S, k=1, sigma=-1e-3, which="LM", return_eigenvectors=False)[0]
    assert abs(hill - independent) <= 1e-6
    assert elapsed <= 20.0  # the whole analysis in this process (the command's own bar includes start-up)


def test_loops_in_the_archive_are_ranked_by_their_hill_eigenvalue(tmp_path, capsys) -> None:
    """``--loops``: loop_hill ascending, each loop's grains, against the library's loop analysis."""
    from ncstab.laws.registry import law_definition
    from ncstab.operators.packing_analysis import packing_tangent
    from ncstab.systems.mesostructures import grain_loops, loop_stiffness

    packing = triangular_lattice(4, 5, fix_bottom=True, jitter=0.05)
    packing = packing.with_forces(np.full(packing.n_contacts, 0.3), np.zeros(packing.n_contacts))
    write_packing(packing, tmp_path / "p.nc")
    assert main(["analyse", str(tmp_path / "p.nc"), "--law", "mcnamara", "--gamma", "0.1", "--loops",
                 "-o", str(tmp_path / "out.nc")]) == 0
    assert "grain loops" in capsys.readouterr().out
    with xr.open_dataset(tmp_path / "out.nc") as ds:
        hill, grains = ds.loop_hill.values, ds.loop_grains.values
        for name in ("loop_hill", "loop_length", "loop_grains"):
            assert {"units", "long_name", "description"} <= set(ds[name].attrs)
    loops = grain_loops(packing)
    expected = loop_stiffness(packing, loops, packing_tangent(packing, law_definition("mcnamara"), 0.1).blocks)
    assert np.array_equal(hill, np.sort(expected)) and np.all(np.diff(hill) >= 0)
    assert sorted(map(tuple, grains.tolist())) == sorted(map(tuple, loops.padded().tolist()))
