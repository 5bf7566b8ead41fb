"""The four-grain diamond chain of the seed (Figs. 1-2).

Two degrees of freedom (Delta_1*, Delta_2*) loaded by (F_1*, F_2*), one family of
four identical contacts with branch variables (l*, alpha).  Everything is in the
dimensionless variables of seed Eq. (37): lengths in units of 2R, forces in
units of 2R k_n.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ncstab.laws.definition import ALPHA0_SPEC, ParameterSpec
from ncstab.systems.protocol import conjugate_forces

__all__ = ["DiamondChain"]


@dataclass(frozen=True)
class DiamondChain:
    """Four rigid grains in a diamond, reduced to two dofs by symmetry.

    Parameters
    ----------
    alpha0
        Initial branch orientation from the vertical axis (rad), in (0, pi/2);
        scalar or array (one value per case of a sweep).

    Notes
    -----
    Kinematics, seed Eq. (1) and (3):
    ``l cos(alpha) = cos(alpha0) - Delta_1``, ``l sin(alpha) = sin(alpha0) - Delta_2``.
    Rates, seed Eq. (10)-(11): ``dl = -cos(a) dD1 - sin(a) dD2``,
    ``l dalpha = sin(a) dD1 - cos(a) dD2``.
    Equilibrium, seed Eq. (4): ``F1 = 2 N cos a + 2 T sin a``,
    ``F2 = 2 N sin a - 2 T cos a``.
    """

    alpha0: object = np.pi / 4
    name: str = "diamond"
    dof_names: tuple[str, ...] = ("D1", "D2")
    force_names: tuple[str, ...] = ("F1", "F2")
    n_contacts: int = 1
    parameter_specs: tuple[ParameterSpec, ...] = (ALPHA0_SPEC,)
    parameters: Mapping[str, np.ndarray] = field(init=False)

    def __post_init__(self) -> None:
        object.__setattr__(self, "parameters", {"alpha0": ALPHA0_SPEC.validate(self.alpha0)})

    @property
    def n_dof(self) -> int:
        return 2

    @property
    def contact_weights(self) -> np.ndarray:
        return np.array([2.0])

    @property
    def _alpha0(self) -> np.ndarray:
        return self.parameters["alpha0"]

    # --- kinematics -------------------------------------------------------------------
    def contact_variables(self, u: np.ndarray) -> np.ndarray:
        """(l*, alpha) from (Delta_1*, Delta_2*), seed Eq. (1), shape ``(..., 1, 2)``."""
        u = np.asarray(u, dtype=float)
        vertical = np.cos(self._alpha0) - u[..., 0]
        horizontal = np.sin(self._alpha0) - u[..., 1]
        length = np.hypot(vertical, horizontal)
        alpha = np.arctan2(horizontal, vertical)
        return np.stack([length, alpha], axis=-1)[..., None, :]

    def displacements(self, q: np.ndarray) -> np.ndarray:
        """(Delta_1*, Delta_2*) from (l*, alpha), seed Eq. (3) and (46)."""
        q = np.asarray(q, dtype=float)
        length, alpha = q[..., 0, 0], q[..., 0, 1]
        return np.stack(
            [np.cos(self._alpha0) - length * np.cos(alpha), np.sin(self._alpha0) - length * np.sin(alpha)],
            axis=-1,
        )

    def contact_jacobian(self, q: np.ndarray) -> np.ndarray:
        """J = d(l, alpha)/d(Delta_1, Delta_2), seed Eq. (10)-(11), ``(..., 1, 2, 2)``."""
        q = np.asarray(q, dtype=float)
        length, alpha = q[..., 0, 0], q[..., 0, 1]
        c, s = np.cos(alpha), np.sin(alpha)
        row_l = np.stack([-c, -s], axis=-1)
        row_alpha = np.stack([s, -c], axis=-1) / length[..., None]
        return np.stack([row_l, row_alpha], axis=-2)[..., None, :, :]

    def contact_hessian(self, q: np.ndarray) -> np.ndarray:
        """H = d2(l, alpha)/du2, ``(..., 1, 2, 2, 2)``.

        With c = (cos a, sin a) and s = (sin a, -cos a):
        d2l/du2 = s s^T / l and d2alpha/du2 = (c s^T + s c^T) / l^2.
        """
        q = np.asarray(q, dtype=float)
        length, alpha = q[..., 0, 0], q[..., 0, 1]
        c = np.stack([np.cos(alpha), np.sin(alpha)], axis=-1)
        s = np.stack([np.sin(alpha), -np.cos(alpha)], axis=-1)
        outer_ss = s[..., :, None] * s[..., None, :]
        outer_cs = c[..., :, None] * s[..., None, :]
        h_l = outer_ss / length[..., None, None]
        h_alpha = (outer_cs + np.swapaxes(outer_cs, -1, -2)) / length[..., None, None] ** 2
        return np.stack([h_l, h_alpha], axis=-3)[..., None, :, :, :]

    @staticmethod
    def symbolic_kinematics(length, cos_alpha, sin_alpha):
        """J and H of :meth:`contact_jacobian` / :meth:`contact_hessian` as sympy matrices.

        In terms of symbols for l, cos(alpha) and sin(alpha), for the one
        contact family; used once, when a fused evaluation kernel is compiled
        (:func:`ncstab.operators.tangent.compile_state_kernel`).

        Returns
        -------
        (J, (H_l, H_alpha))
            2x2 sympy matrices.
        """
        import sympy as sp

        c, s, l = cos_alpha, sin_alpha, length
        jacobian = sp.Matrix([[-c, -s], [s / l, -c / l]])
        c_vec, s_vec = sp.Matrix([c, s]), sp.Matrix([s, -c])
        h_l = s_vec * s_vec.T / l
        h_alpha = (c_vec * s_vec.T + s_vec * c_vec.T) / l**2
        return jacobian, (h_l, h_alpha)

    # --- statics ----------------------------------------------------------------------
    def generalized_forces(self, q: np.ndarray, normal: np.ndarray, tangential: np.ndarray) -> np.ndarray:
        """F = sum_c w_c J_c^T Q_c, seed Eq. (4)/(12); shape ``(..., 2)``.

        ``normal`` and ``tangential`` have shape ``(..., n_contacts)``.
        """
        jacobian = self.contact_jacobian(q)
        conjugate = conjugate_forces(q[..., 0], normal, tangential)
        return np.einsum("c,...cki,...ck->...i", self.contact_weights, jacobian, conjugate)

    def contact_forces(self, q: np.ndarray, forces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Invert Eq. (4): N = (F1 cos a + F2 sin a)/2, T = (F1 sin a - F2 cos a)/2.

        Returns arrays of shape ``(..., 1)`` (one contact family).
        """
        q, forces = np.asarray(q, dtype=float), np.asarray(forces, dtype=float)
        alpha = q[..., 0, 1]
        f1, f2 = forces[..., 0], forces[..., 1]
        normal = (f1 * np.cos(alpha) + f2 * np.sin(alpha)) / 2
        tangential = (f1 * np.sin(alpha) - f2 * np.cos(alpha)) / 2
        return normal[..., None], tangential[..., None]

    def mass_matrix(self) -> np.ndarray:
        """Identity in units of the grain mass.

        Each dof moves two grains (top and bottom, or left and right) by
        Delta_i; with the per-contact external work F . dDelta / 2 (seed Eq. 5),
        Lagrange's equations read m u'' = F - (internal forces), so M = m I.
        """
        return np.broadcast_to(np.eye(2), np.shape(self._alpha0) + (2, 2))

    def secondary_gaps(self, q: np.ndarray) -> np.ndarray:
        """Centre distances of the non-neighbour grains minus 2R, units of 2R.

        Top-bottom: 2 l* cos(alpha) - 1; left-right: 2 l* sin(alpha) - 1
        (seed Figs. 14-15).  A new contact appears where a gap reaches 0.
        Shape ``(..., 2)`` ordered (top_bottom, left_right).
        """
        length, alpha = q[..., 0, 0], q[..., 0, 1]
        return np.stack([2 * length * np.cos(alpha) - 1, 2 * length * np.sin(alpha) - 1], axis=-1)

    def secondary_gap_names(self) -> tuple[str, str]:
        return ("top_bottom", "left_right")

    def secondary_forces(self, u: np.ndarray, kappa: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """Generalized forces of the secondary contacts once they touch, ``(..., 2)``.

        A frictionless unilateral normal spring of stiffness kappa k_n acts
        between top and bottom grains (centre distance d = 2 (cos alpha0 -
        Delta_1) in units of 2R) and between left and right ones
        (d = 2 (sin alpha0 - Delta_2)).  With its energy
        kappa <1 - d>^2 / 2 and the per-contact external work F . du / 2
        (seed Eq. 5, four primary contacts), it adds kappa <1 - d> to F_1
        (resp. F_2).  ``active`` (``(..., 2)`` bool) forces which springs act
        (then kappa (1 - d) without the bracket: the smooth branch an
        event-driven integrator follows within a step); by default those with
        1 - d > 0.
        """
        overlap = self._secondary_overlaps(u)
        if active is None:
            active = overlap > 0.0
        return np.asarray(kappa)[..., None] * np.where(active, overlap, 0.0)

    def secondary_stiffness(self, u: np.ndarray, kappa: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """Tangent of :meth:`secondary_forces`: diag(2 kappa [spring active]), ``(..., 2, 2)``."""
        overlap = self._secondary_overlaps(u)
        if active is None:
            active = overlap > 0.0
        diagonal = 2.0 * np.asarray(kappa)[..., None] * active
        return diagonal[..., :, None] * np.eye(2)

    def _secondary_overlaps(self, u: np.ndarray) -> np.ndarray:
        u = np.asarray(u, dtype=float)
        top_bottom = 1.0 - 2.0 * (np.cos(self._alpha0) - u[..., 0])
        left_right = 1.0 - 2.0 * (np.sin(self._alpha0) - u[..., 1])
        return np.stack([top_bottom, left_right], axis=-1)
