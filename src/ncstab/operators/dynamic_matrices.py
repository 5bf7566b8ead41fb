"""Validation of the mass, damping and stiffness matrices and the solve with M.

Shared by :mod:`ncstab.operators.dynamics` and
:mod:`ncstab.operators.characteristic_polynomial`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ncstab.operators.indicators import det_K

__all__ = ["as_dynamic_matrices", "regular_mass", "solve_mass"]


def as_dynamic_matrices(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """Validate M, C, K and broadcast them to one batch shape ``(..., n, n)``.

    Raises
    ------
    ValueError
        Naming the matrix whose shape is not ``(..., n, n)``, or the shapes that
        disagree in n or do not broadcast.
    """
    named = {"M": mass, "C": damping, "K": stiffness}
    arrays: dict[str, np.ndarray] = {}
    for name, value in named.items():
        if value is None:
            continue
        array = np.asarray(value, dtype=float)
        if array.ndim < 2 or array.shape[-1] != array.shape[-2] or array.shape[-1] == 0:
            raise ValueError(f"{name} must have shape (..., n, n) with n >= 1, got {array.shape}")
        arrays[name] = array
    sizes = {name: array.shape[-1] for name, array in arrays.items()}
    if len(set(sizes.values())) != 1:
        raise ValueError(
            "M, C and K must all be n x n: got "
            + ", ".join(f"{name} {array.shape}" for name, array in arrays.items())
        )
    n = sizes["M"]
    try:
        batch = np.broadcast_shapes(*(array.shape[:-2] for array in arrays.values()))
    except ValueError:
        raise ValueError(
            "the batch dimensions of "
            + ", ".join(f"{name} {array.shape}" for name, array in arrays.items())
            + " do not broadcast"
        ) from None
    full = {name: np.broadcast_to(array, batch + (n, n)) for name, array in arrays.items()}
    return full["M"], full.get("C"), full["K"]


def regular_mass(mass: np.ndarray) -> np.ndarray:
    """``(...)`` bool: M finite and not singular to working precision.

    Hadamard's inequality |det M| <= prod_j |M_j| (the Euclidean norms of the
    columns) makes h = |det M| / prod_j |M_j| a measure in [0, 1] of how far the
    columns are from linearly dependent, unchanged by scaling the columns (a
    graded mass matrix such as diag(1, 1e-8) has h = 1).  M is taken as singular
    where h <= n eps: then the smallest singular value of M with unit columns is
    at most n eps n^((n-1)/2).  det M is the closed form for n <= 2 and LU
    beyond; an exact zero pivot gives det M = 0, so the solve that follows never
    meets one.

    Parameters
    ----------
    mass
        ``(..., n, n)``.

    Returns
    -------
    numpy.ndarray
        ``(...)`` bool.
    """
    n = mass.shape[-1]
    finite = np.isfinite(mass).all(axis=(-2, -1))
    safe = np.where(finite[..., None, None], mass, 1.0)
    determinant = det_K(safe) if n == 2 else np.linalg.det(safe)
    column_norms = np.sqrt(np.einsum("...ij,...ij->...j", safe, safe))
    return finite & (np.abs(determinant) > n * np.finfo(float).eps * np.prod(column_norms, axis=-1))


def solve_mass(mass: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M^-1 rhs ``(..., n, m)`` and the ``(...)`` mask of the cases where it is defined.

    Cases with a singular or non-finite M, or a non-finite result, get zeros and
    ``False``: the solve is never asked to factor a singular matrix, so one bad
    case cannot stop the batch.
    """
    n = mass.shape[-1]
    if mass.size and bool((mass == np.eye(n)).all()):  # M = I (no inertia given): M^-1 rhs = rhs exactly
        valid = np.isfinite(rhs).all(axis=(-2, -1)) & np.ones(mass.shape[:-2], dtype=bool)
        return np.where(valid[..., None, None], rhs, 0.0), valid
    valid = regular_mass(mass) & np.isfinite(rhs).all(axis=(-2, -1))
    safe_mass = np.where(valid[..., None, None], mass, np.eye(n))
    safe_rhs = np.where(valid[..., None, None], rhs, 0.0)
    product = np.linalg.solve(safe_mass, safe_rhs)
    valid &= np.isfinite(product).all(axis=(-2, -1))
    return np.where(valid[..., None, None], product, 0.0), valid
