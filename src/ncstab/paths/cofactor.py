"""The cofactor vector of the constrained rate system, compiled: (adj(M) g', det M) for n dofs.

Along a stage the path's tangent spans the null space of the n x (n + 1)
matrix A = [M | -g'] (``docs/paths.md``, "One formulation for every law"),
and the cofactor vector

    c = (adj(M) g', det M),       A c = det(M) g' - det(M) g' = 0,

spans it wherever it is one-dimensional, smoothly through turning points
(det M = 0) and vanishing only where the null space is larger.  c is the
generalized cross product of A's rows: det([A; x^T]) = c . x for every x.
With the Householder QR decomposition A^T = Q R (Q orthogonal (n+1) x (n+1),
R upper triangular), [A; x^T] = [[R1^T, 0], [x^T Q]] Q^T with R1 the n x n
top of R, so

    c = det(Q) prod_i R_ii  Q e_{n+1}

(Allgower & Georg, *Numerical Continuation Methods*, Sect. 2.3 and 4.1: the
tangent from a QR decomposition, oriented by the sign of det [A; t^T]).
det(Q) is (-1) to the number of reflections applied.  No division by a pivot:
as accurate at a singular M as anywhere else (where ``tangent_field.adjugate``
took a singular value decomposition, an order of magnitude slower for the
six dofs of a ring).  :func:`cofactor_vector` is one case (compiled, for
compiled loops); :func:`cofactor_vectors` a batch, one case after the other.
"""

from __future__ import annotations

import math

import numba
import numpy as np

__all__ = ["cofactor_vector", "cofactor_vectors"]


@numba.njit(cache=True, error_model="numpy")
def cofactor_vector(matrix, rate, out, work):
    """``out[:n] = adj(matrix) rate``, ``out[n] = det(matrix)``; ``work`` is scratch of
    at least ``2 (n + 1) n + (n + 1)`` numbers."""
    n = rate.shape[0]
    rows = n + 1
    b = work[: rows * n].reshape(rows, n)  # A^T, reduced in place to R
    v = work[rows * n : 2 * rows * n].reshape(rows, n)  # the Householder vectors, column k from row k
    q = work[2 * rows * n : 2 * rows * n + rows]
    for i in range(n):
        for j in range(n):
            b[j, i] = matrix[i, j]
        b[n, i] = -rate[i]
    product, sign = 1.0, 1.0
    for k in range(n):
        norm = 0.0
        for i in range(k, rows):
            norm += b[i, k] * b[i, k]
        norm = math.sqrt(norm)
        alpha = -math.copysign(norm, b[k, k])
        size = 0.0
        for i in range(k, rows):
            v[i, k] = b[i, k]
        v[k, k] -= alpha
        for i in range(k, rows):
            size += v[i, k] * v[i, k]
        if size > 0:  # reflect (I - 2 v v^T / v^T v) the columns k.. of b
            sign = -sign
            for j in range(k, n):
                dot = 0.0
                for i in range(k, rows):
                    dot += v[i, k] * b[i, j]
                factor = 2.0 * dot / size
                for i in range(k, rows):
                    b[i, j] -= factor * v[i, k]
        elif size == 0:  # the column is zero from row k: nothing to reflect, R_kk = 0
            alpha = 0.0
        else:  # NaN: so is c
            for i in range(k, rows):
                v[i, k] = 0.0
            alpha = math.nan
        product *= alpha
    # Q e_{n+1} = H_0 H_1 ... H_{n-1} e_{n+1}: the reflections in reverse order
    for i in range(rows):
        q[i] = 0.0
    q[n] = 1.0
    for k in range(n - 1, -1, -1):
        size = 0.0
        dot = 0.0
        for i in range(k, rows):
            size += v[i, k] * v[i, k]
            dot += v[i, k] * q[i]
        if size > 0:
            factor = 2.0 * dot / size
            for i in range(k, rows):
                q[i] -= factor * v[i, k]
    scale = sign * product
    for i in range(rows):
        out[i] = scale * q[i]


@numba.njit(cache=True, error_model="numpy")
def _batch(matrices, rates, out):
    n = rates.shape[1]
    work = np.empty(2 * (n + 1) * n + n + 1)
    for b in range(rates.shape[0]):
        cofactor_vector(matrices[b], rates[b], out[b], work)


def cofactor_vectors(matrices: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(adj(M) g' ``(B, n)``, det M ``(B,)``) of a batch: ``matrices`` ``(B, n, n)``,
    ``rates`` ``(B, n)``; one case after the other (a case's numbers do not depend on
    its batch)."""
    size, n = rates.shape
    out = np.empty((size, n + 1))
    if size:
        _batch(np.ascontiguousarray(matrices, dtype=float), np.ascontiguousarray(rates, dtype=float), out)
    return out[:, :n], out[:, n]
