"""Validation of the mass, damping and stiffness matrices and the solve with M.

Shared by :mod:`ncstab.operators.dynamics` and
:mod:`ncstab.operators.characteristic_polynomial`.
"""

from __future__ import annotations

import numpy as np

from ncstab.operators.indicators import det_K

__all__ = ["as_dynamic_matrices", "regular_mass", "solve_mass"]


def as_dynamic_matrices(
    mass: np.ndarray, damping: np.ndarray | None, stiffness: np.ndarray
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

    The test is sigma_min(M) > n eps sigma_max(M); for n = 2 it is written with
    sigma_min sigma_max = |det M| and sigma_max^2 <= |M|_F^2 (no SVD).
    """
    n = mass.shape[-1]
    finite = np.isfinite(mass).all(axis=(-2, -1))
    safe = np.where(finite[..., None, None], mass, 1.0)
    eps = np.finfo(float).eps
    if n == 1:
        regular = safe[..., 0, 0] != 0
    elif n == 2:
        regular = np.abs(det_K(safe)) > n * eps * np.einsum("...ij,...ij->...", safe, safe)
    else:
        singular_values = np.linalg.svd(safe, compute_uv=False)
        regular = singular_values[..., -1] > n * eps * singular_values[..., 0]
    return finite & regular


def solve_mass(mass: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """M^-1 rhs ``(..., n, m)`` and the ``(...)`` mask of the cases where it is defined.

    Cases with a singular or non-finite M, or a non-finite result, get zeros and
    ``False``: the solve is never asked to factor a singular matrix, so one bad
    case cannot stop the batch.
    """
    valid = regular_mass(mass) & np.isfinite(rhs).all(axis=(-2, -1))
    n = mass.shape[-1]
    safe_mass = np.where(valid[..., None, None], mass, np.eye(n))
    safe_rhs = np.where(valid[..., None, None], rhs, 0.0)
    product = np.linalg.solve(safe_mass, safe_rhs)
    valid &= np.isfinite(product).all(axis=(-2, -1))
    return np.where(valid[..., None, None], product, 0.0), valid
