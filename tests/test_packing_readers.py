"""Readers of DEM outputs (issue 38), on small files written here from the formats' documentation
(LAMMPS/LIGGGHTS ``dump custom`` and ``dump local``, the YADE export of docs/packings.md, CSV): LAMMPS
is not installed.  Each file holds a known packing in SI-like units (d = 2 mm, k_n = 1e5 N/m) and known
contact forces (N, T); the reader must give back the packing's lengths in d and forces in k_n d to 1e-12
(a scaling and a projection: rounding only, the files being written with 17 digits).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ncstab.systems.packing import PackingError, read_packing, triangular_lattice, write_packing
from ncstab.systems.packing_readers import LAMMPS_PAIR_LOCAL, read_csv, read_lammps, read_yade

D, KN = 2e-3, 1e5


@pytest.fixture
def known():
    """A 3 x 4 lattice (ids 101.., type 2 for the bottom row), its forces, and each contact's F of a on b (SI)."""
    packing = triangular_lattice(3, 4, fix_bottom=True)
    rng = np.random.default_rng(7)
    N, T = rng.uniform(0.001, 0.01, packing.n_contacts), rng.uniform(-0.003, 0.003, packing.n_contacts)
    a, b = packing.contacts.T
    d = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    n = d / np.linalg.norm(d, axis=1)[:, None]
    t = np.column_stack([-n[:, 1], n[:, 0]])
    force_on_b = (N[:, None] * n - T[:, None] * t) * KN * D
    ids = 101 + np.arange(packing.n_grains)
    types = np.where(packing.fixed, 2, 1)
    return packing.with_forces(N, T), ids, types, force_on_b


def _same(read, expected) -> None:
    assert np.allclose(read.x, expected.x, atol=1e-12) and np.allclose(read.y, expected.y, atol=1e-12)
    assert np.allclose(read.radius, expected.radius, atol=1e-12)
    assert np.array_equal(read.fixed, expected.fixed)
    assert np.array_equal(read.contacts, expected.contacts)
    assert np.allclose(read.normal_force, expected.normal_force, atol=1e-12)
    assert np.allclose(read.tangential_force, expected.tangential_force, atol=1e-12)


def _dump_atoms(path: Path, packing, ids, types) -> None:
    rows = "\n".join(f"{i} {t} {x * D:.17g} {y * D:.17g} 0 {r * D:.17g}"
                     for i, t, x, y, r in zip(ids, types, packing.x, packing.y, packing.radius))
    snapshot = (f"ITEM: TIMESTEP\n{{step}}\nITEM: NUMBER OF ATOMS\n{packing.n_grains}\nITEM: BOX BOUNDS pp pp pp\n"
                f"-1 1\n-1 1\n-1 1\nITEM: ATOMS id type x y z radius\n{rows}\n")
    # two snapshots: the reader takes the last (the first has every grain shifted)
    first = snapshot.replace("{step}", "0").replace(" 0 ", " 0.5 ")
    path.write_text(first + snapshot.replace("{step}", "1000"))


def test_liggghts_dump_and_pair_gran_local(tmp_path, known) -> None:
    packing, ids, types, force_on_b = known
    _dump_atoms(tmp_path / "atoms.dump", packing, ids, types)
    a, b = packing.contacts.T
    # compute pair/gran/local id force: id1 id2 periodic-flag fx fy fz, the force on id1 (= minus that on id2)
    rows = "\n".join(f"{ids[i]} {ids[j]} 0 {-f[0]:.17g} {-f[1]:.17g} 0" for i, j, f in zip(a, b, force_on_b))
    (tmp_path / "pairs.dump").write_text(
        f"ITEM: TIMESTEP\n1000\nITEM: NUMBER OF ENTRIES\n{len(a)}\nITEM: BOX BOUNDS pp pp pp\n-1 1\n-1 1\n-1 1\n"
        f"ITEM: ENTRIES c_pgl[1] c_pgl[2] c_pgl[3] c_pgl[4] c_pgl[5] c_pgl[6]\n{rows}\n")
    read = read_lammps(tmp_path / "atoms.dump", tmp_path / "pairs.dump", kn=KN, fixed_types=[2])
    _same(read, packing)
    write_packing(read, tmp_path / "p.nc")
    _same(read_packing(tmp_path / "p.nc"), packing)


