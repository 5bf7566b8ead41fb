"""Write the packing of the shipped path study, studies/packings/packing_path.nc (docs/packing-paths.md).

A 4 x 4 triangular lattice of disks (radii drawn in [0.475, 0.5] d), the bottom
row held, carrying a synthetic vertical load: each contact N = 0.01 + 0.02 n_y^2
and T = +-0.002 alternating (units k_n d).  studies/packing_path.toml pushes a
grain of its top row down from that stressed state.

Run:  python docs/scripts/packing_path.py
"""

from pathlib import Path

import numpy as np

from ncstab.systems.packing import triangular_lattice, write_packing

ROOT = Path(__file__).resolve().parents[2]

packing = triangular_lattice(4, 4, fix_bottom=True, jitter=0.05, seed=38)
a, b = packing.contacts.T
d = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
ny = d[:, 1] / np.linalg.norm(d, axis=1)
T = np.where(np.arange(packing.n_contacts) % 2, 0.002, -0.002)
write_packing(packing.with_forces(0.01 + 0.02 * ny**2, T), ROOT / "studies" / "packings" / "packing_path.nc")
