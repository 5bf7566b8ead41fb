"""The stability indicators of one state, compiled: what the stage loop and the Dataset share.

One implementation for every caller.  The compiled stage loop computes them at
every state it evaluates, to watch their signs (det K for a limit point, the
least eigenvalue of K_sym for Hill's condition, the discriminant of K's
characteristic polynomial for flutter without inertia, det K_SS for the
controllability of a mixed control: :mod:`ncstab.paths.loop_diamond_model`,
:mod:`ncstab.paths.loop_general_output`); the Dataset computes them at every
stored state by :mod:`ncstab.operators.stored_states`, which runs this module's
batch loops (:func:`batch_of_states`, :func:`batch_of_growths`) over the states,
one after the other, compiled in a generated module of the cache folder or as
plain Python.

For two dofs every indicator is a closed form, the operations of
:mod:`ncstab.operators.indicators` in the same order (the same numbers, bit for
bit); beyond, LAPACK's LU (det K, det K_SS) and symmetric eigenvalues (Hill),
and the eigenvalues of K for the discriminant.
"""

from __future__ import annotations

import math

import numpy as np

from ncstab.jit import hot, njit

__all__ = [
    "INDICATOR_NAMES", "batch_of_growths", "batch_of_states", "controlled_determinant", "determinant",
    "determinant_2", "discriminant_2", "eigenvalue_discriminant", "hill", "hill_2", "normalised_work",
    "normalised_work_2", "state_values", "state_values_2", "undamped_growth_2",
]

#: The scalar indicators of :func:`state_values`, in its order (the Dataset's variables).
INDICATOR_NAMES = ("det_K", "hill", "d2W", "flutter", "mixed_control")


@hot
def determinant_2(k00, k01, k10, k11):
    """det K of a 2 x 2 matrix (seed Eq. 36: zero at a limit point under force control)."""
    return k00 * k11 - k01 * k10


@hot
def hill_2(k00, k01, k10, k11):
    """The least eigenvalue of K_sym = (K + K^T) / 2 of a 2 x 2 K: its mean diagonal minus
    the radius of its Mohr circle (K_sym's diagonal is K's, 0.5 (k + k) = k exactly)."""
    mean = 0.5 * (k00 + k11)
    return mean - np.hypot(0.5 * (k00 - k11), 0.5 * (k01 + k10))  # the C library's, as numpy's


@hot
def discriminant_2(k00, k01, k10, k11):
    """(tr K)^2 - 4 det K = (K11 - K22)^2 + 4 K12 K21 of a 2 x 2 K: negative where K has a
    complex pair of eigenvalues (flutter without inertia)."""
    difference = k00 - k11
    return difference * difference + 4 * k01 * k10


@hot
def undamped_growth_2(p00, p01, p10, p11):
    """max Re s of M s^2 + K (C = 0) from P = M^-1 K (2 x 2): the largest |Re sqrt(mu)| over
    the eigenvalues mu of -P, in real arithmetic (:func:`ncstab.operators.flutter_indicator`).

    With h = tr P / 2, d = det P and the discriminant h^2 - d, the eigenvalues of P are
    h +- r, r = sqrt(h^2 - d), where it is >= 0: mu = -(h -+ r) is real and the growth is
    sqrt(max(r - h, 0)), r - h taken as -d / (r + h) where h > 0 (no cancellation near
    d = 0).  Where it is < 0, mu = -h -+ i q with q = sqrt(d - h^2) and |mu| = sqrt(d):
    Re sqrt(mu) = sqrt((sqrt(d) - h) / 2), taken as q / (2 sqrt((sqrt(d) + h) / 2)) where
    h > 0 (the stable form of the complex square root).  NaN where P is not finite.
    """
    half_trace = 0.5 * (p00 + p11)
    determinant = p00 * p11 - p01 * p10
    discriminant = half_trace * half_trace - determinant
    if np.isnan(discriminant):
        return np.nan
    if discriminant >= 0:
        r = math.sqrt(discriminant)
        real_mu = -determinant / (r + half_trace) if half_trace > 0 else r - half_trace
        return math.sqrt(0.0 if real_mu < 0.0 else real_mu)
    modulus = math.sqrt(determinant if determinant > 0.0 else 0.0)
    q = math.sqrt(-discriminant)
    if half_trace > 0:
        return q / (2 * math.sqrt(0.5 * (modulus + half_trace)))
    return math.sqrt(0.5 * (modulus - half_trace))


