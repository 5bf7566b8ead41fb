"""Write the shipped example packing, studies/packings/example_packing.nc (docs/packings.md).

A 20 x 20 triangular lattice of disks (radii drawn in [0.475, 0.5] d, so every
lattice contact overlaps a little), the bottom row held, under a synthetic
vertical load: each contact carries N = 0.01 + 0.04 n_y^2 (stronger along the
vertical), and T = +-0.004 alternating.  The forces are not in equilibrium
(R is not zero): a test bed for the analysis, not a settled DEM state.

Run:  python docs/scripts/example_packing.py
"""

from pathlib import Path

import numpy as np

from ncstab.systems.packing import triangular_lattice, write_packing

ROOT = Path(__file__).resolve().parents[2]

packing = triangular_lattice(20, 20, fix_bottom=True, jitter=0.05, seed=38)
a, b = packing.contacts.T
d = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
ny = d[:, 1] / np.linalg.norm(d, axis=1)
T = np.where(np.arange(packing.n_contacts) % 2, 0.004, -0.004)
write_packing(packing.with_forces(0.01 + 0.04 * ny**2, T), ROOT / "studies" / "packings" / "example_packing.nc")
