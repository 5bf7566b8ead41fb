"""The flutter-onset tests and the characteristic polynomial det(M s^2 + C s + K), one case at a time.

One implementation for every caller: each function below is one case, compiled
by numba (:data:`ncstab.jit.njit`).  The compiled stage loop of general models
calls them (:mod:`ncstab.paths.loop_general_output`); for the others they are
compiled in a generated module of the cache folder
(:func:`ncstab.generated_modules.compiled_module`):
the batch functions (:func:`eigenvalue_discriminants`, :func:`frequency_discriminants`,
:func:`characteristic_rows`, :func:`damped_onsets`) run one case after the other
(so a case's numbers do not depend on its batch) for
:func:`ncstab.operators.flutter_discriminant` (n > 2),
:func:`ncstab.operators.frequency_discriminant` (n > 2),
:func:`ncstab.operators.characteristic_polynomial` and
:func:`ncstab.operators.flutter_onset_indicator`.

Coefficients are stored highest degree first, like :func:`numpy.roots`:
``p[0] s^N + p[1] s^(N-1) + ... + p[N]``, N = 2n.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np

from ncstab.generated_modules import compiled_module
from ncstab.jit import njit
from ncstab.operators.one_state import discriminant_2, eigenvalue_discriminant

__all__ = [
    "characteristic_coefficients", "characteristic_rows", "damped_onset", "damped_onsets", "eigenvalue_discriminant",
    "eigenvalue_discriminants", "frequency_discriminant", "frequency_discriminants", "interpolated_coefficients",
    "interpolated_rows", "regular_determinant",
]


@njit
def regular_determinant(mass):
    """det M where M is regular, else NaN (:func:`ncstab.operators.dynamic_matrices.regular_mass`:
    |det M| > n eps prod_j |M_j|, the Euclidean norms of the columns; det M in closed form
    for n <= 2, by LU beyond).  M must be finite."""
    n = mass.shape[0]
    if n == 1:
        determinant = mass[0, 0]
    elif n == 2:
        determinant = mass[0, 0] * mass[1, 1] - mass[0, 1] * mass[1, 0]
    else:
        determinant = np.linalg.det(mass)
    norms = 1.0
    for j in range(n):
        column = 0.0
        for i in range(n):
            column += mass[i, j] * mass[i, j]
        norms *= np.sqrt(column)
    return determinant if abs(determinant) > n * np.finfo(np.float64).eps * norms else np.nan


@njit
def frequency_discriminant(mass, stiffness):
    """The discriminant of q(mu) = det(M mu + K), mu = s^2
    (:func:`ncstab.operators.frequency_discriminant`, whose vectorized closed forms for
    n <= 2 are the expressions here): 1 for n = 1, b^2 - 4 det M det K for n = 2 (b the
    mixed term), and for n >= 3 det(M)^(2n - 2) times :func:`eigenvalue_discriminant` of
    M^-1 K (K itself where M is the identity, exactly).  NaN where M is not regular
    (:func:`ncstab.operators.dynamic_matrices.regular_mass`: |det M| > n eps prod_j |M_j|)
    or an entry is not finite."""
    n = mass.shape[0]
    identity = True
    for i in range(n):
        for j in range(n):
            if not (np.isfinite(mass[i, j]) and np.isfinite(stiffness[i, j])):
                return np.nan
            identity = identity and mass[i, j] == (1.0 if i == j else 0.0)
    determinant = regular_determinant(mass)
    if np.isnan(determinant):
        return np.nan
    if n == 1:
        return 1.0
    if n == 2:
        b = mass[0, 0] * stiffness[1, 1] + stiffness[0, 0] * mass[1, 1] - mass[0, 1] * stiffness[1, 0] - stiffness[0, 1] * mass[1, 0]
        return b * b - 4.0 * determinant * (stiffness[0, 0] * stiffness[1, 1] - stiffness[0, 1] * stiffness[1, 0])
    if identity:
        return eigenvalue_discriminant(stiffness)
    return determinant ** (2 * n - 2) * eigenvalue_discriminant(np.linalg.solve(mass, stiffness))


@njit
def characteristic_coefficients(mass, damping, stiffness, out):
    """The 2n + 1 real coefficients of p(s) = det(M s^2 + C s + K), highest degree first, in ``out``.

    n = 1: ``[m, c, k]``.  n = 2, in closed form (each coefficient a sum of
    products of entries, exact up to rounding)::

        s^4: det M
        s^3: M11 C22 + C11 M22 - M12 C21 - C12 M21
        s^2: M11 K22 + C11 C22 + K11 M22 - M12 K21 - C12 C21 - K12 M21
        s^1: C11 K22 + K11 C22 - C12 K21 - K12 C21
        s^0: det K

    n >= 3: :func:`interpolated_coefficients`.
    """
    n = mass.shape[0]
    if n == 1:
        out[0], out[1], out[2] = mass[0, 0], damping[0, 0], stiffness[0, 0]
        return
    if n == 2:
        out[0] = mass[0, 0] * mass[1, 1] - mass[0, 1] * mass[1, 0]
        out[1] = mass[0, 0] * damping[1, 1] + damping[0, 0] * mass[1, 1] - mass[0, 1] * damping[1, 0] - damping[0, 1] * mass[1, 0]
        out[2] = (
            mass[0, 0] * stiffness[1, 1] + stiffness[0, 0] * mass[1, 1] - mass[0, 1] * stiffness[1, 0]
            - stiffness[0, 1] * mass[1, 0] + damping[0, 0] * damping[1, 1] - damping[0, 1] * damping[1, 0]
        )
        out[3] = (
            damping[0, 0] * stiffness[1, 1] + stiffness[0, 0] * damping[1, 1] - damping[0, 1] * stiffness[1, 0]
            - stiffness[0, 1] * damping[1, 0]
        )
        out[4] = stiffness[0, 0] * stiffness[1, 1] - stiffness[0, 1] * stiffness[1, 0]
        return
    interpolated_coefficients(mass, damping, stiffness, out)


@njit
def interpolated_coefficients(mass, damping, stiffness, out):
    """The coefficients of :func:`characteristic_coefficients` (2n + 1, highest degree
    first, in ``out``) from the values of p on a circle, for every n (used for n >= 3;
    the tests compare it with the closed forms for n = 1, 2).

    Interpolation of p at the N = 2n + 1 points z_k = r w^k on a circle,
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
    K -> gamma^2 K scales r by gamma).  NaN where an entry is not finite.
    """
    n = mass.shape[0]
    points = 2 * n + 1
    norm_m, norm_c, norm_k = 0.0, 0.0, 0.0
    for i in range(n):
        for j in range(n):
            norm_m += mass[i, j] * mass[i, j]
            norm_c += damping[i, j] * damping[i, j]
            norm_k += stiffness[i, j] * stiffness[i, j]
    if not (np.isfinite(norm_m) and np.isfinite(norm_c) and np.isfinite(norm_k)):
        for j in range(points):
            out[j] = np.nan
        return
    norm_m, norm_c, norm_k = np.sqrt(norm_m), np.sqrt(norm_c), np.sqrt(norm_k)
    geometric_mean = abs(np.linalg.det(stiffness) / np.linalg.det(mass)) ** (1.0 / (2 * n))
    root_bound = (norm_c + np.sqrt(norm_c * norm_c + 4.0 * norm_m * norm_k)) / (2.0 * norm_m)
    radius = geometric_mean if np.isfinite(geometric_mean) and geometric_mean > 0 else root_bound
    if not (np.isfinite(radius) and radius > 0):
        radius = 1.0
    pencil = np.empty((n, n), dtype=np.complex128)
    values = np.empty(points, dtype=np.complex128)
    for k in range(points):
        angle = 2.0 * np.pi * k / points
        z = complex(radius * np.cos(angle), radius * np.sin(angle))
        for i in range(n):
            for j in range(n):
                pencil[i, j] = (mass[i, j] * z + damping[i, j]) * z + stiffness[i, j]
        values[k] = np.linalg.det(pencil)
    for j in range(points):  # a_j r^j = (1/N) sum_k p(z_k) w^(-jk), lowest degree first
        total = 0.0
        for k in range(points):
            angle = -2.0 * np.pi * ((j * k) % points) / points
            total += values[k].real * np.cos(angle) - values[k].imag * np.sin(angle)
        out[points - 1 - j] = total / points / radius**j


@njit
def damped_onset(mass, damping, stiffness, coefficients, hurwitz):
    """The flutter-onset test of a damped M s^2 + C s + K: the Hurwitz determinant
    Delta_{2n-1} of its characteristic polynomial made monic (``coefficients`` (2n + 1)
    and ``hurwitz`` (2n - 1, 2n - 1) are scratch).

    By Orlando's formula Delta_{N-1} = (-1)^(N(N-1)/2) a0^(N-1) prod_{i<j} (s_i + s_j),
    so it vanishes where two roots sum to zero: a pair +-i omega on the imaginary
    axis (see :func:`ncstab.operators.flutter_onset_indicator`).  NaN where M is
    not regular (:func:`ncstab.operators.dynamic_matrices.regular_mass`: |det M| >
    n eps prod_j |M_j|) or an entry is not finite.
    """
    n = mass.shape[0]
    finite = True
    for i in range(n):
        for j in range(n):
            finite = finite and np.isfinite(mass[i, j]) and np.isfinite(damping[i, j]) and np.isfinite(stiffness[i, j])
    if not finite or np.isnan(regular_determinant(mass)):
        return np.nan
    characteristic_coefficients(mass, damping, stiffness, coefficients)
    degree = 2 * n
    size = degree - 1
    for i in range(size):
        for j in range(size):
            index = 2 * j - i + 1  # hurwitz_matrix: H[i, j] = a_{2j - i + 1}
            hurwitz[i, j] = coefficients[index] / coefficients[0] if 0 <= index <= degree else 0.0
    return np.linalg.det(hurwitz)


def _eigenvalue_batch(matrices, out):
    for b in range(out.shape[0]):
        out[b] = eigenvalue_discriminant(matrices[b])


def _frequency_batch(masses, stiffnesses, out):
    for b in range(out.shape[0]):
        out[b] = frequency_discriminant(masses[b], stiffnesses[b])


def _characteristic_batch(masses, dampings, stiffnesses, out):
    for b in range(out.shape[0]):
        characteristic_coefficients(masses[b], dampings[b], stiffnesses[b], out[b])


def _interpolated_batch(masses, dampings, stiffnesses, out):
    for b in range(out.shape[0]):
        interpolated_coefficients(masses[b], dampings[b], stiffnesses[b], out[b])


def _onset_batch(masses, dampings, stiffnesses, out):
    n = masses.shape[1]
    coefficients = np.empty(2 * n + 1)
    hurwitz = np.empty((2 * n - 1, 2 * n - 1))
    for b in range(out.shape[0]):
        out[b] = damped_onset(masses[b], dampings[b], stiffnesses[b], coefficients, hurwitz)


@functools.cache
def _compiled() -> Any:
    """This module's per-case functions compiled by numba (a generated module in the cache folder)."""
    return compiled_module(
        __name__, regular_determinant, discriminant_2, eigenvalue_discriminant, frequency_discriminant,
        interpolated_coefficients, characteristic_coefficients, damped_onset, _eigenvalue_batch, _frequency_batch, _characteristic_batch,
        _interpolated_batch, _onset_batch,
    )


