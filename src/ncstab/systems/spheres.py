"""Three-dimensional packings (spheres): a face-centred cubic block, and each free grain's six dofs.

A packing with ``z`` (:attr:`~ncstab.systems.packing.Packing.dimension` 3) has six
dofs per grain, in this order: ``x<i>``, ``y<i>``, ``z<i>``, ``theta_x<i>``,
``theta_y<i>``, ``theta_z<i>`` (translations of the centre, then the rotation
vector's components); a ``fixed`` grain holds all six.
"""

from __future__ import annotations

import numpy as np

from ncstab.systems.packing import Packing, contacts_from_geometry

__all__ = ["SPHERE_COMPONENTS", "fcc_block", "sphere_dof_index", "sphere_dof_names", "sphere_held"]

#: The six dofs of a sphere, in K's order.
SPHERE_COMPONENTS = ("x", "y", "z", "theta_x", "theta_y", "theta_z")


def sphere_held(packing: Packing) -> np.ndarray:
    """``(g, 6)`` bool: each sphere's held dofs (``packing.held`` if it is ``(g, 6)``, else the fixed grains')."""
    if packing.held is not None and np.shape(packing.held) == (packing.n_grains, 6):
        return np.asarray(packing.held, dtype=bool)
    return np.repeat(np.asarray(packing.fixed, dtype=bool)[:, None], 6, axis=1)


def sphere_dof_index(packing: Packing) -> np.ndarray:
    """``(g, 6)``: each sphere's dof indices among the free dofs (grain-major), -1 where held."""
    free = ~sphere_held(packing)
    index = np.full(free.shape, -1, dtype=np.intp)
    index[free] = np.arange(int(np.count_nonzero(free)))
    return index


def sphere_dof_names(packing: Packing) -> list[str]:
    """The names of the free dofs in K's order (``x3``, ``theta_z3``, ...)."""
    free = ~sphere_held(packing)
    grain, component = np.nonzero(free)
    return [f"{SPHERE_COMPONENTS[c]}{g}" for g, c in zip(grain, component)]


def fcc_block(nx: int, ny: int, nz: int, fix_bottom: bool = False) -> Packing:
    """Spheres of diameter 1 on a face-centred cubic lattice (cube side sqrt 2), ``4 nx ny nz`` grains,
    touching (12 neighbours inside), zero forces; ``fix_bottom`` holds the grains at z = 0."""
    a = np.sqrt(2.0)
    basis = np.array([[0, 0, 0], [0.5, 0.5, 0], [0.5, 0, 0.5], [0, 0.5, 0.5]])
    cells = np.stack(np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"), -1).reshape(-1, 3)
    points = (a * (cells[:, None, :] + basis[None, :, :])).reshape(-1, 3)
    points = points[np.lexsort((points[:, 0], points[:, 1], points[:, 2]))]
    radius = np.full(len(points), 0.5)
    x, y, z = points.T.copy()
    contacts = contacts_from_geometry(x, y, radius, tolerance=1e-9, z=z)
    zeros = np.zeros(len(contacts))
    fixed = (z < 1e-9) if fix_bottom else np.zeros(len(points), dtype=bool)
    return Packing(x, y, radius, fixed, contacts, zeros, zeros.copy(), f"fcc block {nx}x{ny}x{nz}", None, None, z,
                   np.zeros((len(contacts), 3)))
