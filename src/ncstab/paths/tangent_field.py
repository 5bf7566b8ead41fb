"""The tangent of a loading path (null space of the constrained rate system), and each case's stage.

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

A system with a load parameter P (``F = R(u, P)``, R the internal forces
minus the loads) has ``P = P_offset + P_slope lambda`` in every stage (held:
slope 0; a load-parameter stage drives it), so the constraint reads
``M du = (g' - Q dR/dP P_slope) dlambda``: the cofactor tangent and the
Newton projection take this effective ``g'`` (:func:`effective_rate`).

Where the cofactor vector passes through zero -- a simple bifurcation point,
where M is singular and the effective g' lies in its range -- its sign flips
while the path goes straight on.  Each state's tangent is therefore also
oriented by continuity: against the motion at the start of the current step
(``StageArrays.reference``), the orientation being flipped where their
product is negative.  On a regular path (limit points included: there the
cofactor vector is smooth and non-zero) this never flips anything.  The
component of the (oriented, unflipped) cofactor vector along that motion is
the *branch test*: it changes sign exactly where the cofactor vector passes
through zero and turns against the motion (a simple bifurcation point: it is
the bordered determinant det [[M, -g'], [t^T]] of a continuation code), and
never at a limit point, where the cofactor vector turns smoothly with the path.

The compiled loop computes the tangent, orients it so and computes the branch
test (``tangent`` or ``tangent_at`` and ``branch_size`` in its model parts,
:mod:`ncstab.paths.compiled`: the 2 x 2 closed form of the reduced diamond, or
:func:`ncstab.paths.cofactor.cofactor_vector` for any n); stage entry reads the
unoriented rate of lambda from it (``settle``).  This module holds each case's
stage (:class:`StageArrays`) and the control matrix and rate that branch
switching differentiates (:mod:`ncstab.paths.branch_switching`).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

__all__ = ["StageArrays", "control_matrix", "effective_rate"]


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
    center, radius, theta0, turn_direction, cycle_axes
        Circle of a cycle stage in the plane of the dofs ``cycle_axes``
        ``(B, 2)``: u[axes] = center + radius (cos, sin)(theta0 + dir lambda);
        the other dofs follow offset + slope lambda (their forces held).
    load_offset, load_slope
        ``(B,)``: the load parameter is load_offset + load_slope lambda.
    lam_end
        ``(B,)`` target of lambda.
    target_sign
        ``(B,)`` +1 if lambda increases toward its target, -1 otherwise.
    orientation
        ``(B,)`` sign applied to the cofactor tangent, fixed at stage entry.
    reference
        ``(B, 2n + 1)`` the motion (du, dF, dlambda) at the start of the
        current step (NaN at a stage's start): each tangent is oriented to
        continue it (see the module docstring).
    switch
        ``(B,)`` int: at the stage's first simple bifurcation point, 0 goes on
        along the branch followed, +1 or -1 leaves along the bifurcating
        branch that way (:mod:`ncstab.paths.branch_switching`).
    switched
        ``(B,)`` bool: the case has switched branch in this stage.
    secondary_state
        ``(B,)`` int: the contact-state bits (which gaps are closed, which
        normal contacts of no_tension laws are open), frozen within a step and
        switched only where a gap crossing is located (so every step
        integrates a smooth field).  Carries over from stage to stage.  Pure-shear
        limit: 0 free, 1 blocked by the top-bottom contact, 2 by the left-right one.
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
    cycle_axes: np.ndarray
    load_offset: np.ndarray
    load_slope: np.ndarray
    lam_end: np.ndarray
    target_sign: np.ndarray
    orientation: np.ndarray
    reference: np.ndarray
    switch: np.ndarray
    switched: np.ndarray
    secondary_state: np.ndarray
    cycles_done: np.ndarray

    @classmethod
    def empty(cls, size: int, n: int) -> "StageArrays":
        return cls(
            force_controlled=np.zeros((size, n), dtype=bool),
            offset=np.zeros((size, n)),
            slope=np.zeros((size, n)),
            is_cycle=np.zeros(size, dtype=bool),
            center=np.zeros((size, 2)),
            radius=np.zeros(size),
            theta0=np.zeros(size),
            turn_direction=np.ones(size),
            cycle_axes=np.tile(np.array([0, min(1, n - 1)]), (size, 1)),
            load_offset=np.zeros(size),
            load_slope=np.zeros(size),
            lam_end=np.zeros(size),
            target_sign=np.ones(size),
            orientation=np.ones(size),
            reference=np.full((size, 2 * n + 1), np.nan),
            switch=np.zeros(size, dtype=int),
            switched=np.zeros(size, dtype=bool),
            secondary_state=np.zeros(size, dtype=int),
            cycles_done=np.zeros(size, dtype=int),
        )

    def take(self, index: np.ndarray) -> "StageArrays":
        return StageArrays(**{f.name: getattr(self, f.name)[index] for f in fields(self)})

    def put(self, index: np.ndarray, other: "StageArrays") -> None:
        for f in fields(self):
            getattr(self, f.name)[index] = getattr(other, f.name)

    def load(self, lam: np.ndarray) -> np.ndarray:
        """The load parameter at lambda, ``(B,)``."""
        return self.load_offset + self.load_slope * lam

    def control_path(self, lam: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """g(lambda) and g'(lambda), each ``(B, n)``."""
        linear_g = self.offset + self.slope * lam[:, None]
        if not self.is_cycle.any():  # elementwise either way: the same bits per case
            return linear_g, self.slope
        angle = self.theta0 + self.turn_direction * lam
        cos, sin = np.cos(angle), np.sin(angle)
        rows = np.arange(lam.shape[0])
        first, second = self.cycle_axes[:, 0], self.cycle_axes[:, 1]
        circle_g, circle_dg = linear_g.copy(), self.slope.copy()
        circle_g[rows, first] = self.center[:, 0] + self.radius * cos
        circle_g[rows, second] = self.center[:, 1] + self.radius * sin
        rate = self.radius * self.turn_direction
        circle_dg[rows, first] = rate * -sin
        circle_dg[rows, second] = rate * cos
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


def effective_rate(stage: StageArrays, dg: np.ndarray, dF_dload: np.ndarray | None) -> np.ndarray:
    """g' - Q dF/dP P_slope: the rate of the constraint in lambda with the load moving.

    ``dF_dload`` (``(B, n)``, dR/dP = -Q_ext) is ``None`` for a system without a
    load parameter: then g' itself (the same array).
    """
    if dF_dload is None:
        return dg
    return dg - np.where(stage.force_controlled, dF_dload, 0.0) * stage.load_slope[:, None]
