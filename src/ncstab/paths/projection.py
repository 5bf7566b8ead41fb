"""The Newton projection onto equilibrium, for a batch of states (numpy).

For a law with a total form the forces are functions of the state, so every
accepted step is projected back onto the manifold of the constraints
``P u(v) + Q F(v, P(lambda)) = g(lambda)`` (equilibrium under the stage's
mixed control): minimum-norm Gauss--Newton corrections of (v, lambda), the
system having one more unknown than equations.  With A = [M | -g'_eff]
(M = P du/dv + Q dF/dv, g'_eff the effective control rate of
:func:`~ncstab.paths.tangent_field.effective_rate`), the correction is
(dv, dlambda) = -A^T (A A^T)^-1 r: quadratic convergence from any nearby
state, as for a square Newton system.

The loop projects each step's end with its own per-case ``project`` (the model
parts of :mod:`ncstab.paths.compiled`); this batched one serves what runs once
per event, not per step: leaving a bifurcation point along a branch
(:mod:`ncstab.paths.branch_switching`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.paths.cofactor import minimum_norm_steps
from ncstab.paths.model import Evaluation
from ncstab.paths.options import PathOptions
from ncstab.paths.rhs import (
    StateLayout,
    evaluate_at,
    gather_evaluations,
    work_forces,
)
from ncstab.paths.tangent_field import StageArrays, control_matrix, effective_rate

__all__ = ["minimum_norm_correction", "project", "project_finite"]


def _correction_2(
    matrix_u: np.ndarray, matrix_f: np.ndarray, force_controlled: np.ndarray, dg: np.ndarray, residual: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Minimum-norm correction for n = 2 in closed form: z = (M M^T + g' g'^T)^-1 r,
    dv = -M^T z; returns (dv, z, singular), singular marking the rows whose
    finite normal matrix could not be inverted (for a least-squares fallback)."""
    fc0, fc1 = force_controlled[:, 0], force_controlled[:, 1]
    m00 = np.where(fc0, matrix_f[:, 0, 0], matrix_u[:, 0, 0])
    m01 = np.where(fc0, matrix_f[:, 0, 1], matrix_u[:, 0, 1])
    m10 = np.where(fc1, matrix_f[:, 1, 0], matrix_u[:, 1, 0])
    m11 = np.where(fc1, matrix_f[:, 1, 1], matrix_u[:, 1, 1])
    g0, g1 = dg[:, 0], dg[:, 1]
    a00 = (m00 * m00 + m01 * m01) + g0 * g0
    a01 = (m00 * m10 + m01 * m11) + g0 * g1
    a11 = (m10 * m10 + m11 * m11) + g1 * g1
    r0, r1 = residual[:, 0], residual[:, 1]
    with np.errstate(all="ignore"):
        det = a00 * a11 - a01 * a01
        z = np.empty(residual.shape)
        z[:, 0] = (a11 * r0 - a01 * r1) / det
        z[:, 1] = (a00 * r1 - a01 * r0) / det
    z0, z1 = z[:, 0], z[:, 1]
    dv = np.empty(residual.shape)
    dv[:, 0] = -(m00 * z0 + m10 * z1)
    dv[:, 1] = -(m01 * z0 + m11 * z1)
    singular = np.isfinite(a00) & np.isfinite(a01) & np.isfinite(a11) & ~np.isfinite(z).all(axis=-1)
    return dv, z, singular


