"""The tangent of a loading path: null space of the constrained rate system.

Along a stage every dof i has either its displacement or its force prescribed:
``P du + Q dF = g'(lambda) dlambda`` with P, Q complementary diagonal selections
(Q = force-controlled) and g the stage's control path (a straight line for a
linear stage, a circle for a cycle stage).  With dF = K du this is
``M du = g' dlambda`` where M = P + Q K is the *control matrix* (rows of K for
force-controlled dofs, identity rows otherwise; det M = det K_SS is the
mixed-control determinant).  In state coordinates v (u = u(v), F = F(v)) the
same holds with M = P du/dv + Q dF/dv.  Its one-dimensional null space is spanned by the
cofactor vector

    (du, dlambda) = (adj(M) g', det M),

smooth in the state and defined through turning points of lambda (where det M
changes sign, lambda simply turns back): pseudo-arclength needs nothing else.
The tangent is normalised in (u, F, lambda) and oriented once per stage.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

from ncstab.operators.indicators import det_K

__all__ = ["StageArrays", "adjugate", "control_matrix", "path_tangent"]


def adjugate(matrix: np.ndarray) -> np.ndarray:
    """Adjugate (transposed cofactor matrix) of ``(..., n, n)`` matrices.

    ``matrix @ adjugate(matrix) = det(matrix) I`` holds even where the matrix
    is singular.  Closed form for n = 1, 2; cofactors otherwise.
    """
    n = matrix.shape[-1]
    if n == 1:
        return np.ones_like(matrix)
    if n == 2:
        out = np.empty_like(matrix)
        out[..., 0, 0] = matrix[..., 1, 1]
        out[..., 1, 1] = matrix[..., 0, 0]
        out[..., 0, 1] = -matrix[..., 0, 1]
        out[..., 1, 0] = -matrix[..., 1, 0]
        return out
    cofactors = np.empty_like(matrix)
    for i in range(n):
        for j in range(n):
            minor = np.delete(np.delete(matrix, i, axis=-2), j, axis=-1)
            cofactors[..., i, j] = (-1) ** (i + j) * np.linalg.det(minor)
    return np.swapaxes(cofactors, -1, -2)


@dataclass
class StageArrays:
    """Per-case description of the current stage (all arrays with leading B).

    Attributes
    ----------
    force_controlled
        ``(B, n)`` bool: dof i prescribed through F_i.
    offset, slope
        ``(B, n)``: for a linear stage, prescribed values = offset + slope lambda.
    is_cycle
        ``(B,)`` bool.
    center, radius, theta0, turn_direction
        Circle of a cycle stage: u = center + radius (cos, sin)(theta0 + dir lambda).
    lam_end
        ``(B,)`` target of lambda.
    target_sign
        ``(B,)`` +1 if lambda increases toward its target, -1 otherwise.
    orientation
        ``(B,)`` sign applied to the cofactor tangent, fixed at stage entry.
    secondary_state
        ``(B,)`` int: which secondary contacts are closed, frozen within a step
        and switched only where a gap crossing is located (so every step
        integrates a smooth field).  Deformable system: bit 0 top-bottom, bit 1
        left-right springs active.  Pure-shear limit: 0 free, 1 blocked by the
        top-bottom contact, 2 by the left-right one.  Carries over from stage
        to stage.
    cycles_done
        ``(B,)`` int: turns completed in the current cycle stage.
    """

    force_controlled: np.ndarray
    offset: np.ndarray
    slope: np.ndarray
    is_cycle: np.ndarray
    center: np.ndarray
    radius: np.ndarray
    theta0: np.ndarray
    turn_direction: np.ndarray
    lam_end: np.ndarray
    target_sign: np.ndarray
    orientation: np.ndarray
    secondary_state: np.ndarray
    cycles_done: np.ndarray

    @classmethod
    def empty(cls, size: int, n: int) -> "StageArrays":
        return cls(
            force_controlled=np.zeros((size, n), dtype=bool),
            offset=np.zeros((size, n)),
            slope=np.zeros((size, n)),
            is_cycle=np.zeros(size, dtype=bool),
            center=np.zeros((size, n)),
            radius=np.zeros(size),
            theta0=np.zeros(size),
            turn_direction=np.ones(size),
            lam_end=np.zeros(size),
            target_sign=np.ones(size),
            orientation=np.ones(size),
            secondary_state=np.zeros(size, dtype=int),
            cycles_done=np.zeros(size, dtype=int),
        )

    def take(self, index: np.ndarray) -> "StageArrays":
        return StageArrays(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def put(self, index: np.ndarray, other: "StageArrays") -> None:
        for f in fields(self):
            getattr(self, f.name)[index] = getattr(other, f.name)

    def control_path(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g(lambda) and g'(lambda), each ``(B, n)``."""
        if not self.is_cycle.any():  # elementwise either way: the same bits per case
            return self.offset + self.slope * lam[:, None], self.slope
        angle = self.theta0 + self.turn_direction * lam
        unit = np.stack([np.cos(angle), np.sin(angle)], axis=-1) if self.center.shape[-1] == 2 else None
        linear_g = self.offset + self.slope * lam[:, None]
        if unit is None:
            return linear_g, self.slope
        circle_g = self.center + self.radius[:, None] * unit
        circle_dg = (self.radius * self.turn_direction)[:, None] * np.stack([-unit[:, 1], unit[:, 0]], -1)
        cyc = self.is_cycle[:, None]
        return np.where(cyc, circle_g, linear_g), np.where(cyc, circle_dg, self.slope)

    def residual(self, u: np.ndarray, forces: np.ndarray, lam: np.ndarray) -> np.ndarray:
        """Control residual P u + Q F - g(lambda), ``(B, n)``."""
        g, _ = self.control_path(lam)
        return np.where(self.force_controlled, forces, u) - g


