"""The cofactor vector and the minimum-norm correction of the constrained rate system, compiled, n dofs.

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
as accurate at a singular M as anywhere else, and an order of magnitude faster
for the six dofs of a ring than the singular value decomposition of adj(M) it
replaced.

The same decomposition gives the Newton projection's minimum-norm correction
(:func:`minimum_norm_step`): [M | -g'] x = -r with A = R^T Q^T is solved by
x = -Q [R1^-T r; 0], with no normal matrix A A^T (whose condition number is
the square of A's).  Each function is one case, compiled by numba
(:data:`ncstab.jit.njit`): the compiled stage loop calls them
(:mod:`ncstab.paths.loop_general`), and for scripts and tests they are compiled
in a generated module of the cache folder
(:func:`ncstab.generated_modules.compiled_module`); :func:`cofactor_vectors` and
:func:`minimum_norm_steps` run a batch, one case after the other (for tests and
scripts: the engine calls the per-case functions from its loop).
"""

from __future__ import annotations

import functools
import math
from typing import Any

import numpy as np

from ncstab.generated_modules import compiled_module
from ncstab.jit import njit

__all__ = ["cofactor_vector", "cofactor_vectors", "minimum_norm_step", "minimum_norm_steps", "work_size"]


def work_size(n):
    """The scratch :func:`cofactor_vector` and :func:`minimum_norm_step` need for n dofs."""
    return 2 * (n + 1) * n + 2 * (n + 1)


@njit
def _factor(matrix, rate, work):
    """Householder QR of A^T = [M | -rate]^T in ``work``: R above the diagonal of the
    first block (its diagonal apart, in ``diagonal``), the reflections' vectors in the
    second; returns (b, v, diagonal, vector, det Q)."""
    n = rate.shape[0]
    rows = n + 1
    b = work[: rows * n].reshape(rows, n)
    v = work[rows * n : 2 * rows * n].reshape(rows, n)
    diagonal = work[2 * rows * n : 2 * rows * n + n]
    vector = work[2 * rows * n + rows : 2 * rows * n + 2 * rows]
    for i in range(n):
        for j in range(n):
            b[j, i] = matrix[i, j]
        b[n, i] = -rate[i]
    sign = 1.0
    for k in range(n):
        norm = 0.0
        for i in range(k, rows):
            norm += b[i, k] * b[i, k]
        alpha = -math.copysign(math.sqrt(norm), b[k, k])
        for i in range(k, rows):
            v[i, k] = b[i, k]
        v[k, k] -= alpha
        size = 0.0
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
        else:  # NaN: so is every result
            for i in range(k, rows):
                v[i, k] = 0.0
            alpha = math.nan
        diagonal[k] = alpha
    return b, v, diagonal, vector, sign


@njit
def _apply_q(v, vector):
    """vector <- Q vector = H_0 H_1 ... H_{n-1} vector (the reflections in reverse order)."""
    rows, n = v.shape
    for k in range(n - 1, -1, -1):
        size = 0.0
        dot = 0.0
        for i in range(k, rows):
            size += v[i, k] * v[i, k]
            dot += v[i, k] * vector[i]
        if size > 0:
            factor = 2.0 * dot / size
            for i in range(k, rows):
                vector[i] -= factor * v[i, k]


@njit
def cofactor_vector(matrix, rate, out, work):
    """``out[:n] = adj(matrix) rate``, ``out[n] = det(matrix)`` (``work``: :func:`work_size`)."""
    n = rate.shape[0]
    _, v, diagonal, vector, sign = _factor(matrix, rate, work)
    product = 1.0
    for k in range(n):
        product *= diagonal[k]
    for i in range(n + 1):
        vector[i] = 0.0
    vector[n] = 1.0
    _apply_q(v, vector)
    scale = sign * product
    for i in range(n + 1):
        out[i] = scale * vector[i]


@njit
def minimum_norm_step(matrix, rate, residual, out, work):
    """The minimum-norm solution x = (dv, dlambda) of [M | -rate] x = -residual, into
    ``out``; False (out untouched) where R has a zero on its diagonal (A of lower rank:
    the caller's least squares)."""
    n = rate.shape[0]
    b, v, diagonal, vector, _ = _factor(matrix, rate, work)
    # A = R^T Q^T, so x = -Q [R1^-T residual; 0]: R1^T y = residual by forward substitution
    for i in range(n):
        if diagonal[i] == 0 or math.isnan(diagonal[i]):
            return False
        total = residual[i]
        for j in range(i):
            total -= b[j, i] * vector[j]
        vector[i] = total / diagonal[i]
    vector[n] = 0.0
    _apply_q(v, vector)
    for i in range(n + 1):
        out[i] = -vector[i]
    return True


def _cofactor_batch(matrices, rates, out):
    work = np.empty(work_size(rates.shape[1]))
    for b in range(rates.shape[0]):
        cofactor_vector(matrices[b], rates[b], out[b], work)


def _step_batch(matrices, rates, residuals, out, solved):
    work = np.empty(work_size(rates.shape[1]))
    for b in range(rates.shape[0]):
        solved[b] = minimum_norm_step(matrices[b], rates[b], residuals[b], out[b], work)


@functools.cache
def _compiled() -> Any:
    """This module's per-case functions compiled by numba (a generated module in the cache
    folder ``compiled``, :func:`ncstab.generated_modules.compiled_module`)."""
    return compiled_module(
        __name__, work_size, _factor, _apply_q, cofactor_vector, minimum_norm_step, _cofactor_batch, _step_batch
    )


def cofactor_vectors(matrices: np.ndarray, rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(adj(M) g' ``(B, n)``, det M ``(B,)``) of a batch: ``matrices`` ``(B, n, n)``,
    ``rates`` ``(B, n)``; one case after the other (a case's numbers do not depend on
    its batch)."""
    size, n = rates.shape
    out = np.empty((size, n + 1))
    if size:
        _compiled()._cofactor_batch(
            np.ascontiguousarray(matrices, dtype=float), np.ascontiguousarray(rates, dtype=float), out
        )
    return out[:, :n], out[:, n]


def minimum_norm_steps(
    matrices: np.ndarray, rates: np.ndarray, residuals: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(dv ``(B, n)``, dlambda ``(B,)``, solved ``(B,)``): the minimum-norm corrections of
    a batch (:func:`minimum_norm_step`), NaN where not solved."""
    size, n = rates.shape
    out = np.full((size, n + 1), np.nan)
    solved = np.zeros(size, dtype=np.bool_)
    if size:
        _compiled()._step_batch(np.ascontiguousarray(matrices, dtype=float), np.ascontiguousarray(rates, dtype=float),
                                np.ascontiguousarray(residuals, dtype=float), out, solved)
    return out[:, :n], out[:, n], solved