@njit
def determinant(matrix):
    """det of a finite n x n matrix: closed forms for n <= 2, LAPACK's LU beyond."""
    n = matrix.shape[0]
    if n == 1:
        return matrix[0, 0]
    if n == 2:
        return determinant_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    return np.linalg.det(np.ascontiguousarray(matrix))


@njit
def hill(matrix):
    """The least eigenvalue of (K + K^T) / 2 of a finite n x n K (Hill's condition holds
    while it is positive): closed forms for n <= 2, LAPACK's symmetric eigenvalues beyond."""
    n = matrix.shape[0]
    if n == 1:
        return matrix[0, 0]
    if n == 2:
        return hill_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    return np.linalg.eigvalsh(0.5 * (matrix + matrix.T))[0]


@njit
def eigenvalue_discriminant(matrix):
    """prod_{i<j} (lambda_i - lambda_j)^2 over the eigenvalues of a real n x n matrix (real,
    negative where it has one complex pair: the discriminant of its characteristic
    polynomial; :func:`discriminant_2` for n = 2).  NaN where an entry is not finite."""
    n = matrix.shape[0]
    for i in range(n):
        for j in range(n):
            if not np.isfinite(matrix[i, j]):
                return np.nan
    if n == 2:
        return discriminant_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    eigenvalues = np.linalg.eigvals(matrix.astype(np.complex128))
    product = 1.0 + 0.0j
    for i in range(n):
        for j in range(i + 1, n):
            product = product * (eigenvalues[i] - eigenvalues[j]) ** 2
    return product.real


@njit
def controlled_determinant(matrix, controlled):
    """det K_SS over the force-controlled dofs S (``controlled``, a boolean per dof): the
    controllability of a mixed control, lost where it vanishes (seed Eq. 35: K22 with F2
    held and Delta_1 driven; det K under force control; 1 under a kinematic control)."""
    n = matrix.shape[0]
    m, last = 0, 0
    for i in range(n):
        if controlled[i]:
            m += 1
            last = i
    if m == 0:
        return 1.0
    if m == 1:
        return matrix[last, last]
    if m == n:
        return determinant(matrix)
    sub = np.empty((m, m))
    row = 0
    for i in range(n):
        if controlled[i]:
            column = 0
            for j in range(n):
                if controlled[j]:
                    sub[row, column] = matrix[i, j]
                    column += 1
            row += 1
    return determinant(sub)


@hot
def normalised_work_2(k00, k01, k10, k11, du0, du1):
    """du . K du / (|K du| |du|) of two dofs: the cosine between dF = K du and du along the
    path (numpy's einsum and norms, in their order)."""
    f0 = k00 * du0 + k01 * du1
    f1 = k10 * du0 + k11 * du1
    return (f0 * du0 + f1 * du1) / (math.sqrt(f0 * f0 + f1 * f1) * math.sqrt(du0 * du0 + du1 * du1))


@njit
def normalised_work(matrix, du):
    """du . K du / (|K du| |du|) of n dofs (:func:`normalised_work_2` for two)."""
    n = du.shape[0]
    if n == 2:
        return normalised_work_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1], du[0], du[1])
    work, force_norm, du_norm = 0.0, 0.0, 0.0
    for i in range(n):
        force = 0.0
        for j in range(n):
            force += matrix[i, j] * du[j]
        work += force * du[i]
        force_norm += force * force
        du_norm += du[i] * du[i]
    return work / (math.sqrt(force_norm) * math.sqrt(du_norm))


