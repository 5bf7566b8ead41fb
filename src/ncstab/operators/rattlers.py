"""Rattlers of a packing: free grains that carry no load, found recursively, and the packing without them.

A contact is force-carrying where its normal force exceeds the tolerance
``N > RATTLER_TOLERANCE * max_c N_c`` (compression positive).  A free grain (one
with a dof that is not held) with fewer than two force-carrying contacts cannot
be in equilibrium under a non-zero load: it is a rattler.  Removing a rattler
removes its contacts, which can leave a neighbour with fewer than two: the
removal is repeated until no grain is removed (the 2-core of the force-carrying
contact graph with the held grains always kept).  A packing that stores no
positive normal force at all (a purely geometric network) has no rattler by
this rule: nothing tells a carrying contact from another.

:func:`without_rattlers` returns the packing that ``ncstab analyse`` assembles by
default: the rattlers held (their dofs leave K) and every contact that touches
one removed (their stiffness leaves K).
"""

from __future__ import annotations

import numpy as np

from ncstab.systems.packing import Packing

__all__ = ["RATTLER_TOLERANCE", "force_carrying", "rattler_mask", "without_rattlers"]

#: A contact carries force where N > RATTLER_TOLERANCE * max N (relative: N is in units of k_n d).
RATTLER_TOLERANCE = 1e-9


def force_carrying(packing: Packing, tolerance: float = RATTLER_TOLERANCE) -> np.ndarray:
    """``(c,)`` bool: N > tolerance * max N (all False where no contact is compressed)."""
    N = np.asarray(packing.normal_force, dtype=float)
    top = float(N.max()) if N.size else 0.0
    if top <= 0:
        return np.zeros(len(N), dtype=bool)
    return N > tolerance * top


def rattler_mask(packing: Packing, tolerance: float = RATTLER_TOLERANCE) -> np.ndarray:
    """``(g,)`` bool: the rattlers (free grains left with fewer than two force-carrying contacts, recursively).

    Each pass counts every grain's remaining force-carrying contacts
    (``numpy.bincount``), marks the free grains with fewer than two and drops their
    contacts; at most g passes.  No rattler where no contact is compressed.
    """
    g = packing.n_grains
    active = force_carrying(packing, tolerance)
    rattler = np.zeros(g, dtype=bool)
    if not active.any():
        return rattler
    free = ~packing.held_dofs.all(axis=1)
    a, b = packing.contacts[:, 0], packing.contacts[:, 1]
    while True:
        count = np.bincount(a[active], minlength=g) + np.bincount(b[active], minlength=g)
        new = free & ~rattler & (count < 2)
        if not new.any():
            return rattler
        rattler |= new
        active &= ~(rattler[a] | rattler[b])


def without_rattlers(packing: Packing, rattler: np.ndarray) -> Packing:
    """``packing`` with the ``rattler`` grains held (``fixed``) and every contact touching one removed."""
    rattler = np.asarray(rattler, dtype=bool)
    keep = ~(rattler[packing.contacts[:, 0]] | rattler[packing.contacts[:, 1]])
    held = None if packing.held is None else packing.held_dofs | rattler[:, None]
    return Packing(packing.x, packing.y, packing.radius, packing.fixed | rattler, packing.contacts[keep],
                   packing.normal_force[keep], packing.tangential_force[keep], packing.source, held)