def eigenvalue_discriminants(matrices: np.ndarray) -> np.ndarray:
    """``(...)``: :func:`eigenvalue_discriminant` of each ``(..., n, n)`` matrix."""
    matrices = np.asarray(matrices, dtype=float)
    n = matrices.shape[-1]
    rows = np.ascontiguousarray(matrices.reshape(-1, n, n))
    out = np.empty(rows.shape[0])
    if out.size:
        _compiled()._eigenvalue_batch(rows, out)
    return out.reshape(matrices.shape[:-2])


def frequency_discriminants(mass: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """``(...)``: :func:`frequency_discriminant` of each case of a batch."""
    shape, (masses, _, stiffnesses) = _rows(mass, mass, stiffness)
    out = np.empty(masses.shape[0])
    if out.size:
        _compiled()._frequency_batch(masses, stiffnesses, out)
    return out.reshape(shape)


def _rows(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> tuple[tuple[int, ...], tuple[np.ndarray, ...]]:
    """The batch shape and the three matrices as contiguous ``(B, n, n)`` float rows."""
    n = mass.shape[-1]
    shape = np.broadcast_shapes(mass.shape[:-2], damping.shape[:-2], stiffness.shape[:-2])
    rows = tuple(
        np.ascontiguousarray(np.broadcast_to(np.asarray(a, dtype=float), shape + (n, n)).reshape(-1, n, n))
        for a in (mass, damping, stiffness)
    )
    return shape, rows


def characteristic_rows(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """``(..., 2n + 1)``: :func:`characteristic_coefficients` of each case of a batch."""
    return _coefficient_rows("_characteristic_batch", mass, damping, stiffness)


def interpolated_rows(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """``(..., 2n + 1)``: :func:`interpolated_coefficients` of each case of a batch."""
    return _coefficient_rows("_interpolated_batch", mass, damping, stiffness)


def _coefficient_rows(batch: str, mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    shape, rows = _rows(mass, damping, stiffness)
    out = np.empty((rows[0].shape[0], 2 * mass.shape[-1] + 1))
    if out.shape[0]:
        getattr(_compiled(), batch)(*rows, out)
    return out.reshape(shape + out.shape[-1:])


def damped_onsets(mass: np.ndarray, damping: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """``(...)``: :func:`damped_onset` of each case of a batch."""
    shape, rows = _rows(mass, damping, stiffness)
    out = np.empty(rows[0].shape[0])
    if out.size:
        _compiled()._onset_batch(*rows, out)
    return out.reshape(shape)