def test_lammps_property_local_and_pair_local(tmp_path, known) -> None:
    packing, ids, types, force_on_b = known
    _dump_atoms(tmp_path / "atoms.dump", packing, ids, types)
    a, b = packing.contacts.T
    # pairs listed j-i (the reverse order): the force on the first atom is then the force on b;
    # as LAMMPS's granular pair/local writes it: fx fy fz the normal part, p1 p2 p3 the tangential
    branch = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    n = branch / np.linalg.norm(branch, axis=1)[:, None]
    normal = np.sum(force_on_b * n, axis=1)[:, None] * n
    tangential = force_on_b - normal
    rows = "\n".join(f"{ids[j]} {ids[i]} {f[0]:.17g} {f[1]:.17g} 0 {t[0]:.17g} {t[1]:.17g} 0"
                     for i, j, f, t in zip(a, b, normal, tangential))
    (tmp_path / "pairs.dump").write_text(
        f"ITEM: TIMESTEP\n1000\nITEM: NUMBER OF ENTRIES\n{len(a)}\nITEM: BOX BOUNDS pp pp pp\n-1 1\n-1 1\n-1 1\n"
        "ITEM: ENTRIES c_ids[1] c_ids[2] c_pair[1] c_pair[2] c_pair[3] c_pair[4] c_pair[5] c_pair[6]\n"
        f"{rows}\n")
    read = read_lammps(tmp_path / "atoms.dump", tmp_path / "pairs.dump", columns=LAMMPS_PAIR_LOCAL, kn=KN,
                       fixed_ids=ids[packing.fixed])
    # the same contacts with a and b swapped: N and T are unchanged by the swap (docs/packings.md)
    assert np.array_equal(read.contacts, packing.contacts[:, ::-1])
    assert np.allclose(read.normal_force, packing.normal_force, atol=1e-12)
    assert np.allclose(read.tangential_force, packing.tangential_force, atol=1e-12)


def test_a_dump_without_contacts_finds_the_touching_pairs(tmp_path, known) -> None:
    packing, ids, types, _ = known
    _dump_atoms(tmp_path / "atoms.dump", packing, ids, types)
    read = read_lammps(tmp_path / "atoms.dump", fixed_types=[2])
    assert np.array_equal(read.contacts, packing.contacts)
    assert not read.normal_force.any()


def test_yade_export(tmp_path, known) -> None:
    packing, ids, _, force_on_b = known
    a, b = packing.contacts.T
    lines = ["# ncstab YADE export: B id x y radius fixed / I id1 id2 fx fy (force of id1 on id2)"]
    lines += [f"B {i} {x * D:.17g} {y * D:.17g} {r * D:.17g} {int(f)}"
              for i, x, y, r, f in zip(ids, packing.x, packing.y, packing.radius, packing.fixed)]
    lines += [f"I {ids[i]} {ids[j]} {f[0]:.17g} {f[1]:.17g}" for i, j, f in zip(a, b, force_on_b)]
    (tmp_path / "yade.txt").write_text("\n".join(lines) + "\n")
    _same(read_yade(tmp_path / "yade.txt", kn=KN), packing)


def test_csv_tables(tmp_path, known) -> None:
    packing, ids, _, force_on_b = known
    a, b = packing.contacts.T
    (tmp_path / "grains.csv").write_text("id,x,y,radius,fixed\n" + "\n".join(
        f"{i},{x * D:.17g},{y * D:.17g},{r * D:.17g},{int(f)}"
        for i, x, y, r, f in zip(ids, packing.x, packing.y, packing.radius, packing.fixed)))
    (tmp_path / "forces.csv").write_text("a,b,fx,fy\n" + "\n".join(
        f"{ids[i]},{ids[j]},{f[0]:.17g},{f[1]:.17g}" for i, j, f in zip(a, b, force_on_b)))
    (tmp_path / "nt.csv").write_text("a,b,normal_force,tangential_force\n" + "\n".join(
        f"{ids[i]},{ids[j]},{n * KN * D:.17g},{t * KN * D:.17g}"
        for i, j, n, t in zip(a, b, packing.normal_force, packing.tangential_force)))
    _same(read_csv(tmp_path / "grains.csv", tmp_path / "forces.csv", kn=KN), packing)
    _same(read_csv(tmp_path / "grains.csv", tmp_path / "nt.csv", kn=KN), packing)


def test_readers_refuse_unknown_ids_and_periodic_images(tmp_path, known) -> None:
    packing, ids, _, _ = known
    (tmp_path / "grains.csv").write_text("id,x,y,radius\n" + "\n".join(
        f"{i},{x:.17g},{y:.17g},{r:.17g}" for i, x, y, r in zip(ids, packing.x, packing.y, packing.radius)))
    (tmp_path / "c.csv").write_text("a,b\n101,102\n101,999\n")
    with pytest.raises(PackingError, match="contact 1 names grain id 999"):
        read_csv(tmp_path / "grains.csv", tmp_path / "c.csv")
    (tmp_path / "c.csv").write_text("a,b\n101,104\n")
    with pytest.raises(PackingError, match="periodic"):
        read_csv(tmp_path / "grains.csv", tmp_path / "c.csv")
    (tmp_path / "y.txt").write_text("B 1 0 0 0.5 0\nX 1 2\n")
    with pytest.raises(PackingError, match="line 2"):
        read_yade(tmp_path / "y.txt")
