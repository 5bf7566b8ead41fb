"""Second-order work of given directions and the exact unstable cone in a plane of a packing's dofs (issue 38).

Tolerances, and why:

* ``direction_d2W`` against d . (K d) from the archived K (scipy.sparse, written
  here): the same sums in another order, each of O(1) terms rounded at 1e-16:
  1e-12 relative;
* against the closed form of a free grain on a held one (K written by hand
  from the contact kinematics, seed Eq. 30-34): entries of a few O(1) terms:
  1e-12 relative, and the cone's bounds (roots of a quadratic with a simple
  root) 1e-12 rad;
* d2W at the cone's bounds evaluated with the full K: the root of
  m + r cos(2t - 2 phi) is exact in the 2 x 2 form, and the form is E^T K E up
  to n rounding errors of O(|K|): 1e-10 (the issue's bar) on O(1) entries.
"""

from __future__ import annotations

import numpy as np
import pytest
import xarray as xr
from scipy import sparse

import ncstab
from ncstab.cli import main
from ncstab.operators.packing_directions import DirectionsError
from ncstab.systems.packing import Packing, triangular_lattice, write_packing

D, N, T, RA, RB = 0.88, 0.3, 0.05, 0.5, 0.4


def _two_grains(normal: float = N, tangential: float = T) -> Packing:
    """Grain 0 held at the origin, grain 1 free above it at distance D (branch angle pi/2)."""
    return Packing(np.array([0.0, 0.0]), np.array([0.0, D]), np.array([RA, RB]), np.array([True, False]),
                   np.array([[0, 1]]), np.array([normal]), np.array([tangential]))


def _two_grain_K(law: str, gamma: float) -> np.ndarray:
    """K of the free grain (x1, y1, theta1), by hand.

    J_l = (0, 1/rho, 0), J_beta = (-1/D, 0, -c) with c = r_b/(r_a + r_b); H_l = e_x e_x^T/(rho D),
    H_beta = (e_x e_y^T + e_y e_x^T)/D^2; Q* = (-N/rho, D T/rho^2), rho = D + N;
    K = rho^2 (J^T D* J + Q*_l H_l + Q*_beta H_beta) with D* = diag(1, gamma) (McNamara, the Hessian of its
    energy) or [[1, 0], [T*, gamma l^2]] (Cundall-Strack).
    """
    rho, c = D + N, RB / (RA + RB)
    if law == "mcnamara":
        g = gamma * rho**2
        return np.array([[g / D**2 - N / D, T / D, g * c / D], [T / D, 1.0, 0.0], [g * c / D, 0.0, g * c**2]])
    return np.array([[gamma - N / D, 0.0, gamma * D * c], [T / D, 1.0, 0.0],
                     [gamma * D * c, -T * c, gamma * D**2 * c**2]])


def _lattice(rows: int = 4, normal: float = 0.2) -> Packing:
    packing = triangular_lattice(rows, rows + 1 if rows < 10 else rows, fix_bottom=True, jitter=0.05)
    rng = np.random.default_rng(3)
    return packing.with_forces(np.full(packing.n_contacts, normal),
                               rng.uniform(-0.3, 0.3, packing.n_contacts) * normal)


def _archived_K(ds: xr.Dataset):
    n = ds.sizes["dof"]
    return sparse.csr_matrix((ds.K_value.values, (ds.K_row.values, ds.K_col.values)), shape=(n, n))


def _over_dofs(ds: xr.Dataset, name: str, fixed: np.ndarray) -> np.ndarray:
    """A (..., grain, component) variable over the free dofs, (..., n)."""
    values = ds[name].values[..., ~fixed, :]
    return values.reshape(*values.shape[:-2], -1)


