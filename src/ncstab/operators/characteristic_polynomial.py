"""The characteristic polynomial det(M s^2 + C s + K) and its Hurwitz determinants.

Coefficients are stored highest degree first, like :func:`numpy.roots` and
:func:`numpy.polyval`: ``p[..., 0] s^N + p[..., 1] s^(N-1) + ... + p[..., N]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ncstab.operators.dynamic_matrices import as_dynamic_matrices

__all__ = ["characteristic_polynomial", "hurwitz_determinants", "hurwitz_matrix"]


def characteristic_polynomial(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """Real coefficients of p(s) = det(M s^2 + C s + K), highest degree first.

    n = 1: ``[m, c, k]``.  n = 2, in closed form (each coefficient a sum of
    products of entries, exact up to rounding)::

        s^4: det M
        s^3: M11 C22 + C11 M22 - M12 C21 - C12 M21
        s^2: M11 K22 + C11 C22 + K11 M22 - M12 K21 - C12 C21 - K12 M21
        s^1: C11 K22 + K11 C22 - C12 K21 - K12 C21
        s^0: det K

    n >= 3: interpolation of p at the N = 2n + 1 points z_k = r w^k on a circle,
    w = exp(2 pi i / N).  Then p(z_k) = sum_j (a_j r^j) w^(jk), so the scaled
    coefficients a_j r^j are the discrete Fourier transform of the values
    divided by N: a Vandermonde solve whose matrix V / sqrt(N) is unitary
    (condition number 1), unlike the Vandermonde matrix of real points, whose
    condition number grows exponentially with N.  The radius is the geometric
    mean of the root moduli, r = |det K / det M|^(1/2n) (|prod s_i| =
    |a_N / a_0|), so that the extreme terms a_0 r^N and a_N are equal on the
    circle; where det M or det K is 0 it is the root bound of the case n = 1,
    ||M|| r^2 = ||C|| r + ||K|| (Frobenius norms).  The determinants at the
    points are backward stable (LU), so each a_j carries an absolute error of
    about N eps max|p(z)| / r^j: a few eps relative to the largest term of p on
    the circle, and so scale invariant (s -> gamma s, C -> gamma C,
    K -> gamma^2 K scales r by gamma).

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
    n = mass.shape[-1]
    if n == 1:
        return np.stack([mass[..., 0, 0], damping[..., 0, 0], stiffness[..., 0, 0]], axis=-1)
    if n == 2:
        return _quartic_coefficients(mass, damping, stiffness)
    return _polynomial_by_interpolation(mass, damping, stiffness)


def _cross(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a11 b22 + b11 a22 - a12 b21 - b12 a21 (the mixed term of det(a + b) for 2x2)."""
    return (
        a[..., 0, 0] * b[..., 1, 1]
        + b[..., 0, 0] * a[..., 1, 1]
        - a[..., 0, 1] * b[..., 1, 0]
        - b[..., 0, 1] * a[..., 1, 0]
    )


def _quartic_coefficients(
    mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray
) -> np.ndarray:
    """``(..., 5)``: the closed form of :func:`characteristic_polynomial` for n = 2."""

    def det2(a: np.ndarray) -> np.ndarray:
        return a[..., 0, 0] * a[..., 1, 1] - a[..., 0, 1] * a[..., 1, 0]

    return np.stack(
        [
            det2(mass),
            _cross(mass, damping),
            _cross(mass, stiffness) + det2(damping),
            _cross(damping, stiffness),
            det2(stiffness),
        ],
        axis=-1,
    )


def _polynomial_by_interpolation(
    mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray
) -> np.ndarray:
    """``(..., 2n + 1)``: det(M s^2 + C s + K) from its values at 2n + 1 points on a circle.

    Valid for every n (used for n >= 3; the tests compare it with the closed
    forms for n = 1, 2).
    """
    n = mass.shape[-1]
    points = 2 * n + 1
    # At least one batch axis: numpy evaluates power on a 0-d array by the C library
    # and on arrays by its SIMD code where the CPU has AVX-512, so one case alone would
    # differ from the same case in a batch by a rounding (tests/test_dynamics.py).
    batch_shape = np.broadcast_shapes(mass.shape[:-2], damping.shape[:-2], stiffness.shape[:-2])
    mass, damping, stiffness = (np.broadcast_to(a, batch_shape + (n, n)).reshape((-1, n, n)) for a in (mass, damping, stiffness))
    finite = (
        np.isfinite(mass).all((-2, -1))
        & np.isfinite(damping).all((-2, -1))
        & np.isfinite(stiffness).all((-2, -1))
    )
    if not finite.all():  # NaN for those cases, without LAPACK's warnings
        mass, damping, stiffness = (
            np.where(finite[..., None, None], a, 0.0) for a in (mass, damping, stiffness)
        )
    norm_m = np.linalg.norm(mass, axis=(-2, -1))
    norm_c = np.linalg.norm(damping, axis=(-2, -1))
    norm_k = np.linalg.norm(stiffness, axis=(-2, -1))
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        geometric_mean = np.abs(np.linalg.det(stiffness) / np.linalg.det(mass)) ** (1.0 / (2 * n))
        root_bound = (norm_c + np.sqrt(norm_c**2 + 4.0 * norm_m * norm_k)) / (2.0 * norm_m)
    radius = np.where(
        np.isfinite(geometric_mean) & (geometric_mean > 0), geometric_mean, root_bound
    )
    radius = np.where(np.isfinite(radius) & (radius > 0), radius, 1.0)
    z = radius[..., None] * np.exp(2j * np.pi * np.arange(points) / points)  # (..., N)
    z = z[..., None, None]
    pencil = (
        mass[..., None, :, :] * z**2 + damping[..., None, :, :] * z + stiffness[..., None, :, :]
    )
    values = np.linalg.det(pencil)  # (..., N)
    scaled = np.fft.fft(values, axis=-1) / points  # a_j r^j, lowest degree first
    coefficients = scaled.real / radius[..., None] ** np.arange(points)
    return np.where(finite[..., None], coefficients[..., ::-1], np.nan).reshape(batch_shape + (points,))


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
