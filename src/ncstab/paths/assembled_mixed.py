"""The sparse engine's bordered solves in mixed form, where an assembled K is below float64's resolution.

An assembled K adds up its members' stiffnesses, K = G + B^T D B (B the members' kinematic
Jacobians J stacked, D their dQ/dq, G the curvature terms Q H and the loads' own stiffness),
and its conditioning is that of B squared.  Hencky's column in lateral deflections w has
entries of order 6 and a lowest curvature of order (pi / n)^4: at n = 10,000 links the
rounding of the entries resolves the buckling mode to 0.2 % only, and past P1 the load on
the buckled branch is then fixed to about 1e-3 of P1 while the branch rises by P1 theta^2 / 8
(docs/models.md).  Solved in mixed form, with the members' kinematic increments z = B dx as
unknowns beside dx,

    [[G, B^T D], [B, -I]] [dx; z] = [r; 0],

the same equations are never summed into K, and the conditioning is that of B (n^2, not n^4).
Its factorization (SuperLU, COLAMD order) has the band of the members: a column of 10,001 links
factorizes in 0.02 s.  The border of the arclength equation is eliminated as in
:meth:`~ncstab.paths.assembled_engine.CaseRun.solve` (Keller's bordering algorithm).

The sparse engine takes this route for the rest of a stage once one of its steps failed at the
rounding floor (:func:`at_rounding_floor`): everywhere else its numbers are those of the
assembled K.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as splinalg

from ncstab.elements import shortening, tip_load_terms
from ncstab.operators.assembly import gap_springs, member_responses

__all__ = ["ROUNDING_FLOOR", "at_rounding_floor", "mixed_solver"]

#: A corrector's residual within this many roundings of the forces it balances is at
#: float64's floor (:func:`at_rounding_floor`).
ROUNDING_FLOOR = 8.0


def at_rounding_floor(G: np.ndarray, state, u: np.ndarray, load: float) -> bool:
    """Whether the residual ``G`` is within :data:`ROUNDING_FLOOR` roundings of the forces it
    balances at ``u`` under ``load``: machine epsilon times |K| |u| + |dR/dP| |P| (max
    norms).  There Newton's steps with the assembled K are driven by rounding (a column of
    10,001 links past P1: |G| 2.4e-20 against a floor of 3.3e-20, docs/models.md), and the
    sparse engine goes on in mixed form (module docstring)."""
    scale = abs(state.K).max() * np.max(np.abs(u), initial=0.0)
    scale += np.max(np.abs(state.dR_dload), initial=0.0) * abs(load)
    return bool(np.max(np.abs(G), initial=0.0) <= ROUNDING_FLOOR * np.finfo(float).eps * scale)


class _Triplets:
    """Entries (row, column, value) of a sparse matrix, gathered before it is built."""

    def __init__(self) -> None:
        self.rows: list[np.ndarray] = []
        self.columns: list[np.ndarray] = []
        self.values: list[np.ndarray] = []

    def add(self, rows, columns, values) -> None:
        rows, columns, values = np.broadcast_arrays(rows, columns, values)
        self.rows.append(rows.ravel()), self.columns.append(columns.ravel()), self.values.append(values.ravel())

    def matrix(self, size: int) -> sparse.csc_matrix:
        data = (np.concatenate(self.values), (np.concatenate(self.rows), np.concatenate(self.columns)))
        return sparse.coo_matrix(data, shape=(size, size)).tocsc()


def mixed_solver(run, control, point, column: np.ndarray, last: np.ndarray) -> Callable[[np.ndarray], np.ndarray]:
    """A solver of the bordered system [[K_SS, column], [last]] x = right at ``point``, in mixed
    form (module docstring).

    Parameters
    ----------
    run
        The case (:class:`~ncstab.paths.assembled_engine.CaseRun`).
    control
        The stage's control (:class:`~ncstab.paths.assembled_control.StageControl`): its force
        dofs S are unknowns; its driven dofs D move by u_slope dlambda, so their part of
        ``column``, K_SD u_slope, is taken from the members instead (B_D u_slope in the rows of z).
    point
        The state (:class:`~ncstab.paths.assembled_engine.Point`): u, load, internal forces.
    column, last
        dG/d(lambda / scale) and the border row, as for ``CaseRun.bordered``.
    """
    n, system = run.n, run.system
    entries = _Triplets()
    size = n  # rows and columns: the n dofs, then the members' z
    for dofs, J, H, Q, D, w in member_responses(system, run.law, run.parameters, point.u, point.internal):
        m, k, _ = J.shape
        wD, curvature = w[:, None, None] * D, w[:, None, None] * np.einsum("mk,mkab->mab", Q, H)
        z = size + np.arange(m * k).reshape(m, k)
        size += m * k
        entries.add(dofs[:, :, None], dofs[:, None, :], curvature)  # G
        entries.add(dofs[:, :, None], z[:, None, :], np.einsum("mkl,mkp->mlp", J, wD))  # B^T D
        entries.add(z[:, :, None], dofs[:, None, :], J)  # B
        entries.add(z, z, -1.0)
    if system.axial_load is not None:  # bars: B a rise each, D = -P L cos^-3
        bars = system.axial_load
        _, _, _, r = shortening(bars.rise_dofs, bars.rise_signs, point.u, bars.lengths)
        length = 1.0 if bars.lengths is None else np.asarray(bars.lengths, dtype=float)
        z = size + np.arange(len(r))
        size += len(r)
        entries.add(bars.rise_dofs, z[:, None], bars.rise_signs * (-point.load * length * (1.0 - r * r) ** -1.5)[:, None])
        entries.add(z[:, None], bars.rise_dofs, bars.rise_signs)
        entries.add(z, z, -1.0)
    if system.tip_load is not None:  # its own stiffness, -P dQ_ext/du, in G
        _, pairs, blocks = tip_load_terms(system.tip_load, point.u)
        entries.add(pairs[:, :, None], pairs[:, None, :], -point.load * blocks)
    if len(run.closed):  # closed secondary contacts' springs, in G (as in the assembled K)
        dofs, _, _, blocks = gap_springs(system, run.closed, point.u, run.kappa)
        entries.add(dofs[:, :, None], dofs[:, None, :], blocks)
    whole = entries.matrix(size)
    S, D = control.force_dofs, control.displacement_dofs
    m = len(S)
    kept = np.concatenate([S, np.arange(n, size)])
    matrix = whole[kept][:, kept]
    along_column = np.zeros(len(kept))  # dG/d(lambda / scale) with the members' z in their rows
    along_column[:m] = column
    if len(D):
        slope = control.u_slope * control.scale
        along_column[:m] -= point.state.K[S][:, D] @ slope  # K_SD's part, summed: taken from the members
        along_column += whole[kept][:, D] @ slope  # G_SD and B_D
    lu = splinalg.splu(matrix.tocsc())
    along = lu.solve(along_column)[:m]

    def solve(right: np.ndarray) -> np.ndarray:
        extended = np.zeros(len(kept))
        extended[:m] = right[:m]
        x = lu.solve(extended)[:m]
        step = (right[m] - last[:m] @ x) / (last[m] - last[:m] @ along)
        return np.append(x - step * along, step)

    return solve