@hot
def state_values_2(k00, k01, k10, k11, du0, du1, controlled0, controlled1, staged):
    """:func:`state_values` of two dofs, from K's entries and du's (``staged``: whether the
    state has a stage, whose force-controlled dofs are ``controlled0``, ``controlled1``)."""
    mixed = np.nan
    if staged:
        if controlled0 and controlled1:
            mixed = determinant_2(k00, k01, k10, k11)
        elif controlled0:
            mixed = k00
        elif controlled1:
            mixed = k11
        else:
            mixed = 1.0
    return (determinant_2(k00, k01, k10, k11), hill_2(k00, k01, k10, k11),
            normalised_work_2(k00, k01, k10, k11, du0, du1), discriminant_2(k00, k01, k10, k11), mixed)


@njit
def state_values(matrix, du, controlled):
    """:data:`INDICATOR_NAMES` of one state with tangent ``matrix`` (n x n), increment
    ``du`` along the path and force-controlled dofs ``controlled`` (a boolean per dof; empty
    where the state has no stage: det K_SS NaN).  NaN where K is not finite (the closed
    forms of two dofs give what IEEE arithmetic gives, as numpy's do)."""
    n = matrix.shape[0]
    finite = True
    for i in range(n):
        for j in range(n):
            finite = finite and np.isfinite(matrix[i, j])
    det_k, least, mixed = np.nan, np.nan, np.nan
    if n == 2 or finite:
        det_k = determinant(matrix)
        least = hill(matrix)
        if controlled.shape[0] == n:
            mixed = controlled_determinant(matrix, controlled)
    return det_k, least, normalised_work(matrix, du), eigenvalue_discriminant(matrix), mixed


def batch_of_states(stiffness, du, u, stage, controlled, identity_mass, symmetric, skew, out):
    """K_sym, K_skew and :data:`INDICATOR_NAMES` of every stored state ``(cases, steps)``
    (run by :func:`ncstab.operators.stored_states.stored_state_indicators`)."""
    # every stored state of (cases, steps): K_sym, K_skew and state_values; stage < 0: padding;
    # identity_mass (two dofs, M = I, C = 0): flutter is max Re s, NaN where K or u is not finite
    n = stiffness.shape[2]
    none = controlled[0, :0]
    for b in range(stiffness.shape[0]):
        for t in range(stiffness.shape[1]):
            for i in range(n):
                for j in range(n):
                    symmetric[b, t, i, j] = 0.5 * (stiffness[b, t, i, j] + stiffness[b, t, j, i])
                    skew[b, t, i, j] = 0.5 * (stiffness[b, t, i, j] - stiffness[b, t, j, i])
            k = stage[b, t]
            if n == 2:  # from the entries, no views (state_values' numbers, bit for bit)
                k00, k01 = stiffness[b, t, 0, 0], stiffness[b, t, 0, 1]
                k10, k11 = stiffness[b, t, 1, 0], stiffness[b, t, 1, 1]
                values = state_values_2(
                    k00, k01, k10, k11, du[b, t, 0], du[b, t, 1], k >= 0 and controlled[k, 0],
                    k >= 0 and controlled[k, 1], k >= 0,
                )
            else:
                values = state_values(stiffness[b, t], du[b, t], controlled[k] if k >= 0 else none)
            for v in range(len(values)):
                out[v, b, t] = values[v]
            if identity_mass and n == 2:
                finite = np.isfinite(k00) and np.isfinite(k01) and np.isfinite(k10) and np.isfinite(k11)
                finite = finite and np.isfinite(u[b, t, 0]) and np.isfinite(u[b, t, 1])
                out[3, b, t] = undamped_growth_2(k00, k01, k10, k11) if finite else np.nan


def batch_of_growths(product, out):
    """:func:`undamped_growth_2` of each ``(2, 2)`` row of ``product`` into ``out``."""
    for b in range(out.shape[0]):
        out[b] = undamped_growth_2(product[b, 0, 0], product[b, 0, 1], product[b, 1, 0], product[b, 1, 1])