def test_direction_d2W_equals_d_K_d_of_the_archived_K(tmp_path, capsys) -> None:
    """CSV (named dofs, the others 0) and .npy directions, against an independent d . K d."""
    packing = _lattice()
    write_packing(packing, tmp_path / "p.nc")
    rng = np.random.default_rng(8)
    names = packing.dof_names()
    rows = rng.normal(size=(5, packing.n_dof)) * rng.choice([1e-3, 1.0, 1e3], size=(5, 1))
    np.save(tmp_path / "d.npy", rows)
    (tmp_path / "d.csv").write_text(
        "# a comment line\nname,x7,theta7,y12,x13\nshear,1,0,0,-1\nroll,0.5,-2,,\n\nlift,0,0,1e-3,0\n")
    assert main(["analyse", str(tmp_path / "p.nc"), "--law", "cundall_strack", "--directions",
                 str(tmp_path / "d.npy"), "-o", str(tmp_path / "npy.nc")]) == 0
    assert "5 directions" in capsys.readouterr().out
    assert main(["analyse", str(tmp_path / "p.nc"), "--law", "cundall_strack", "--directions",
                 str(tmp_path / "d.csv"), "-o", str(tmp_path / "csv.nc")]) == 0
    with xr.open_dataset(tmp_path / "npy.nc") as ds, xr.open_dataset(tmp_path / "csv.nc") as dc:
        K = _archived_K(ds)
        assert float(ds.K_asymmetry) > 1e-3  # a non-associated law: K is not symmetric
        expected = np.array([d @ (K @ d) / (d @ d) for d in rows])
        assert np.allclose(ds.direction_d2W.values, expected, rtol=1e-12, atol=0)
        assert np.array_equal(_over_dofs(ds, "direction_vector", packing.fixed), rows)
        assert list(dc.direction.values) == ["shear", "roll", "lift"]
        csv_rows = np.zeros((3, packing.n_dof))
        for row, entries in enumerate([{"x7": 1, "x13": -1}, {"x7": 0.5, "theta7": -2}, {"y12": 1e-3}]):
            for name, value in entries.items():
                csv_rows[row, names.index(name)] = value
        assert np.array_equal(_over_dofs(dc, "direction_vector", packing.fixed), csv_rows)
        expected = np.array([d @ (K @ d) / (d @ d) for d in csv_rows])
        assert np.allclose(dc.direction_d2W.values, expected, rtol=1e-12, atol=0)
        for name in ("direction_d2W", "direction_vector", "direction", "cone_width", "cone_lower", "cone_upper",
                     "cone_hill", "cone_form", "cone_basis", "plane"):
            assert {"units", "long_name", "description"} <= set(dc[name].attrs), name


@pytest.mark.parametrize("law", ["mcnamara", "cundall_strack"])
def test_a_free_grain_on_a_held_one_against_its_closed_form(law: str) -> None:
    """K by hand; d2W of given directions; the cone in the plane (x1, y1) from the roots of a quadratic."""
    gamma = 0.1
    K = _two_grain_K(law, gamma)
    directions = {"x": [1, 0, 0], "theta": [0, 0, 1], "xy": [1, 1, 0], "x_theta": [2, 0, -3], "y": [0, 1, 0]}
    ds = ncstab.analyse(_two_grains(), law, gamma, modes=3, directions=directions, cone_planes=["x,y"],
                        keep_rattlers=True)  # one contact: a rattler, kept for its closed form
    assert np.allclose(_archived_K(ds).toarray(), K, rtol=0, atol=1e-12)
    for name, d in directions.items():
        d = np.asarray(d, float)
        assert abs(float(ds.direction_d2W.sel(direction=name)) - d @ K @ d / (d @ d)) <= 1e-12 * np.abs(K).max()
    # in the plane (x1, y1): d2W(t) = K11 cos^2 + (K12 + K21) cos sin + K22 sin^2 < 0 between the roots
    # u = tan t of u^2 K22 + u (K12 + K21) + K11 = 0 (K22 = 1 > 0, K11 < 0: one root of each sign)
    b = K[0, 1] + K[1, 0]
    roots = np.sort(np.roots([K[1, 1], b, K[0, 0]]).real)
    width = 2 * (np.arctan(roots[1]) - np.arctan(roots[0]))
    cone = ds.sel(plane="x,y")
    assert K[0, 0] < 0 and abs(float(cone.cone_width) - width) <= 1e-12
    assert abs(float(cone.cone_lower) - np.mod(np.arctan(roots[0]), np.pi)) <= 1e-12
    assert abs(float(cone.cone_upper) - float(cone.cone_lower) - width / 2) <= 1e-12
    assert np.allclose(cone.cone_form.values, K[:2, :2], rtol=0, atol=1e-12)


