"""A granular contact whose branch is affine in the dofs: q = (l, alpha) for arrays of members.

Each member m sees its branch through two coordinates in the frame of its
reference grain, c = the component along the grain's axis and s = the
component across it, affine in the member's own L dofs::

    (c, s) = origin_m + A_m u_e,        l = sqrt(c^2 + s^2),  alpha = atan2(s, c)

(seed Eq. 1 and 3: l cos(alpha) = 2R cos(alpha0) - Delta_1, l sin(alpha) =
2R sin(alpha0) - Delta_2, in units of 2R).  This covers the seed's diamond in
both reductions, rings of grains each free along its radius, and grains moving
in the plane without rotating.  With

    dl/d(c, s) = (c, s)/l,            dalpha/d(c, s) = (-s, c)/l^2,
    d2l = (s^2, -cs, c^2)/l^3,        d2alpha = (2cs, s^2 - c^2, -2cs)/l^4

(entries (cc, cs, ss)), J = G A and H_k = A^T G2_k A on the member's dofs.  The
same kinematics measure a unilateral gap: its distance is l - 1.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BranchElements", "branch_kinematics"]


@dataclass(frozen=True, eq=False)
class BranchElements:
    """Members whose branch coordinates (c, s) are affine in their dofs.

    Attributes
    ----------
    names
        Member names, ``(m,)``.
    dofs
        Global dof index of each member's local dofs, ``(m, L)`` (int).
    matrix
        d(c, s)/du_e, ``(m, 2, L)``.
    origin
        (c, s) at u = 0, ``(m, 2)``.
    weight
        Weight of every member in the internal virtual work (seed Eq. 5).
    """

    names: tuple[str, ...]
    dofs: np.ndarray
    matrix: np.ndarray
    origin: np.ndarray
    weight: float = 1.0

    def __post_init__(self) -> None:
        m = len(self.names)
        if self.dofs.ndim != 2 or self.dofs.shape[0] != m:
            raise ValueError(f"branch elements: dofs must be (members, L), got {self.dofs.shape} for {m} members")
        if self.matrix.shape != (m, 2, self.dofs.shape[1]) or self.origin.shape != (m, 2):
            raise ValueError("branch elements: matrix must be (members, 2, L) and origin (members, 2)")

    @property
    def size(self) -> int:
        return len(self.names)

    def coordinates(self, u: np.ndarray) -> np.ndarray:
        """(c, s) of every member at the dofs ``u`` ``(n,)``: ``(m, 2)``."""
        return self.origin + np.einsum("mkl,ml->mk", self.matrix, u[self.dofs])

    def kinematics(self, u: np.ndarray, second: bool = True):
        """q, J, H of every member (:func:`branch_kinematics`): the element protocol the
        assembly reads (:mod:`ncstab.operators.assembly`), with :attr:`names`, :attr:`dofs`,
        :attr:`weight` and :attr:`size`."""
        return branch_kinematics(self, u, second)


def branch_kinematics(elements: BranchElements, u: np.ndarray, second: bool = True):
    """q = (l, alpha), J = dq/du_e and H = d2q/du_e2 of every member.

    Parameters
    ----------
    elements
        The members.
    u
        The dofs, ``(n,)``.
    second
        Whether to compute H.

    Returns
    -------
    q : (m, 2)
        ``(l, alpha)`` of each member.
    J : (m, 2, L)
    H : (m, 2, L, L) or None
    """
    cs = elements.coordinates(u)
    c, s = cs[:, 0], cs[:, 1]
    r2 = c * c + s * s
    l = np.sqrt(r2)
    q = np.stack([l, np.arctan2(s, c)], axis=1)
    gradient = np.empty((len(c), 2, 2))
    gradient[:, 0, 0] = c / l
    gradient[:, 0, 1] = s / l
    gradient[:, 1, 0] = -s / r2
    gradient[:, 1, 1] = c / r2
    A = elements.matrix
    J = np.einsum("mkp,mpl->mkl", gradient, A)
    if not second:
        return q, J, None
    l3, r4 = l * r2, r2 * r2
    curvature = np.empty((len(c), 2, 2, 2))
    curvature[:, 0, 0, 0] = s * s / l3
    curvature[:, 0, 0, 1] = curvature[:, 0, 1, 0] = -c * s / l3
    curvature[:, 0, 1, 1] = c * c / l3
    curvature[:, 1, 0, 0] = 2 * c * s / r4
    curvature[:, 1, 0, 1] = curvature[:, 1, 1, 0] = (s * s - c * c) / r4
    curvature[:, 1, 1, 1] = -2 * c * s / r4
    H = np.einsum("mpa,mkpq,mqb->mkab", A, curvature, A)
    return q, J, H
