"""Rotational springs whose variable is linear in the dofs: q = c . u_e - rest.

Where the dofs are themselves angles (the absolute bar angles phi_i of Ziegler's
chain, :mod:`ncstab.systems.assembled_chain`), a spring's rotation is a fixed
linear combination of its own dofs: the base spring measures q = phi_1, the spring
at joint j (between bars j and j + 1) q = phi_{j+1} - phi_j.  Then

    q = c . u_e - rest,        J = dq/du_e = c,        H = d2q/du_e2 = 0

on the spring's own L dofs, and the assembly (:mod:`ncstab.operators.assembly`)
gives R = sum_e w J_e^T Q_e and K = sum_e w J_e^T D_e J_e (the H term vanishes).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["LinearSprings"]


@dataclass(frozen=True, eq=False)
class LinearSprings:
    """Springs whose variable is a fixed linear combination of their dofs.

    Attributes
    ----------
    names
        Spring names, ``(m,)``.
    dofs
        Global dof index of each spring's local dofs, ``(m, L)``; a padding entry has
        index 0 and coefficient 0 (the base spring of a chain has one dof).
    coefficients
        c of each spring on its local dofs, ``(m, L)``.
    weight
        Weight of every spring in the internal virtual work.
    rest
        Each spring's q where it is stress-free ``(m,)``, or None for 0.
    """

    names: tuple[str, ...]
    dofs: np.ndarray
    coefficients: np.ndarray
    weight: float = 1.0
    rest: np.ndarray | None = None

    def __post_init__(self) -> None:
        m = len(self.names)
        if self.dofs.ndim != 2 or self.dofs.shape[0] != m or self.coefficients.shape != self.dofs.shape:
            raise ValueError(f"linear springs: dofs and coefficients must both be (members, L), got "
                             f"{self.dofs.shape} and {self.coefficients.shape} for {m} members")

    @property
    def size(self) -> int:
        return len(self.names)

    def kinematics(self, u: np.ndarray, second: bool = True):
        """q = c . u_e - rest ``(m, 1)``, J = c ``(m, 1, L)``, H = 0 ``(m, 1, L, L)`` (or None)."""
        q = np.einsum("ml,ml->m", self.coefficients, u[self.dofs])
        if self.rest is not None:
            q = q - self.rest
        J = self.coefficients[:, None, :].astype(float)
        if not second:
            return q[:, None], J, None
        L = self.dofs.shape[1]
        return q[:, None], J, np.zeros((self.size, 1, L, L))