def _cone_checks(K, basis: np.ndarray, width: float, lower: float, upper: float) -> None:
    """d2W of the full K at the bounds is 0, negative inside the cone (and its opposite), positive outside."""
    def work(t):
        d = np.cos(t) * basis[0] + np.sin(t) * basis[1]
        return d @ (K @ d) / (d @ d)

    assert abs(upper - lower - width / 2) <= 1e-12 and 0 <= lower < np.pi
    scale = abs(K).max()
    for t in (lower, upper, lower + np.pi, upper + np.pi):
        assert abs(work(t)) <= 1e-10 * scale, t
    span = upper - lower
    for f in (0.01, 0.3, 0.5, 0.9, 0.99):
        assert work(lower + f * span) < 0 and work(lower + np.pi + f * span) < 0
        assert work(upper + f * (np.pi - span)) > 0


@pytest.mark.parametrize("rows, law", [(4, "cundall_strack"), (4, "mcnamara"), (16, "cundall_strack")])
def test_the_cone_bounds_are_roots_of_the_full_second_order_work(rows: int, law: str) -> None:
    """Hill lost with one negative eigenvalue (a lattice under a large compression, alternating T): the cone in
    the plane of the two softest modes, and in the plane of two given directions (the softest mode and a
    random direction); 16 rows: the sparse path (720 free dofs)."""
    packing = _lattice(rows, 0.2 if rows == 4 else 0.12)
    first = ncstab.analyse(packing, law, 1.0 if law == "cundall_strack" else 0.5, modes=2)
    assert int(first.negative_eigenvalues) == 1
    softest = _over_dofs(first, "mode", packing.fixed)[0]
    other = np.random.default_rng(2).normal(size=packing.n_dof)
    ds = ncstab.analyse(packing, law, float(first.attrs["gamma"]), modes=2,
                        directions={"soft": softest, "other": other}, cone_planes=[("soft", "other")])
    K = _archived_K(ds)
    assert list(ds.plane.values) == ["softest modes", "soft,other"]
    for k in range(2):
        basis = _over_dofs(ds, "cone_basis", packing.fixed)[k]
        assert np.allclose(basis @ basis.T, np.eye(2), rtol=0, atol=1e-12)
        width, lower, upper = (float(ds[name][k]) for name in ("cone_width", "cone_lower", "cone_upper"))
        assert 0 < width < 2 * np.pi
        _cone_checks(K, basis, width, lower, upper)
    assert abs(float(ds.cone_hill[0]) - float(ds.hill)) <= 1e-10  # the softest mode lies in the plane


def test_no_cone_where_hill_holds_and_everything_where_both_are_negative() -> None:
    holds = ncstab.analyse(_lattice(4, 0.05), "cundall_strack", 1.0, modes=0)
    assert float(holds.hill) > 0 and float(holds.cone_width[0]) == 0
    assert np.isnan(holds.cone_lower[0]) and np.isnan(holds.cone_upper[0])
    assert holds.sizes["mode"] == 0 and holds.sizes["plane"] == 1  # the cone's modes are not archived
    lost = ncstab.analyse(_lattice(4, 0.3), "cundall_strack", 1.0, modes=2)
    assert int(lost.negative_eigenvalues) >= 2 and float(lost.cone_width[0]) == 2 * np.pi
    assert np.isnan(lost.cone_lower[0]) and np.isnan(lost.cone_upper[0])
    K = _archived_K(lost)
    basis = _over_dofs(lost, "cone_basis", _lattice(4, 0.3).fixed)[0]
    for t in np.linspace(0, np.pi, 7):
        d = np.cos(t) * basis[0] + np.sin(t) * basis[1]
        assert d @ (K @ d) < 0


GOOD_CSV = "name,x1,y1,theta1\na,1,0,0\nb,0,1,0\n"


