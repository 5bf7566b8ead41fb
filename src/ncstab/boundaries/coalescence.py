"""The first guess of an undamped flutter boundary: the coalescing pair and its Jordan chain.

Without damping, flutter of ``M s^2 + K`` is the coalescence of two pairs
``s = +- i omega``: a double eigenvalue ``mu = omega^2`` of the pencil
``K - mu M`` with an eigenvector v and a Jordan vector w,
``(K - mu M) v = 0``, ``(K - mu M) w = M v``.  At a located flutter onset
(accurate to the path's event tolerance) the two eigenvalues of ``M^-1 K``
that are closest to one another are that pair; their mean is the guess of mu,
the smallest right singular vector of ``K - mu M`` that of v, and the bordered
solve ``[[K - mu M, v], [v^T, 0]] [w; t] = [M v; 0]`` that of w.
"""

from __future__ import annotations

import numpy as np

__all__ = ["coalescing_pair", "is_undamped"]


def is_undamped(damping: np.ndarray | None) -> bool:
    """Whether the damping matrices ``(B, n, n)`` (or ``None``) all vanish."""
    return damping is None or not np.any(np.asarray(damping))


def coalescing_pair(K: np.ndarray, M: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """``(omega, v, w)`` of the closest pair of eigenvalues of ``M^-1 K`` ``(n, n)``.

    Returns
    -------
    omega
        ``sqrt(mu)``, mu the mean of the pair's real parts.
    v, w
        ``(n,)`` real: v a unit eigenvector guess of ``K - mu M``, w its Jordan
        vector guess with ``v . w = 0``.

    Raises
    ------
    ValueError
        The system has fewer than two dofs, or the pair is not at ``mu > 0``.
    """
    n = K.shape[0]
    if n < 2:
        raise ValueError("an undamped flutter onset needs two coalescing eigenvalues: the system has one dof")
    mu = np.linalg.eigvals(np.linalg.solve(M, K))
    gap = np.abs(mu[:, None] - mu[None, :]) + np.diag(np.full(n, np.inf))
    i, j = np.unravel_index(int(np.argmin(gap)), gap.shape)
    double = 0.5 * float((mu[i] + mu[j]).real)
    if not double > 0.0:
        raise ValueError(f"the closest eigenvalues of M^-1 K coalesce at omega^2 = {double:.6g}, not at a frequency omega > 0")
    pencil = K - double * M
    v = np.linalg.svd(pencil)[2][-1]
    bordered = np.block([[pencil, v[:, None]], [v[None, :], np.zeros((1, 1))]])
    w = np.linalg.solve(bordered, np.append(M @ v, 0.0))[:n]
    return float(np.sqrt(double)), v, w
