"""The protocol a discrete system implements for the rest of ncstab.

A system maps generalized displacements ``u`` (shape ``(..., n_dof)``) to the
variables of its contacts ``q = (l, alpha)`` per contact family (shape
``(..., n_contacts, 2)``), and contact forces back to generalized forces by the
principle of virtual work:

    F = sum_c w_c J_c^T Q_c,   Q_c = (-N_c, l_c T_c)   (seed Eq. 5, 9, 12)

with ``J_c = dq_c/du`` and ``w_c`` the weight of the contact family (the diamond
has one family of four identical contacts, and ``w = 2`` because the external
work per contact is F . du / 2).  The tangent operator of any system then
follows from J, the Hessians ``H_c = d2 q_c / du2`` and the law (see
:mod:`ncstab.operators.tangent`), so a new system (a follower-force column, a
ring of n grains) only implements the methods below.
"""

from __future__ import annotations

from typing import Mapping, Protocol, runtime_checkable

import numpy as np

from ncstab.laws.definition import ParameterSpec

__all__ = ["DiscreteSystem", "conjugate_forces"]


def conjugate_forces(length: np.ndarray, normal: np.ndarray, tangential: np.ndarray) -> np.ndarray:
    """Work-conjugates of (l, alpha): Q = (-N, l T), seed Eq. (9)/(16).

    Returns
    -------
    numpy.ndarray
        Shape ``broadcast(length, normal, tangential) + (2,)``.
    """
    return np.stack(np.broadcast_arrays(-normal, length * tangential), axis=-1)


@runtime_checkable
class DiscreteSystem(Protocol):
    """What the operators and the path engine need from a discrete system."""

    name: str
    #: Names of the generalized displacements, e.g. ``("D1", "D2")``.
    dof_names: tuple[str, ...]
    #: Names of the conjugate generalized forces, e.g. ``("F1", "F2")``.
    force_names: tuple[str, ...]
    #: Number of contact families (each with variables (l, alpha)).
    n_contacts: int
    #: Parameters of the system (validated like law parameters).
    parameter_specs: tuple[ParameterSpec, ...]
    #: Validated parameter values.
    parameters: Mapping[str, np.ndarray]

    @property
    def n_dof(self) -> int: ...

    @property
    def contact_weights(self) -> np.ndarray:
        """Weights ``w_c``, shape ``(n_contacts,)``."""
        ...

    def contact_variables(self, u: np.ndarray) -> np.ndarray:
        """q = (l, alpha) per contact, shape ``(..., n_contacts, 2)``."""
        ...

    def displacements(self, q: np.ndarray) -> np.ndarray:
        """Inverse kinematics u(q) where it exists, shape ``(..., n_dof)``."""
        ...

    def contact_jacobian(self, q: np.ndarray) -> np.ndarray:
        """J = dq/du, shape ``(..., n_contacts, 2, n_dof)``."""
        ...

    def contact_hessian(self, q: np.ndarray) -> np.ndarray:
        """H = d2q/du2, shape ``(..., n_contacts, 2, n_dof, n_dof)``."""
        ...

    def mass_matrix(self) -> np.ndarray:
        """Mass matrix, shape ``(..., n_dof, n_dof)``."""
        ...

    def secondary_gaps(self, q: np.ndarray) -> np.ndarray:
        """Distances (units 2R) to new contacts minus one; < 0 means overlap."""
        ...