@pytest.mark.parametrize("file, text, option, words", [
    ("d.csv", "name,x1,q1\na,1,0\n", [], ["d.csv", "line 1, column 3", "'q1' is not a dof name"]),
    ("d.csv", "x0,y1\n1,0\n", [], ["d.csv", "column 1", "'x0'", "grain 0 is held"]),
    ("d.csv", "x1,theta9\n1,0\n", [], ["d.csv", "'theta9'", "no grain 9"]),
    ("d.csv", "x1,y1\n1,0\n0,nan\n", [], ["d.csv", "line 3, column 'y1'", "'nan' is not a finite number"]),
    ("d.csv", "x1,y1\n1,abc\n", [], ["d.csv", "line 2, column 'y1'", "'abc' is not a number"]),
    ("d.csv", "name,x1,y1\na,1,0\nflat,0,0\n", [], ["d.csv", "line 3", "'flat'", "zero direction"]),
    ("d.csv", "x1,y1\n1,0,3\n", [], ["d.csv", "line 2 has 3 fields"]),
    ("d.csv", "x1,x1\n1,0\n", [], ["d.csv", "'x1' appears twice"]),
    ("d.npy", [[1.0, 0.0, 0.0, 1.0]], [], ["d.npy", "rows of length 4", "3 free dofs"]),
    ("d.npy", [[1.0, 0.0, 0.0], [0.0, np.inf, 0.0]], [], ["d.npy", "entry [1, 1]", "dof y1", "inf"]),
    ("d.npy", [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]], [], ["d.npy", "row 1 is the zero direction"]),
    ("d.csv", GOOD_CSV, ["--cone-plane", "a,c"], ["--cone-plane 'a,c'", "no direction 'c'", "d.csv"]),
    ("d.csv", GOOD_CSV, ["--cone-plane", "a,a"], ["--cone-plane 'a,a'", "parallel"]),
    ("d.csv", GOOD_CSV, ["--cone-plane", "a"], ["--cone-plane 'a'", "two directions"]),
    ("d.csv", GOOD_CSV, ["--cone-plane", "a,b", "--cone-plane", "0,1"], ["--cone-plane '0,1'", "'a,b' is given twice"]),
    ("d.txt", "x1\n1\n", [], ["d.txt", "not a .csv or .npy file"]),
])
def test_malformed_directions_are_exit_2_naming_the_file_and_entry(tmp_path, monkeypatch, capsys, file, text,
                                                                   option, words) -> None:
    monkeypatch.chdir(tmp_path)
    write_packing(_two_grains(), "p.nc")
    if file.endswith(".npy"):
        np.save(file, np.asarray(text))
    else:
        (tmp_path / file).write_text(text)
    before = sorted(p.name for p in tmp_path.iterdir())
    assert main(["analyse", "p.nc", "--law", "mcnamara", "--keep-rattlers", "--directions", file, *option]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "Traceback" not in err
    assert all(word in err for word in words), err
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # nothing written


def test_missing_directions_and_a_plane_without_them_are_exit_2(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    write_packing(_two_grains(), "p.nc")
    assert main(["analyse", "p.nc", "--law", "mcnamara", "--directions", "none.csv"]) == 2
    assert "--directions: no such file: none.csv" in capsys.readouterr().err
    assert main(["analyse", "p.nc", "--law", "mcnamara", "--cone-plane", "0,1"]) == 2
    assert "needs --directions" in capsys.readouterr().err
    assert not (tmp_path / "results").exists()


def test_the_python_api_refuses_malformed_arrays_naming_the_entry() -> None:
    packing = _two_grains()
    with pytest.raises(DirectionsError, match="rows of length 2, but the packing has 3 free dofs"):
        ncstab.analyse(packing, "mcnamara", keep_rattlers=True, directions=np.ones((1, 2)))
    with pytest.raises(DirectionsError, match=r"entry \[0, 2\] \(dof theta1\) is nan"):
        ncstab.analyse(packing, "mcnamara", keep_rattlers=True, directions=[1.0, 0.0, np.nan])
    with pytest.raises(DirectionsError, match="'b' has 2 entries"):
        ncstab.analyse(packing, "mcnamara", keep_rattlers=True, directions={"a": [1, 0, 0], "b": [1, 0]})
    ds = ncstab.analyse(packing, "mcnamara", keep_rattlers=True, directions=[0.0, 2.0, 0.0])  # one direction, (n,)
    assert list(ds.direction.values) == ["0"] and float(ds.direction_d2W[0]) == pytest.approx(1.0, abs=1e-12)
