"""Stability indicators as pure functions of the tangent operator K.

Every function takes arrays of shape ``(..., n, n)`` (any leading batch
dimensions, like :mod:`numpy.linalg`) and returns ``(...)`` or ``(..., n, n)``.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

__all__ = [
    "symmetric_part",
    "skew_part",
    "det_K",
    "hill_eigenvalue",
    "second_order_work",
    "normalized_second_order_work",
    "flutter_discriminant",
    "force_controlled_mask",
    "mixed_control_determinant",
    "mixed_control_stiffness",
]


def _on_finite(function, matrices: np.ndarray) -> np.ndarray:
    """``function`` of the ``(..., n, n)`` matrices whose entries are all finite, NaN
    for the others (padding after a path's end, a failed case): LAPACK is not asked
    about NaN matrices."""
    finite = np.isfinite(matrices).all(axis=(-2, -1))
    out = np.full(matrices.shape[:-2], np.nan)
    if finite.any():
        out[finite] = function(matrices[finite])
    return out


def symmetric_part(stiffness: np.ndarray) -> np.ndarray:
    """K_sym = (K + K^T) / 2."""
    return 0.5 * (stiffness + np.swapaxes(stiffness, -1, -2))


def skew_part(stiffness: np.ndarray) -> np.ndarray:
    """K_skew = (K - K^T) / 2 (zero for a hyperelastic law at equilibrium, seed Eq. 41)."""
    return 0.5 * (stiffness - np.swapaxes(stiffness, -1, -2))


def det_K(stiffness: np.ndarray) -> np.ndarray:
    """det K: vanishes at a limit point under force control (divergence, seed Eq. 36)."""
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.shape[-1] == 2:  # closed form: exact and faster than LU
        return stiffness[..., 0, 0] * stiffness[..., 1, 1] - stiffness[..., 0, 1] * stiffness[..., 1, 0]
    return _on_finite(np.linalg.det, stiffness)


def hill_eigenvalue(stiffness: np.ndarray) -> np.ndarray:
    """Smallest eigenvalue of K_sym.

    Hill's condition (second-order work du . K du > 0 for every du != 0) holds
    while it is positive.
    """
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.shape[-1] == 2:
        # From K's entries: K_sym's diagonal is K's (0.5 (k + k) = k exactly), its
        # off-diagonal entry 0.5 (K01 + K10), as symmetric_part rounds it.
        k00, k11 = stiffness[..., 0, 0], stiffness[..., 1, 1]
        mean = 0.5 * (k00 + k11)
        radius = np.hypot(0.5 * (k00 - k11), 0.5 * (stiffness[..., 0, 1] + stiffness[..., 1, 0]))
        return mean - radius
    return _on_finite(lambda m: np.linalg.eigvalsh(m)[..., 0], symmetric_part(stiffness))


def second_order_work(stiffness: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """d2W = du . K du for displacement increments ``du`` of shape ``(..., n)``."""
    return np.einsum("...i,...ij,...j->...", direction, stiffness, direction)


def normalized_second_order_work(stiffness: np.ndarray, direction: np.ndarray) -> np.ndarray:
    """du . K du / |du|^2: independent of the length of ``du``, in [hill, max eig K_sym]."""
    return second_order_work(stiffness, direction) / np.einsum("...i,...i->...", direction, direction)


def flutter_discriminant(stiffness: np.ndarray) -> np.ndarray:
    """Discriminant of the characteristic polynomial of K.

    Negative when K has a complex-conjugate pair of eigenvalues (flutter).
    For 2x2: ``(tr K)^2 - 4 det K = (K11 - K22)^2 + 4 K12 K21``.  For n x n:
    ``prod_{i<j} (lambda_i - lambda_j)^2``, real for a real matrix.
    """
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.shape[-1] == 2:
        return (stiffness[..., 0, 0] - stiffness[..., 1, 1]) ** 2 + 4 * stiffness[..., 0, 1] * stiffness[..., 1, 0]
    from ncstab.operators.onset_cases import eigenvalue_discriminants

    return eigenvalue_discriminants(stiffness)  # each case alone, the compiled stepper's function


def force_controlled_mask(force_controlled: Sequence[bool] | Sequence[int] | np.ndarray, n: int) -> np.ndarray:
    """Boolean mask of the force-controlled dofs from indices or booleans."""
    array = np.asarray(force_controlled)
    if array.dtype == bool:
        if array.shape[-1:] != (n,):
            raise ValueError(f"force_controlled mask must have length {n}, got shape {array.shape}")
        return array
    mask = np.zeros(n, dtype=bool)
    for index in array.ravel():
        if not 0 <= int(index) < n:
            raise ValueError(f"force_controlled index {int(index)} out of range for {n} dofs")
        mask[int(index)] = True
    return mask


def mixed_control_determinant(stiffness: np.ndarray, force_controlled: Sequence[int] | np.ndarray) -> np.ndarray:
    """det K_SS for the force-controlled dofs S (controllability of a mixed control).

    Under a mixed control (dF_S prescribed, du_D prescribed) the response is
    du_S = K_SS^{-1} (dF_S - K_SD du_D): the control is lost where det K_SS = 0.
    With F2 held and Delta_1 driven this is K22 (seed Eq. 35); with every dof
    force-controlled it is det K; with none it is 1 (kinematic control).

    Parameters
    ----------
    stiffness
        ``(..., n, n)``.
    force_controlled
        Indices (or a boolean mask of length n) of the force-controlled dofs;
        one selection for the whole batch.
    """
    stiffness = np.asarray(stiffness, dtype=float)
    n = stiffness.shape[-1]
    mask = force_controlled_mask(force_controlled, n)
    if mask.ndim != 1:
        raise ValueError("force_controlled must be one selection for the whole batch")
    index = np.flatnonzero(mask)
    if index.size == 0:
        return np.ones(stiffness.shape[:-2])
    sub = stiffness[..., index[:, None], index[None, :]]
    return sub[..., 0, 0] if index.size == 1 else det_K(sub)


def mixed_control_stiffness(stiffness: np.ndarray, force_controlled: Sequence[int] | np.ndarray) -> np.ndarray:
    """det K / det K_SS: determinant of the Schur complement on the driven dofs.

    For two dofs with F2 held and Delta_1 driven this is the path's slope
    dF1/dDelta1 = (K11 K22 - K12 K21) / K22 of seed Eq. (35).
    """
    return det_K(stiffness) / mixed_control_determinant(stiffness, force_controlled)
