"""Static indicators of a dense or sparse K: det K's sign and size, Hill's eigenvalue, inertia.

For large n det K over- or underflows, so its sign and log|det K| come from
one LU factorization (SuperLU: det = prod diag(U) times the signs of the row
and column permutations); the eigenvalue that crosses zero at a limit or
bifurcation point is found by shift-invert Lanczos/Arnoldi at 0 (ARPACK);
Hill's eigenvalue, the smallest of K_sym, by shift-invert below a Gershgorin
lower bound of the spectrum (the nearest eigenvalue to a shift below every
eigenvalue is the smallest); the inertia of K_sym (how many eigenvalues are
negative: the unstable directions of the second-order work) by Sylvester's
law, counting the negative pivots of its LDL^T factorization (an LU without
pivoting).  Below :data:`DENSE_LIMIT` dofs numpy's dense routines give the same
numbers directly.
"""

from __future__ import annotations

import numpy as np
import scipy.sparse as sparse
import scipy.sparse.linalg as splinalg

__all__ = ["DENSE_LIMIT", "critical_eigenvalue", "determinant", "hill_eigenvalue", "is_symmetric", "lu_determinant", "negative_pivots",
           "permutation_sign", "start_vector"]

#: Up to this size the indicators use dense linear algebra.
DENSE_LIMIT = 200
#: An eigenvalue within this part of max |K_ij| of zero carries no sign (double rounding).
ROUNDING = 1e-13


def permutation_sign(perm: np.ndarray) -> int:
    """+1 or -1: the parity of a permutation, (-1)^(n - its number of cycles) (the cycles are the
    connected components of the graph i -> perm[i]: O(n), in compiled code)."""
    from scipy.sparse.csgraph import connected_components

    perm = np.asarray(perm)
    n = len(perm)
    if n == 0:
        return 1
    graph = sparse.csr_matrix((np.ones(n), (np.arange(n), perm)), shape=(n, n))
    cycles = connected_components(graph, directed=True, connection="weak", return_labels=False)
    return -1 if (n - cycles) % 2 else 1


def determinant(K) -> tuple[float, float]:
    """(sign, log|det K|) of a dense or sparse square matrix (sign 0 if singular)."""
    if not sparse.issparse(K):
        return tuple(float(x) for x in np.linalg.slogdet(np.asarray(K)))  # type: ignore[return-value]
    if K.shape[0] == 0:
        return 1.0, 0.0
    try:
        lu = splinalg.splu(K.tocsc())
    except RuntimeError:  # exactly singular
        return 0.0, -np.inf
    return lu_determinant(lu)


def lu_determinant(lu) -> tuple[float, float]:
    """(sign, log|det|) from a SuperLU factorization (Pr A Pc = L U, L unit lower)."""
    diagonal = lu.U.diagonal()
    sign = np.prod(np.sign(diagonal)) * permutation_sign(lu.perm_r) * permutation_sign(lu.perm_c)
    return float(sign), float(np.sum(np.log(np.abs(diagonal))))


def critical_eigenvalue(K) -> tuple[float, np.ndarray]:
    """The real eigenvalue of K nearest zero and its (real, unit) right eigenvector."""
    n = K.shape[0]
    symmetric = is_symmetric(K)
    if not sparse.issparse(K) or n <= DENSE_LIMIT:
        A = K.toarray() if sparse.issparse(K) else np.asarray(K)
        if symmetric:
            values, vectors = np.linalg.eigh(A)
        else:
            values, vectors = np.linalg.eig(A)
        real = np.abs(values.imag) <= 1e-12 * (1 + np.abs(values.real)) if np.iscomplexobj(values) else np.ones(n, bool)
        candidates = np.flatnonzero(real) if real.any() else np.arange(n)
        k = candidates[np.argmin(np.abs(values[candidates].real))]
        vector = np.real(vectors[:, k])
        return float(np.real(values[k])), vector / np.linalg.norm(vector)
    if symmetric:
        values, vectors = splinalg.eigsh(K.tocsc(), k=1, sigma=0.0, which="LM", tol=1e-13, v0=start_vector(n))
    else:
        values, vectors = splinalg.eigs(K.tocsc(), k=1, sigma=0.0, which="LM", tol=1e-13, v0=start_vector(n))
    vector = np.real(vectors[:, 0])
    return float(np.real(values[0])), vector / np.linalg.norm(vector)


def start_vector(n: int) -> np.ndarray:
    """ARPACK's starting vector: fixed (a seeded draw), so that a run repeats bit for bit
    (ARPACK draws a random one otherwise), and not orthogonal to any particular mode."""
    return np.random.default_rng(20221).standard_normal(n)


def is_symmetric(K) -> bool:
    """K = K^T to 1e-13 of max |K_ij| (dense or sparse)."""
    difference = K - K.T
    size = abs(K).max() if sparse.issparse(K) else np.abs(K).max()
    largest = abs(difference).max() if sparse.issparse(difference) else np.abs(difference).max()
    return bool(largest <= 1e-13 * max(size, 1e-300))


def hill_eigenvalue(K) -> float:
    """The smallest eigenvalue of K_sym = (K + K^T)/2 (Hill's condition holds while > 0).

    Large sparse K: shift-invert Lanczos at 0 (ARPACK; one sparse LU, O(n) for banded K) for
    as many eigenvalues as K_sym has negative ones plus one, checked against that count
    (Sylvester's inertia, :func:`negative_pivots`); else plain Lanczos for the lowest.  (LAPACK's
    banded solver, tried before, allocates an n x n workspace: 0.23 s a call at n = 10,000.)
    """
    if not sparse.issparse(K) or K.shape[0] <= DENSE_LIMIT:
        A = K.toarray() if sparse.issparse(K) else np.asarray(K)
        return float(np.linalg.eigvalsh(0.5 * (A + A.T))[0])
    S = (0.5 * (K + K.T)).tocsc()
    negative = negative_pivots(S)
    count = min(negative + 1, S.shape[0] - 1)
    values = splinalg.eigsh(S, k=count, sigma=0.0, which="LM", tol=1e-13, return_eigenvectors=False,
                            v0=start_vector(S.shape[0]))
    noise = ROUNDING * abs(S).max()
    if int(np.sum(values < -noise)) <= negative <= int(np.sum(values < noise)):
        return float(np.min(values))  # the count agrees (up to eigenvalues within rounding of 0)
    # the nearest eigenvalues to 0 were not all the negative ones: shift-invert below the
    # spectrum (Gershgorin's bound), where the lowest eigenvalue is the nearest
    radius = np.asarray(abs(S).sum(axis=1)).ravel() - np.abs(S.diagonal())
    below = float(np.min(S.diagonal() - radius)) - 1.0
    return float(splinalg.eigsh(S, k=1, sigma=below, which="LM", tol=1e-13, return_eigenvectors=False,
                                v0=start_vector(S.shape[0]))[0])


def negative_pivots(S) -> int:
    """The number of negative eigenvalues of a symmetric matrix (Sylvester: negative pivots of LDL^T)."""
    if not sparse.issparse(S) or S.shape[0] <= DENSE_LIMIT:
        A = S.toarray() if sparse.issparse(S) else np.asarray(S)
        return int(np.sum(np.linalg.eigvalsh(A) < 0))
    lu = splinalg.splu(sparse.csc_matrix(S), permc_spec="NATURAL", diag_pivot_thresh=0.0,
                       options={"SymmetricMode": True})
    return int(np.sum(lu.U.diagonal() < 0))
