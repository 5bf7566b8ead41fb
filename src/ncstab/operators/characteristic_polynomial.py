"""The characteristic polynomial det(M s^2 + C s + K) and its Hurwitz determinants.

Coefficients are stored highest degree first, like :func:`numpy.roots` and
:func:`numpy.polyval`: ``p[..., 0] s^N + p[..., 1] s^(N-1) + ... + p[..., N]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ncstab.operators.dynamic_matrices import as_dynamic_matrices
from ncstab.operators.onset_cases import characteristic_rows

__all__ = ["characteristic_polynomial", "hurwitz_determinants", "hurwitz_matrix"]


def characteristic_polynomial(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """Real coefficients of p(s) = det(M s^2 + C s + K), highest degree first.

    n = 1: ``[m, c, k]``.  n = 2: closed forms, each coefficient a sum of products of
    entries (listed in :func:`ncstab.operators.onset_cases.characteristic_coefficients`).
    n >= 3: interpolation of p at 2n + 1 points on a circle of radius the
    geometric mean of the root moduli, by a discrete Fourier transform (a
    unitary Vandermonde solve): each coefficient to a few eps of the largest
    term of p on the circle
    (:func:`ncstab.operators.onset_cases.interpolated_coefficients`).  Every
    case is computed alone, by the compiled per-case function the compiled
    stepper calls too (:func:`ncstab.operators.onset_cases.characteristic_coefficients`).

    Parameters
    ----------
    mass, damping, stiffness
        M, C, K of shape ``(..., n, n)``; ``damping=None`` means C = 0.

    Returns
    -------
    numpy.ndarray
        ``(..., 2n + 1)`` float.  Its leading coefficient is det M (0 for a
        singular M: the polynomial then has a lower degree).
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    if damping is None:
        damping = np.zeros_like(mass)
    return characteristic_rows(mass, damping, stiffness)


def hurwitz_matrix(coefficients: ArrayLike) -> np.ndarray:
    """The N x N Hurwitz matrix of a0 s^N + a1 s^(N-1) + ... + aN.

    H[i, j] = a_{2j - i + 1} (0-based i, j; a_k = 0 outside 0..N)::

        [[a1, a3, a5, ...],
         [a0, a2, a4, ...],
         [0,  a1, a3, ...],
         [0,  a0, a2, ...], ...]

    Parameters
    ----------
    coefficients
        ``(..., N + 1)``, highest degree first, N >= 1.

    Returns
    -------
    numpy.ndarray
        ``(..., N, N)``.
    """
    coefficients = np.asarray(coefficients, dtype=float)
    if coefficients.ndim < 1 or coefficients.shape[-1] < 2:
        raise ValueError(
            f"coefficients must have shape (..., N + 1) with N >= 1, got {coefficients.shape}"
        )
    degree = coefficients.shape[-1] - 1
    row, column = np.indices((degree, degree))
    index = 2 * column - row + 1
    inside = (index >= 0) & (index <= degree)
    return np.where(inside, coefficients[..., np.clip(index, 0, degree)], 0.0)


def hurwitz_determinants(coefficients: ArrayLike) -> np.ndarray:
    """Leading principal minors Delta_1..Delta_N of the Hurwitz matrix.

    Routh-Hurwitz: for a0 > 0, every root has Re s < 0 if and only if
    Delta_k > 0 for k = 1..N.  For a quartic:
    Delta_1 = a1, Delta_2 = a1 a2 - a0 a3, Delta_3 = a1 a2 a3 - a0 a3^2 - a1^2 a4,
    Delta_4 = a4 Delta_3.  Each minor is a determinant by LU (one batched call per
    order k <= N, not per case); it is a polynomial in the coefficients, smooth
    along a path.

    Parameters
    ----------
    coefficients
        ``(..., N + 1)``, highest degree first (as :func:`characteristic_polynomial`).

    Returns
    -------
    numpy.ndarray
        ``(..., N)``: Delta_1 .. Delta_N.
    """
    hurwitz = hurwitz_matrix(coefficients)
    finite = np.isfinite(hurwitz).all(axis=(-2, -1))
    hurwitz = np.where(finite[..., None, None], hurwitz, 0.0)  # NaN below, without LAPACK's warning
    degree = hurwitz.shape[-1]
    minors = np.stack([np.linalg.det(hurwitz[..., :k, :k]) for k in range(1, degree + 1)], axis=-1)
    return np.where(finite[..., None], minors, np.nan)