def minimum_norm_correction(
    du_dv: np.ndarray, df_dv: np.ndarray, force_controlled: np.ndarray, dg: np.ndarray, residual: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """(dv, dlambda): the minimum-norm solution of [M | -g'] (dv, dlambda) = -r.

    For n = 2 in closed form, z = (M M^T + g g^T)^-1 r, dv = -M^T z, dlambda = g . z;
    for more dofs from one QR decomposition of [M | -g']^T, compiled
    (:func:`ncstab.paths.cofactor.minimum_norm_step`: no normal matrix, whose
    condition number is the square of A's).  Rows of a rank-deficient A by least
    squares on the normal matrix, case by case.
    """
    if dg.shape[-1] == 2:
        dv, z, singular = _correction_2(du_dv, df_dv, force_controlled, dg, residual)
        matrix = None
    else:
        matrix = control_matrix(du_dv, df_dv, force_controlled)
        dv, dlam, solved = minimum_norm_steps(matrix, dg, residual)
        singular = ~solved & np.isfinite(matrix).all(axis=(-2, -1)) & np.isfinite(dg).all(axis=-1)
        z = None
    if singular.any():  # rank-deficient: least squares per case
        rows = np.flatnonzero(singular)
        if matrix is None:
            matrix = control_matrix(du_dv, df_dv, force_controlled)
        sub = matrix[rows]
        normal_matrix = sub @ np.swapaxes(sub, -1, -2) + dg[rows, :, None] * dg[rows, None, :]
        with np.errstate(all="ignore"):
            least = np.stack([np.linalg.lstsq(a, r, rcond=None)[0] for a, r in zip(normal_matrix, residual[rows])])
        dv[rows] = -np.einsum("bji,bj->bi", sub, least)
        if z is None:
            dlam[rows] = np.sum(dg[rows] * least, axis=-1)
        else:
            z[rows] = least
    if z is not None:
        dlam = np.sum(dg * z, axis=-1)
    return dv, dlam


def project(
    batch: Any, stage: StageArrays, y: np.ndarray, layout: StateLayout, options: PathOptions
) -> tuple[np.ndarray, np.ndarray, Evaluation]:
    """Newton projection of (v, lambda) onto equilibrium + control constraints.

    Returns the projected states, a mask of the cases that converged to
    ``options.newton_tol`` (max norm of the residual) and ``batch.evaluate``
    at the projected states (the last residual check evaluates there:
    callers need not evaluate again).
    """
    y = y.copy()
    size_all = y.shape[0]
    converged = np.zeros(size_all, dtype=bool)
    todo = np.arange(size_all)
    pieces: list[tuple[np.ndarray, Evaluation]] = []
    sub, st = batch, stage
    for _ in range(options.newton_max_iter + 1):
        lam = y[todo, layout.lam]
        with np.errstate(all="ignore"):
            evaluation = evaluate_at(sub, st, y[todo], layout)
            residual = st.residual(evaluation.displacements, evaluation.forces, lam)
        size = np.max(np.abs(residual), axis=-1)
        ok = size <= options.newton_tol
        converged[todo[ok]] = True
        keep = ~ok & np.isfinite(size)
        if not keep.any():
            pieces.append((todo, evaluation))
            todo = todo[:0]
            break
        if not keep.all():
            pieces.append((todo[~keep], evaluation.take(~keep)))
        kept = np.flatnonzero(keep)
        todo, residual = todo[kept], residual[kept]
        st = st.take(kept)
        sub = sub.take(kept)
        _, dg = st.control_path(lam[kept])
        dF_dload = None if evaluation.dF_dload is None else evaluation.dF_dload[kept]
        dg = effective_rate(st, dg, dF_dload)
        du_dv, df_dv = evaluation.du_dv[kept], evaluation.dF_dv[kept]
        dv, dlam = minimum_norm_correction(du_dv, df_dv, st.force_controlled, dg, residual)
        y[todo, layout.v] += dv
        # Keep the work W consistent with the corrected path.
        if dv.shape[-1] == 2:
            du = np.empty(dv.shape)
            du[:, 0] = du_dv[:, 0, 0] * dv[:, 0] + du_dv[:, 0, 1] * dv[:, 1]
            du[:, 1] = du_dv[:, 1, 0] * dv[:, 0] + du_dv[:, 1, 1] * dv[:, 1]
        else:
            du = (du_dv @ dv[:, :, None])[:, :, 0]
        forces = work_forces(evaluation.take(kept), st, lam[kept]) if dF_dload is not None else evaluation.forces[kept]
        y[todo, layout.lam] += dlam
        y[todo, layout.work] += sub.work_factor * np.sum(forces * du, axis=-1)
    if todo.size:  # out of iterations: evaluate at the last corrected states
        with np.errstate(all="ignore"):
            pieces.append((todo, evaluate_at(sub, st, y[todo], layout)))
    return y, converged, gather_evaluations(pieces, size_all)


def project_finite(
    batch: Any, stage: StageArrays, y: np.ndarray, err: np.ndarray, layout: StateLayout, options: PathOptions
) -> tuple[np.ndarray, np.ndarray, Evaluation | None]:
    """Newton-project the finite states; err = inf where projection fails.

    Also returns the evaluation at the projected states when every state
    was projected (else ``None``).
    """
    y, err = y.copy(), err.copy()
    index = np.flatnonzero(np.isfinite(err))
    evaluation = None
    if index.size:
        if index.size == y.shape[0]:
            projected, converged, evaluation = project(batch, stage, y, layout, options)
        else:
            projected, converged, _ = project(batch.take(index), stage.take(index), y[index], layout, options)
        y[index] = projected
        err[index[~converged]] = np.inf
    return y, err, evaluation

