"""The contact between two rotating grains in the plane: q = (l, beta), for arrays of contacts.

Two disks a and b, of radii r_a and r_b, centres X_a and X_b, rotations theta_a
and theta_b (counter-clockwise), each with three dofs (x, y, theta).  With the
branch d = X_b - X_a, its length |d| and angle alpha = atan2(d_y, d_x), the
unit normal n = d/|d| and tangent t = (-n_y, n_x), the contact's two
interaction variables are::

    l    = |d| / rho,
    beta = alpha - (r_a theta_a + r_b theta_b) / (r_a + r_b).

*Why beta.*  The material points of a and b at the contact point move with
v_a + r_a omega_a t and v_b - r_b omega_b t, so their relative tangential
displacement is ``|d| dalpha - (r_a dtheta_a + r_b dtheta_b)``; where
|d| = r_a + r_b this is ``(r_a + r_b) dbeta``: ``l dbeta`` is the seed's
tangential displacement ``du_t = l dalpha`` (seed Eq. 6, 11) with the grains'
rotations included, in units of the contact's length scale.  A rigid rotation
phi of the whole packing adds phi to alpha and to both thetas and leaves beta
(and l) unchanged; rigid translations leave both unchanged: K has these three
null vectors whatever the law (the three zero eigenvalues of a free packing).
Grains that do not rotate have beta = alpha: the seed's diamond (seed Eq. 1-3,
with the seed's angle measured from another axis, which only shifts alpha0).

*Units.*  A packing's lengths are in units of the mean grain diameter d and its
forces in units of k_n d (seed Eq. 37 with 2R -> d).  The seed's laws are
written in units of each contact's rest length (l0 = 1): each contact has its
own length scale rho, and its law sees l = |d|/rho, forces f* = f/rho and energy
W* = W/rho^2.  The internal virtual work of a contact is then (seed Eq. 9, 16)::

    delta W = -N delta|d| + T |d| delta beta = rho^2 (-N* delta l + T* l delta beta),

so a packing's R and K are sums over contacts of rho^2 J^T Q* and
rho^2 (J^T D* J + Q* H) with J, H the derivatives of (l, beta) below: every
contact has the same k_n (a linear-spring DEM) and k_t = gamma k_n.  rho is the
rest length of the normal law N = k_n (rho - |d|): rho = |d| + N for the state's
normal force N (= r_a + r_b for a linear-spring DEM, whose N is k_n times the
overlap; :mod:`ncstab.systems.packing`).

*Derivatives.*  On the contact's dofs u_e = (x_a, y_a, theta_a, x_b, y_b,
theta_b), d is affine (d = d_0 + A u_e, A = [-I 0 I 0]): the branch
kinematics of :mod:`ncstab.elements.branch` give (|d|, alpha) with their J and
H, and::

    J_l = J_|d| / rho,   H_l = H_|d| / rho,
    J_beta = J_alpha - (r_a e_theta_a + r_b e_theta_b)/(r_a + r_b),   H_beta = H_alpha

(beta is alpha plus a linear function of the rotations).  The force of grain a on
grain b is ``N n - T t`` and its moment on b is ``r_b T |d|/(r_a + r_b)``
(``R = J^T Q`` is the internal force).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ncstab.elements.branch import BranchElements, branch_kinematics

__all__ = ["GrainContacts", "grain_contact_kinematics"]

#: d(branch)/d(u_e) for u_e = (x_a, y_a, theta_a, x_b, y_b, theta_b): d = X_b - X_a.
_BRANCH_MAP = np.array([[-1.0, 0.0, 0.0, 1.0, 0.0, 0.0], [0.0, -1.0, 0.0, 0.0, 1.0, 0.0]])


@dataclass(frozen=True, eq=False)
class GrainContacts:
    """Contacts between rotating disks (see the module docstring).

    Attributes
    ----------
    dofs : (m, 6) int
        Global index of (x_a, y_a, theta_a, x_b, y_b, theta_b); a held dof points at
        a slot whose value is always 0 (the caller's convention).
    branch : (m, 2)
        X_b - X_a at u = 0.
    lever : (m, 2)
        r_a/(r_a + r_b) and r_b/(r_a + r_b).
    scale : (m,)
        Each contact's length scale rho (its law's rest length).
    free : (m, 6) bool or None
        Which of the six dofs exist; a held one (False) is 0 whatever ``u`` holds at
        its index, and its columns of J and H are 0.  ``None``: all six (the caller
        points held dofs at a slot of ``u`` that is always 0 instead).
    labels : tuple of str
        The contacts' names (default ``"0"``, ``"1"``, ...).

    With :attr:`names`, :attr:`weight` (rho^2, the factor of each contact's virtual work)
    and :meth:`kinematics`, the contacts are an element family of an assembled system
    (:mod:`ncstab.operators.assembly`), as :class:`~ncstab.elements.branch.BranchElements` are.
    """

    dofs: np.ndarray
    branch: np.ndarray
    lever: np.ndarray
    scale: np.ndarray
    free: np.ndarray | None = None
    labels: tuple[str, ...] = ()

    @property
    def size(self) -> int:
        return len(self.scale)

    @property
    def names(self) -> tuple[str, ...]:
        return self.labels or tuple(map(str, range(self.size)))

    @property
    def weight(self) -> np.ndarray:
        """rho^2 per contact: R = sum rho^2 J^T Q*, K = sum rho^2 (J^T D* J + Q* H) (module docstring)."""
        return self.scale * self.scale

    def kinematics(self, u: np.ndarray, second: bool = True):
        """q = (l, beta), J and H of every contact (:func:`grain_contact_kinematics`)."""
        return grain_contact_kinematics(self, u, second)

    @functools.cached_property
    def elements(self) -> BranchElements:
        """The branches as :class:`~ncstab.elements.branch.BranchElements` (weight 1; built once)."""
        m = self.size
        matrix = np.broadcast_to(_BRANCH_MAP, (m, 2, 6))
        if self.free is not None:
            matrix = matrix * self.free[:, None, :]
        return BranchElements(names=tuple(map(str, range(m))), dofs=self.dofs, matrix=matrix, origin=self.branch)


def grain_contact_kinematics(contacts: GrainContacts, u: np.ndarray, second: bool = True):
    """q = (l, beta), J = dq/du_e ``(m, 2, 6)`` and H = d2q/du_e2 ``(m, 2, 6, 6)``.

    Parameters
    ----------
    contacts
        The contacts.
    u : (n,)
        Every dof, indexed by ``contacts.dofs`` (held ones 0, or masked by ``contacts.free``).
    second
        Whether to compute H.

    Returns
    -------
    q : (m, 2)
    J : (m, 2, 6)
    H : (m, 2, 6, 6) or None
    """
    q, J, H = branch_kinematics(contacts.elements, u, second=second)
    rho = contacts.scale
    lever = contacts.lever if contacts.free is None else contacts.lever * contacts.free[:, [2, 5]]
    theta = u[contacts.dofs[:, [2, 5]]]
    q = np.stack([q[:, 0] / rho, q[:, 1] - np.sum(lever * theta, axis=1)], axis=1)
    J = J.copy()
    J[:, 0] /= rho[:, None]
    J[:, 1, 2] -= lever[:, 0]
    J[:, 1, 5] -= lever[:, 1]
    if H is not None:
        H = H.copy()
        H[:, 0] /= rho[:, None, None]
    return q, J, H
