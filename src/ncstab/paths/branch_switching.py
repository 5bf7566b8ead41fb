"""Branch switching at a simple bifurcation point.

At a simple bifurcation point x* = (v*, lambda*) of the constraint
G(x) = P u(v) + Q F(v, P(lambda)) - g(lambda) = 0 (the stage's equilibrium
under its control), the Jacobian A = [M | -g'_eff] (n x (n + 1)) has rank
n - 1: its null space is spanned by the tangent t0 of the branch followed
and one more vector t1, and psi^T A = 0 for one left null vector psi.  The
branches through x* leave along the directions a t0 + b t1 that solve the
algebraic bifurcation equation (Lyapunov--Schmidt reduction to second order;
Keller 1977, Seydel "Practical Bifurcation and Stability Analysis" 5.5,
BifurcationKit's branch switching):

    c00 a^2 + 2 c01 a b + c11 b^2 = 0,   c_ij = psi^T D2G(x*)[t_i, t_j].

(1, 0) is one root (the branch followed, c00 = 0 up to the location's
accuracy); the other is the bifurcating branch's direction.  The second
derivatives D2G[t_i, t_j] are the derivatives of A along t_j applied to t_i,
taken by central differences of the engine's own tangent (step 1e-5: the
coefficients to about 1e-10, far more than the choice of a direction needs;
the branch itself is then followed to the integrator's accuracy).  The path
leaves x* by a short step along the chosen direction and is projected back
onto equilibrium (laws with a total form) by the loop's Newton projection
before the loop goes on.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.paths.rhs import StateLayout, evaluate_at, work_forces
from ncstab.paths.tangent_field import StageArrays, control_matrix, effective_rate

__all__ = [
    "DERIVATIVE_STEP", "LEAVING_STEP", "bifurcating_direction", "bifurcation_coefficients", "branch_direction",
    "branch_motion", "leave_along_branch",
]

#: Step of the central differences for the second derivatives of G.
DERIVATIVE_STEP = 1e-5
#: Length of the step that leaves the bifurcation point along the new branch.
LEAVING_STEP = 1e-4


def _jacobian(batch: Any, stage: StageArrays, y: np.ndarray, layout: StateLayout) -> np.ndarray:
    """A = [M | -g'_eff] at states ``y``: ``(B, n, n + 1)`` in (v, lambda)."""
    evaluation = evaluate_at(batch, stage, y, layout)
    matrix = control_matrix(evaluation.du_dv, evaluation.dF_dv, stage.force_controlled)
    _, dg = stage.control_path(y[:, layout.lam])
    dg = effective_rate(stage, dg, evaluation.dF_dload)
    return np.concatenate([matrix, -dg[:, :, None]], axis=-1)


def _shifted(y: np.ndarray, direction: np.ndarray, step: float, layout: StateLayout) -> np.ndarray:
    out = y.copy()
    out[:, layout.v] += step * direction[:, :-1]
    out[:, layout.lam] += step * direction[:, -1]
    return out


def bifurcating_direction(
    batch: Any, stage: StageArrays, y: np.ndarray, incoming: np.ndarray, layout: StateLayout
) -> np.ndarray:
    """The direction ``(B, n + 1)`` in (v, lambda) of the branch that crosses the one
    followed (whose tangent is ``incoming``) at the bifurcation points ``y``.

    Unit vectors, signed so that their component along the second null vector
    t1 is positive (t1 itself signed by its largest entry): a deterministic
    choice, which ``direction = -1`` reverses.
    """
    A = _jacobian(batch, stage, y, layout)
    u_left, _, vt = np.linalg.svd(A)
    psi = u_left[:, :, -1]  # (B, n): left null vector
    null = np.swapaxes(vt[:, -2:, :], -1, -2)  # (B, n + 1, 2): right null space
    t0 = np.einsum("bkj,bj->bk", null, np.einsum("bkj,bk->bj", null, incoming))
    t0 /= np.linalg.norm(t0, axis=-1, keepdims=True)
    t1 = null[:, :, 0] - np.sum(null[:, :, 0] * t0, -1, keepdims=True) * t0
    other = null[:, :, 1] - np.sum(null[:, :, 1] * t0, -1, keepdims=True) * t0
    t1 = np.where(np.linalg.norm(t1, axis=-1, keepdims=True) >= np.linalg.norm(other, axis=-1, keepdims=True), t1, other)
    t1 /= np.linalg.norm(t1, axis=-1, keepdims=True)
    rows = np.arange(y.shape[0])
    t1 *= np.sign(t1[rows, np.argmax(np.abs(t1), axis=-1)])[:, None]

    def second(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """psi^T D2G[a, b] by central differences of A along b."""
        h = DERIVATIVE_STEP
        plus = _jacobian(batch, stage, _shifted(y, b, h, layout), layout)
        minus = _jacobian(batch, stage, _shifted(y, b, -h, layout), layout)
        return np.einsum("bi,bij,bj->b", psi, (plus - minus) / (2 * h), a)

    return branch_direction(*bifurcation_coefficients(second, t0, t1), t0, t1)


def bifurcation_coefficients(second, t0: np.ndarray, t1: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(c00, c01, c11) of the algebraic bifurcation equation, c_ij = psi^T D2G[t_i, t_j], from
    ``second(a, b)`` = psi^T D2G[a, b] ``(B,)`` (the mixed one symmetrized: a central
    difference of A along b applied to a is symmetric only up to its error).  Both engines'
    (this module's and :mod:`ncstab.paths.assembled_path`'s, each with its own Jacobian)."""
    return second(t0, t0), 0.5 * (second(t0, t1) + second(t1, t0)), second(t1, t1)


def branch_direction(c00: np.ndarray, c01: np.ndarray, c11: np.ndarray, t0: np.ndarray,
                     t1: np.ndarray) -> np.ndarray:
    """The bifurcating branch's unit direction ``(B, n + 1)`` a t0 + b t1 from the algebraic
    bifurcation equation c00 a^2 + 2 c01 a b + c11 b^2 = 0 (Keller 1977; Seydel 5.5).

    Of its two roots, one is the branch followed (t0: c00 = 0 up to the location's
    accuracy); the other, the root less aligned with t0, is returned, signed so that
    b >= 0 (t1 along itself where every coefficient is about 0).  Both engines call it.
    """
    rows = np.arange(t0.shape[0])
    # The two roots (a, b) of c00 a^2 + 2 c01 a b + c11 b^2 = 0, each written two ways
    # (one of which may vanish); the bifurcating branch is the root less aligned with
    # t0 (the other is the branch followed: c00 = 0 up to the location's accuracy).
    root = np.sqrt(np.maximum(c01 * c01 - c00 * c11, 0.0))
    candidates = np.stack(
        [
            np.stack([c11, -c01 - root], -1),
            np.stack([c11, -c01 + root], -1),
            np.stack([-c01 - root, c00], -1),
            np.stack([-c01 + root, c00], -1),
        ],
        axis=1,
    )  # (B, 4, 2): (a, b)
    norms = np.linalg.norm(candidates, axis=-1)
    scale = np.maximum(np.abs(c00) + np.abs(c01) + np.abs(c11), 1e-300)
    usable = norms > 1e-9 * scale[:, None]
    candidates = candidates / np.where(usable, norms, 1.0)[..., None]
    alignment = np.where(usable, np.abs(candidates[:, :, 0]), np.inf)
    pick = np.argmin(alignment, axis=1)
    degenerate = ~usable.any(axis=1)  # every coefficient ~0: take t1
    a, b = candidates[rows, pick, 0], candidates[rows, pick, 1]
    a, b = np.where(degenerate, 0.0, a), np.where(degenerate, 1.0, b)
    sign = np.where(b < 0, -1.0, 1.0)
    direction = (a * sign)[:, None] * t0 + (b * sign)[:, None] * t1
    return direction / np.linalg.norm(direction, axis=-1, keepdims=True)


def _shift_work(batch: Any, stage: StageArrays, y: np.ndarray, moved: np.ndarray, layout: StateLayout) -> np.ndarray:
    """The work of the internal forces over the move from ``y`` to ``moved`` (the
    trapezoidal rule on their power, rhs.work_forces: an error O(LEAVING_STEP^3), 1e-12;
    without it the work would miss the strain energy of the move, ~ |K| LEAVING_STEP^2)."""
    before, after = evaluate_at(batch, stage, y, layout), evaluate_at(batch, stage, moved, layout)
    forces = work_forces(before, stage, y[:, layout.lam]) + work_forces(after, stage, moved[:, layout.lam])
    du = after.displacements - before.displacements
    return batch.work_factor * 0.5 * np.sum(forces * du, axis=-1)


def leave_along_branch(
    batch: Any, stage: StageArrays, y: np.ndarray, incoming: np.ndarray, layout: StateLayout
) -> tuple[np.ndarray, np.ndarray]:
    """Cases at simple bifurcation points ``y`` (reached along ``incoming``) whose stage
    switches branch leave along the bifurcating branch, the way ``stage.switch`` (+-1)
    says.

    Returns the new states (a step of :data:`LEAVING_STEP` along the branch, its work
    added; for a law with a total form the caller projects them back onto equilibrium,
    :meth:`ncstab.paths.compiled_stages.CompiledStages.settle`) and the direction taken
    ``(B, n + 1)`` in (v, lambda).
    """
    direction = stage.switch.astype(float)[:, None] * bifurcating_direction(batch, stage, y, incoming, layout)
    moved = _shifted(y, direction, LEAVING_STEP, layout)
    moved[:, layout.work] += _shift_work(batch, stage, y, moved, layout)
    return moved, direction


def branch_motion(
    batch: Any, stage: StageArrays, y: np.ndarray, direction: np.ndarray, layout: StateLayout
) -> np.ndarray:
    """The motion (du, dF, dlambda) ``(B, 2n + 1)`` along ``direction`` (in (v, lambda)) at
    the states ``y`` the cases left to: the reference the next tangents continue (so that
    the path goes on along the new branch, not back)."""
    evaluation = evaluate_at(batch, stage, y, layout)
    dv, dlam = direction[:, :-1], direction[:, -1]
    du = np.einsum("bij,bj->bi", evaluation.du_dv, dv)
    dF = np.einsum("bij,bj->bi", evaluation.dF_dv, dv)
    if evaluation.dF_dload is not None:
        dF = dF + evaluation.dF_dload * (stage.load_slope * dlam)[:, None]
    return np.concatenate([du, dF, dlam[:, None]], axis=-1)
