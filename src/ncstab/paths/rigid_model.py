"""The pure-shear limit of the diamond (rigid normal contacts), seed Eq. (60)-(68).

With k_n -> infinity the branch length is fixed by the law, l = lbar(alpha)
(:func:`ncstab.symbolic.rigid.rigid_limit`), the normal force is a reaction
Nhat, and forces are in units of 2R k_t (Eq. 62).  The engine integrates the
state coordinates

* v = (alpha, Nhat) while the chain is free: u = u(alpha) by Eq. (3) with
  l = lbar, F = F(alpha, Nhat) by Eq. (4);
* v = (Nhat, Rhat) once a rigid secondary contact has closed (blocking,
  Eq. 66-68): alpha is frozen, u is constant, and the reaction Rhat of the
  new contact adds to F1 (top-bottom) or F2 (left-right).

The tangent operator K = dF/du is undefined on the constraint (u moves on a
curve): K and the indicators built on it are NaN; the control determinant,
turning points and secondary contacts are located as usual.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.laws.registry import Law
from ncstab.paths.model import DiamondBatchTraits, Evaluation
from ncstab.symbolic.rigid import RigidLimit, rigid_limit
from ncstab.systems.diamond import DiamondChain

__all__ = ["RigidCaseBatch"]

#: Which gap blocked a chain (its state; 0: free).
TOP_BOTTOM, LEFT_RIGHT = 1, 2


@dataclass(frozen=True)
class RigidCaseBatch(DiamondBatchTraits):
    """B cases of one law on the diamond with rigid normal contacts.

    Internal variables: That for a rate law (Cundall--Strack), then the
    orientation frozen by a blocking contact (always present, rate 0).
    """

    system: DiamondChain
    law: Law
    activate_secondary: bool

    @property
    def rigid(self) -> RigidLimit:
        return rigid_limit(self.law.definition)

    @property
    def n_dof(self) -> int:
        return 2

    @property
    def has_total_form(self) -> bool:
        return self.rigid.tangential is not None

    @property
    def n_internal(self) -> int:
        return (0 if self.has_total_form else 1) + 1

    @property
    def force_unit(self) -> str:
        return "2R k_t"

    @property
    def size(self) -> int:
        return int(np.size(self.system.parameters["alpha0"]))

    @property
    def _alpha0(self) -> np.ndarray:
        return self.system.parameters["alpha0"]

    def take(self, index: np.ndarray) -> "RigidCaseBatch":
        alpha0 = self._alpha0[index] if np.ndim(self._alpha0) else self._alpha0
        law = Law(self.law.definition, {k: (v[index] if np.ndim(v) else v) for k, v in self.law.parameters.items()})
        return RigidCaseBatch(DiamondChain(alpha0=alpha0), law, self.activate_secondary)

    def initial_secondary_state(self, v: np.ndarray) -> np.ndarray:
        """The chain starts free (no blocking contact)."""
        return np.zeros(v.shape[0], dtype=int)

    def initial_state(self) -> np.ndarray:
        """Unloaded state: alpha = alpha0, Nhat = 0."""
        alpha0 = np.broadcast_to(self._alpha0, (self.size,))
        return np.column_stack([alpha0, np.zeros(self.size)])

    def evaluate(
        self,
        v: np.ndarray,
        internal: np.ndarray,
        blocked: np.ndarray | None = None,
        geometry_only: bool = False,
        load: np.ndarray | None = None,
    ) -> Evaluation:
        """u(v), F(v), their Jacobians and the contact state (seed Eq. 3, 4, 61-65), from the
        law's compiled kernel (:func:`ncstab.paths.compiled_rigid.rigid_rows`, the compiled
        loop's too).

        ``geometry_only`` and ``load`` are ignored (everything is cheap here; no load).
        """
        from ncstab.paths.compiled_rigid import rigid_row, rigid_rows

        size = v.shape[0]
        blocked = np.zeros(size, dtype=int) if blocked is None else blocked
        alpha0 = np.broadcast_to(np.asarray(self._alpha0, dtype=float), (size,))
        rows = rigid_rows(self.law.definition, v, internal, blocked, alpha0)
        at = rigid_row(not self.has_total_form)
        u, du, df, q = at["coordinates"], at["coordinates"] + 2, at["coordinates"] + 6, at["interactions"]
        return Evaluation(
            rows[:, None, q : q + 2], rows[:, q + 2 : q + 3], rows[:, q + 3 : q + 4], rows[:, u : u + 2],
            rows[:, 0:2], rows[:, at["stiffness"] : at["stiffness"] + 4].reshape(size, 2, 2),
            rows[:, du : du + 4].reshape(size, 2, 2), rows[:, df : df + 4].reshape(size, 2, 2),
            rows[:, at["gaps"] : at["gaps"] + 2], np.full(size, np.nan),
        )