def control_matrix(du_dv: np.ndarray, df_dv: np.ndarray, force_controlled: np.ndarray) -> np.ndarray:
    """M = P du/dv + Q dF/dv: rows of dF/dv for force-controlled dofs, of du/dv otherwise.

    For a deformable system (v = u) this is P + Q K, whose determinant is the
    mixed-control determinant det K_SS.
    """
    return np.where(force_controlled[..., :, None], df_dv, du_dv)


def path_tangent(
    du_dv: np.ndarray, df_dv: np.ndarray, stage: StageArrays, lam: np.ndarray, oriented: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Unit tangent of the path in state coordinates, and det M.

    Normalised so that |du|^2 + |dF|^2 + dlambda^2 = 1 with du = (du/dv) dv and
    dF = (dF/dv) dv.

    Returns
    -------
    (dv, du, dlam, det_m)
        ``(B, n)``, ``(B, n)``, ``(B,)``, ``(B,)``; NaN where the null space is
        not one-dimensional (adj(M) g' = 0 and det M = 0).
    """
    _, dg = stage.control_path(lam)
    if dg.shape[-1] == 2:
        return _path_tangent_2(du_dv, df_dv, stage, dg, oriented)
    matrix = control_matrix(du_dv, df_dv, stage.force_controlled)
    det_m = det_K(matrix)
    dv = (adjugate(matrix) @ dg[:, :, None])[:, :, 0]
    dlam = det_m
    du = (du_dv @ dv[:, :, None])[:, :, 0]
    df = (df_dv @ dv[:, :, None])[:, :, 0]
    norm = np.sqrt(np.sum(du**2, -1) + np.sum(df**2, -1) + dlam**2)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(norm > 0, 1.0 / norm, np.nan)
    if oriented:
        scale = scale * stage.orientation
    return dv * scale[:, None], du * scale[:, None], dlam * scale, det_m


def _path_tangent_2(
    du_dv: np.ndarray, df_dv: np.ndarray, stage: StageArrays, dg: np.ndarray, oriented: bool
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`path_tangent` for n = 2 in closed form: the adjugate, det M and the
    products with du/dv and dF/dv written out entry by entry (no (B, 2, 2)
    temporaries, no matmul)."""
    fc0, fc1 = stage.force_controlled[:, 0], stage.force_controlled[:, 1]
    m00 = np.where(fc0, df_dv[:, 0, 0], du_dv[:, 0, 0])
    m01 = np.where(fc0, df_dv[:, 0, 1], du_dv[:, 0, 1])
    m10 = np.where(fc1, df_dv[:, 1, 0], du_dv[:, 1, 0])
    m11 = np.where(fc1, df_dv[:, 1, 1], du_dv[:, 1, 1])
    det_m = m00 * m11 - m01 * m10
    g0, g1 = dg[:, 0], dg[:, 1]
    dv = np.empty(dg.shape)
    dv[:, 0] = m11 * g0 - m01 * g1
    dv[:, 1] = m00 * g1 - m10 * g0
    dv0, dv1 = dv[:, 0], dv[:, 1]
    du = np.empty(dg.shape)
    du[:, 0] = du_dv[:, 0, 0] * dv0 + du_dv[:, 0, 1] * dv1
    du[:, 1] = du_dv[:, 1, 0] * dv0 + du_dv[:, 1, 1] * dv1
    df0 = df_dv[:, 0, 0] * dv0 + df_dv[:, 0, 1] * dv1
    df1 = df_dv[:, 1, 0] * dv0 + df_dv[:, 1, 1] * dv1
    du0, du1 = du[:, 0], du[:, 1]
    norm = np.sqrt((du0 * du0 + du1 * du1) + (df0 * df0 + df1 * df1) + det_m * det_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        scale = np.where(norm > 0, 1.0 / norm, np.nan)
    if oriented:
        scale = scale * stage.orientation
    dv *= scale[:, None]
    du *= scale[:, None]
    return dv, du, det_m * scale, det_m
