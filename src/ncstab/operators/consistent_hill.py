"""Hill's condition on the consistent branch: the smallest second-order work over unit directions.

With friction the second-order work of a direction d is ``W(d) = d^T K_{P(d)} d / d^T d``, where
P(d) is the branch pattern d selects (:meth:`FrictionBranches.select`); the minimum over the unit
sphere is the minimum over the patterns P of the minimum of d^T S_P d (S_P = sym K_P) within P's
cone C_P, a polyhedral cone (each contact's switching condition is linear in d).

*Search* (:func:`consistent_hill`): an active-set iteration over patterns, started from the sticking
pattern and from the all-sliding one (every sliding contact sliding, every open one separating):
pattern P -> the smallest eigenpair (lambda, v) of S_P -> the patterns P(v) and P(-v) -> the next
pattern is that of the sign with the lower W, until the eigenvector selects its own pattern (then
lambda = W(v) is the global minimum of d^T S_P d, hence of W over C_P) or a pattern repeats.

*Guarantee*: every value reported is W(d) of a direction d evaluated on the branches d itself
selects (``hill_direction``; checked by :meth:`FrictionBranches.consistent`), so ``hill`` is an upper
bound of the true minimum.  It equals the minimum when the minimizing pattern's eigenvector lies in
its own cone and the search reaches that pattern; it is not a proof of that (no lower bound over the
patterns not visited).  No refinement on the faces of a cone is made.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse

from ncstab.operators.friction_branches import FrictionBranches

__all__ = ["ConsistentHill", "consistent_hill", "smallest_eigenpair"]

#: Up to this many dofs the eigenpairs are dense LAPACK (numpy.linalg.eigh).
DENSE_DOFS = 600


@dataclass(frozen=True)
class ConsistentHill:
    """The result of :func:`consistent_hill`.

    Attributes
    ----------
    value
        min W(d) over the directions met (an upper bound of Hill's minimum on the consistent branch).
    direction : (n,)
        Its unit direction (largest component positive is not imposed: the sign selects the branches).
    pattern : (k,)
        The branches ``direction`` selects (limit contacts, codes of :mod:`ncstab.operators.friction_branches`).
    sticking : float
        The smallest eigenvalue of sym K with every contact elastic.
    patterns
        How many patterns were visited.
    converged
        Whether a visited pattern's own eigenvector selected it (the value is then that pattern's global minimum).
    """

    value: float
    direction: np.ndarray
    pattern: np.ndarray
    sticking: float
    patterns: int
    converged: bool


def smallest_eigenpair(K, guess: float | None = None) -> tuple[float, np.ndarray]:
    """The smallest eigenvalue of S = (K + K^T)/2 and its unit eigenvector.

    Dense below DENSE_DOFS; else shift-invert Lanczos at a shift sigma proved below the spectrum by
    Sylvester's inertia (no negative pivot of LDL^T of S - sigma I), lowered until it is.
    """
    from ncstab.operators.sparse_indicators import negative_pivots

    n = K.shape[0]
    if n <= DENSE_DOFS:
        A = K.toarray() if sparse.issparse(K) else np.asarray(K)
        values, vectors = np.linalg.eigh(0.5 * (A + A.T))
        return float(values[0]), vectors[:, 0]
    import scipy.sparse.linalg as splinalg

    S = (0.5 * (K + K.T)).tocsc()
    scale = float(abs(S).max())
    eye = sparse.identity(n, format="csc")
    step = 1e-3 * scale
    sigma = (0.0 if guess is None else min(guess, 0.0)) - step
    while negative_pivots(S - sigma * eye):
        step *= 8
        sigma -= step
    values, vectors = splinalg.eigsh(S, k=1, sigma=sigma, which="LM", tol=1e-12,
                                     v0=np.cos(np.arange(n) + 0.5))
    return float(values[0]), vectors[:, 0]


def _work(branches: FrictionBranches, d: np.ndarray) -> tuple[float, np.ndarray]:
    pattern = branches.select(d)
    K = branches.tangent(pattern)
    return float(d @ (K @ d) / (d @ d)), pattern


def consistent_hill(branches: FrictionBranches, max_patterns: int = 50) -> ConsistentHill:
    """The active-set search of the module docstring; at most ``max_patterns`` patterns from each start."""
    sticking, v0 = smallest_eigenpair(branches.K_elastic)
    best: tuple[float, np.ndarray, np.ndarray] | None = None
    visited: set[bytes] = set()
    converged = False
    starts = [branches.sticking()]
    if len(branches.limit):
        starts.append(branches.all_sliding())
    for start in starts:
        pattern, guess = start, sticking
        for _ in range(max_patterns):
            key = pattern.tobytes()
            if key in visited:
                break
            visited.add(key)
            value, v = ((sticking, v0) if not pattern.any() else
                        smallest_eigenpair(branches.tangent(pattern), guess))
            candidates = [(*_work(branches, s * v), s * v) for s in (1.0, -1.0)]
            candidates.sort(key=lambda item: item[0])
            for work, selected, d in candidates:
                if best is None or work < best[0]:
                    best = (work, d, selected)
            own = [c for c in candidates if np.array_equal(c[1], pattern)]
            if own:
                converged = True
                break
            pattern, guess = candidates[0][1], value
    assert best is not None
    work, d, selected = best
    return ConsistentHill(work, d / np.linalg.norm(d), selected, sticking, len(visited), converged)
