"""The Love-Weber stress of a packing's contact forces, and the volume it is averaged over.

For each contact c between grains a and b, with f_c the force of a on b
(``N n - T t``, n the unit branch from a to b, t = n turned by +90 degrees) and
l_c = x_b - x_a the branch vector::

    sigma_ij = (1 / V) sum_c f_ci l_cj            (compression positive)

(Love 1927, Weber 1966; Christoffersen, Mehrabadi and Nemat-Nasser 1981).  A
compressive contact (N > 0) adds N |l| n n^T: positive.  V is the grains'
bounding box, the rectangle from min(x - r) to max(x + r) and from min(y - r)
to max(y + r) (an area: the stress is per unit thickness).  Units: k_n (force
k_n d times length d over area d^2).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.systems.packing import Packing

__all__ = ["BOUNDING_BOX", "PackingStress", "love_weber_stress"]

BOUNDING_BOX = ("grains' bounding box: (max(x + r) - min(x - r)) (max(y + r) - min(y - r)), an area (stress per "
                "unit thickness)")


@dataclass(frozen=True)
class PackingStress:
    """``stress`` (2, 2), its ``volume`` V and the rule V was taken by."""

    stress: np.ndarray
    volume: float
    volume_rule: str


def love_weber_stress(packing: Packing) -> PackingStress:
    """sigma = (1/V) sum_c f_c l_c^T over every contact of ``packing`` (module docstring), ``(2, 2)``."""
    a, b = packing.contacts[:, 0], packing.contacts[:, 1]
    branch = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    n = branch / np.linalg.norm(branch, axis=1)[:, None]
    t = np.column_stack([-n[:, 1], n[:, 0]])
    force = packing.normal_force[:, None] * n - packing.tangential_force[:, None] * t
    r = packing.radius
    volume = float((np.max(packing.x + r) - np.min(packing.x - r)) * (np.max(packing.y + r) - np.min(packing.y - r)))
    return PackingStress(np.einsum("ci,cj->ij", force, branch) / volume, volume, BOUNDING_BOX)
