"""Ziegler's pendulum as an assembled system: a chain of n rigid bars under a tip load.

The same system as the derived :func:`ncstab.systems.bars.ziegler` (``links = n``, n = 2
Ziegler's pendulum; checked against it in the tests, R, K, M and C to 1e-12), built from
elements so that any n runs on the sparse engine (:mod:`ncstab.paths.assembled_path`):

* dofs ``phi1 .. phin``, the bars' absolute angles from the vertical (rad), forces
  ``M1 .. Mn`` (units k); bars of length l = 1;
* linear rotational springs (:class:`~ncstab.elements.LinearSprings`, law
  ``linear_spring``): q = phi1 at the base, q = phi_{j+1} - phi_j at joint j;
* a tip load P (units k/l), follower or dead (:class:`~ncstab.elements.TipLoad`);
* inertia (:class:`ChainInertia`): point masses m_k at the end of bar k (m1 at every joint
  between two bars, m2 at the tip) and dashpots (b1 at the base, b2 at every other joint):

      M_ij(phi) = cos(phi_i - phi_j) sum_{k >= max(i, j)} m_k,
      C = sum_k b_k d_k d_k^T,  d_1 = e_1, d_k = e_k - e_{k-1}.

As n grows the chain is the discretised Beck column (Beck 1952): a cantilever of length
L = n l and bending stiffness EI = k l (a spring k over each bar of length l) whose mass
is lumped at the joints (2 at each, half at the tip: the default m1 = 2, m2 = 1 is a
uniform column).  Its flutter load P_n (units k/l) gives P_n n^2 = P_n L^2 / EI, which
tends to Beck's 20.05 like 1/n (18.96 at 20 bars, 19.53 at 40: docs/assembled-systems.md).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.elements import LinearSprings, TipLoad
from ncstab.laws.spring import LINEAR_SPRING
from ncstab.systems.assembled import AssembledSystem
from ncstab.systems.bars import (
    ZIEGLER_LOADS,
    ZIEGLER_REFERENCE,
    ZIEGLER_UNITS,
    chain_parameters,
    ziegler_member_names,
    ziegler_title,
)

__all__ = ["ChainInertia", "assembled_ziegler", "chain_transform"]


def chain_transform(n: int) -> np.ndarray:
    """T ``(n, n)``, lower bidiagonal (1 on the diagonal, -1 below), det T = 1.

    With phi = T v, v_k = phi_1 + ... + phi_k is the lateral displacement of joint k (l = 1,
    to first order), and T^T M T is diagonal on the straight chain (diag(m_k)): the pencil
    (T^T M T, T^T C T, T^T K T) has the characteristic polynomial of (M, C, K) itself,
    det(T)^2 = 1, with a well-conditioned mass matrix.
    """
    return np.eye(n) - np.eye(n, k=-1)


@dataclass(frozen=True, eq=False)
class ChainInertia:
    """The mass and damping matrices of a chain of n bars (see the module docstring).

    Attributes
    ----------
    masses
        m_k at the end of bar k, ``(n,)`` (the last at the tip).
    dashpots
        b_k at the start of bar k, ``(n,)`` (the first at the base).
    """

    masses: np.ndarray
    dashpots: np.ndarray

    @staticmethod
    def of(n: int, values: dict[str, float]) -> ChainInertia:
        """The chain's inertia for the parameters ``m1``, ``m2``, ``b1``, ``b2`` in ``values``
        (their defaults where absent: 2, 1, 0, 0)."""
        m1, m2 = float(values.get("m1", 2.0)), float(values.get("m2", 1.0))
        b1, b2 = float(values.get("b1", 0.0)), float(values.get("b2", 0.0))
        return ChainInertia(np.append(np.full(n - 1, m1), m2), np.append(b1, np.full(n - 1, b2)))

    def for_values(self, values: dict[str, float]) -> ChainInertia:
        return ChainInertia.of(len(self.masses), values)

    def mass(self, u: np.ndarray) -> np.ndarray:
        """M(u) ``(n, n)``: M_ij = cos(u_i - u_j) sum_{k >= max(i, j)} m_k."""
        n = len(self.masses)
        tail = np.cumsum(self.masses[::-1])[::-1]
        index = np.arange(n)
        return tail[np.maximum.outer(index, index)] * np.cos(u[:, None] - u[None, :])

    def damping(self) -> np.ndarray:
        """C ``(n, n)`` = D^T diag(b) D, D the differences (D phi)_k = phi_k - phi_{k-1} (phi_0 = 0)."""
        D = chain_transform(len(self.masses))
        return D.T @ (self.dashpots[:, None] * D)

    def pencil(self, u: np.ndarray, K) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(T^T M T, T^T C T, T^T K T) at u (:func:`chain_transform`): the same roots s of
        det(M s^2 + C s + K) = 0, with M nearly diagonal (the functions of
        :mod:`ncstab.operators.dynamics` refuse a mass matrix whose determinant is small
        against the product of its column norms, as the chain's M is for n >= 15)."""
        T = chain_transform(len(self.masses))
        dense = K.toarray() if hasattr(K, "toarray") else np.asarray(K)
        return T.T @ self.mass(u) @ T, T.T @ self.damping() @ T, T.T @ dense @ T


def assembled_ziegler(links: int = 2, load: str = "follower") -> AssembledSystem:
    """Ziegler's chain of ``links`` rigid bars (n >= 2) under a ``follower`` or ``dead`` tip load P."""
    if isinstance(links, bool) or not isinstance(links, int) or links < 2:
        raise ValueError(f"Ziegler's chain needs links >= 2 (a whole number), got {links!r}")
    if load not in ZIEGLER_LOADS:
        raise ValueError(f"load = {load!r} is not allowed; allowed: {', '.join(ZIEGLER_LOADS)}")
    n = links
    joints = np.arange(1, n)
    dofs = np.vstack([[0, 0], np.stack([joints - 1, joints], axis=1)])  # base: phi1 (padded); joint j: phi_j, phi_{j+1}
    coefficients = np.vstack([[1.0, 0.0], np.tile([-1.0, 1.0], (n - 1, 1))])
    return AssembledSystem(
        name="ziegler",
        title=ziegler_title(n, load),
        dofs=tuple(f"phi{i}" for i in range(1, n + 1)),
        forces=tuple(f"M{i}" for i in range(1, n + 1)),
        springs=LinearSprings(ziegler_member_names(n), dofs, coefficients),
        spring_law=LINEAR_SPRING,
        tip_load=TipLoad(load, np.arange(n), description=f"{load} tip load P (units k/l)"),
        inertia=ChainInertia.of(n, {}),
        units=ZIEGLER_UNITS,
        settings=(("load", load),) if n == 2 else (("links", n), ("load", load)),
        reference=ZIEGLER_REFERENCE,
        system_parameters=chain_parameters(n),
    )
