"""Three-dimensional packings through the readers and the packing file (issue 58): never a silent projection.

Each file is written here from a known sphere packing (an FCC block with known contact forces, in SI-like
units d = 2 mm, k_n = 1e5 N/m) with 17 digits; a reader must give back x, y, z, radius, N and the tangential
force's three components to 1e-12 (a scaling and a projection: rounding only).  2-D data (no z, or z
constant, as the LAMMPS pour of tests/data/lammps_pour) stay two-dimensional.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from ncstab.systems.packing import PackingError, read_packing, write_packing
from ncstab.systems.packing_readers import LAMMPS_PAIR_LOCAL, read_csv, read_lammps, read_yade
from ncstab.systems.spheres import fcc_block

D, KN = 2e-3, 1e5
DATA = Path(__file__).resolve().parent / "data" / "lammps_pour"


@pytest.fixture
def spheres():
    """A 2x1x2 FCC block (ids 101..), its forces N and tangential vectors, and each contact's F of a on b (SI)."""
    packing = fcc_block(2, 1, 2, fix_bottom=True)
    rng = np.random.default_rng(3)
    a, b = packing.contacts.T
    branch = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a], packing.z[b] - packing.z[a]])
    n = branch / np.linalg.norm(branch, axis=1)[:, None]
    N = rng.uniform(0.001, 0.01, packing.n_contacts)
    T = rng.uniform(-0.003, 0.003, (packing.n_contacts, 3))
    T -= np.sum(T * n, axis=1)[:, None] * n
    ids = 101 + np.arange(packing.n_grains)
    return packing.with_forces(N, T), ids, (N[:, None] * n + T) * KN * D


def _same(read, expected) -> None:
    assert read.dimension == 3
    for name in ("x", "y", "z", "radius", "normal_force", "tangential_force_vector"):
        assert np.allclose(getattr(read, name), getattr(expected, name), atol=1e-12), name
    assert np.array_equal(read.contacts, expected.contacts) and np.array_equal(read.fixed, expected.fixed)


def _dumps(folder: Path, packing, ids, force_on_b) -> None:
    rows = "\n".join(f"{i} {1 + f} {x * D:.17g} {y * D:.17g} {z * D:.17g} {r * D:.17g}" for i, f, x, y, z, r in
                     zip(ids, packing.fixed.astype(int), packing.x, packing.y, packing.z, packing.radius))
    (folder / "atoms.dump").write_text(
        f"ITEM: TIMESTEP\n5\nITEM: NUMBER OF ATOMS\n{packing.n_grains}\nITEM: BOX BOUNDS pp pp pp\n-1 1\n-1 1\n"
        f"-1 1\nITEM: ATOMS id type x y z radius\n{rows}\n")
    a, b = packing.contacts.T
    rows = "\n".join(f"{ids[i]} {ids[j]} 0 " + " ".join(f"{-c:.17g}" for c in f) for i, j, f in zip(a, b, force_on_b))
    (folder / "pairs.dump").write_text(
        f"ITEM: TIMESTEP\n5\nITEM: NUMBER OF ENTRIES\n{len(a)}\nITEM: BOX BOUNDS pp pp pp\n-1 1\n-1 1\n-1 1\n"
        f"ITEM: ENTRIES c_p[1] c_p[2] c_p[3] c_p[4] c_p[5] c_p[6]\n{rows}\n")


def test_a_dump_whose_z_varies_gives_spheres_and_round_trips(tmp_path, spheres) -> None:
    packing, ids, force_on_b = spheres
    _dumps(tmp_path, packing, ids, force_on_b)
    read = read_lammps(tmp_path / "atoms.dump", tmp_path / "pairs.dump", kn=KN, fixed_types=[2])
    _same(read, packing)
    write_packing(read, tmp_path / "p.nc")
    _same(read_packing(tmp_path / "p.nc"), packing)
    found = read_lammps(tmp_path / "atoms.dump", fixed_types=[2])  # no dump local: the touching spheres
    assert found.dimension == 3 and np.array_equal(found.contacts, packing.contacts)


def test_two_dimensions_on_spheres_are_refused_unless_a_plane_section_is_asked(tmp_path, spheres) -> None:
    packing, ids, force_on_b = spheres
    _dumps(tmp_path, packing, ids, force_on_b)
    with pytest.raises(PackingError, match="z varies"):
        read_lammps(tmp_path / "atoms.dump", tmp_path / "pairs.dump", kn=KN, dimension=2)
    section = read_lammps(tmp_path / "atoms.dump", tmp_path / "pairs.dump", kn=KN, plane_section=True)
    assert section.dimension == 2 and np.allclose(section.x, packing.x) and np.allclose(section.y, packing.y)
    with pytest.raises(PackingError, match="no z"):
        read_csv(_csv(tmp_path, packing, ids, with_z=False), dimension=3)


def _csv(folder: Path, packing, ids, with_z: bool = True) -> Path:
    header = "id,x,y,z,radius,fixed" if with_z else "id,x,y,radius,fixed"
    rows = [f"{i},{float(x * D)!r},{float(y * D)!r}," + (f"{float(z * D)!r}," if with_z else "") + f"{float(r * D)!r},{int(f)}"
            for i, x, y, z, r, f in zip(ids, packing.x, packing.y, packing.z, packing.radius, packing.fixed)]
    (folder / "grains.csv").write_text("\n".join([header, *rows]) + "\n")
    return folder / "grains.csv"


def test_yade_export_and_csv_keep_z(tmp_path, spheres) -> None:
    packing, ids, force_on_b = spheres
    a, b = packing.contacts.T
    lines = [f"B {i} {float(x * D)!r} {float(y * D)!r} {float(z * D)!r} {float(r * D)!r} {int(f)}"
             for i, x, y, z, r, f in zip(ids, packing.x, packing.y, packing.z, packing.radius, packing.fixed)]
    lines += [f"I {ids[i]} {ids[j]} " + " ".join(repr(float(c)) for c in f) for i, j, f in zip(a, b, force_on_b)]
    (tmp_path / "packing.txt").write_text("\n".join(lines) + "\n")
    _same(read_yade(tmp_path / "packing.txt", kn=KN), packing)
    grains = _csv(tmp_path, packing, ids)
    rows = [f"{ids[i]},{ids[j]}," + ",".join(repr(float(c)) for c in f) for i, j, f in zip(a, b, force_on_b)]
    (tmp_path / "contacts.csv").write_text("\n".join(["a,b,fx,fy,fz", *rows]) + "\n")
    _same(read_csv(grains, tmp_path / "contacts.csv", kn=KN), packing)


def test_a_packing_file_with_z_checks_its_tangential_force(tmp_path, spheres) -> None:
    packing = spheres[0]
    bad = packing.with_forces(packing.normal_force, packing.tangential_force_vector + np.array([1.0, 0.0, 0.0]))
    write_packing(bad, tmp_path / "bad.nc")
    with pytest.raises(PackingError, match="along the branch"):
        read_packing(tmp_path / "bad.nc")


def test_the_lammps_pour_with_constant_z_stays_two_dimensional() -> None:
    read = read_lammps(DATA / "atoms.dump", DATA / "pairs.dump", columns=LAMMPS_PAIR_LOCAL, kn=1000.0,
                       fixed_types=[2])
    assert read.dimension == 2 and read.z is None
