"""K of a packing with any contact law, and its static indicators: Hill, inertia, det K, modes, participation.

For a packing (:mod:`ncstab.systems.packing`) and a contact law, every contact
is a :class:`~ncstab.elements.grain_contact.GrainContacts` member with its own
length scale rho and reference angle alpha0, chosen so that the law's forces at
the state are the packing's (:func:`contact_references`).  Then (seed Eq. 5, 9,
16 and their derivative, Eq. 30-34)::

    R = sum_c rho_c^2 J_c^T Q*_c,      K = dR/du = sum_c rho_c^2 (J_c^T D*_c J_c + sum_k Q*_ck H_ck),

with Q* = (-N*, l T*) and D* = dQ*/dq from the law
(:func:`ncstab.elements.law_response`), scattered over the free dofs into a
``scipy.sparse`` CSR matrix.  For a rate (hypoelastic) law the stored forces are
the packing's forces and D* is the law's tangent at them.  K is not symmetric
for a law without energy (Cundall-Strack with T != 0); Hill's condition is the
positivity of K_sym = (K + K^T)/2 (the second-order work d^T K d).

Indicators (:func:`analyse_packing`) reuse :mod:`ncstab.operators.sparse_indicators`:
Hill's eigenvalue, the number of negative and zero eigenvalues of K_sym by
Sylvester's inertia of LDL^T (of K_sym -+ tol I), the sign of det K by LU, and
the K smallest eigenpairs of K_sym by shift-invert Lanczos just below Hill's
eigenvalue; dense LAPACK below :data:`DENSE_DOFS` dofs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import sparse

from ncstab.elements.grain_contact import GrainContacts, grain_contact_kinematics
from ncstab.elements.law_response import LawResponse, law_response
from ncstab.systems.packing import Packing, PackingError

__all__ = ["DENSE_DOFS", "PackingAnalysis", "PackingTangent", "analyse_packing", "contact_references",
           "packing_contacts", "packing_tangent", "second_order_work"]

#: Up to this many free dofs the indicators use dense LAPACK (numpy.linalg.eigh of K_sym).
DENSE_DOFS = 600
#: Zero eigenvalues of K_sym: |lambda| <= ZERO_TOLERANCE * max |diag K_sym|.
ZERO_TOLERANCE = 1e-9
#: K is taken as symmetric (a law with energy) where max |K - K^T| <= this times max |K| (rounding).
SYMMETRY_TOLERANCE = 1e-12


@dataclass
class PackingTangent:
    """R and K of a packing over its free dofs (see the module docstring).

    Attributes
    ----------
    R : (n,)
        Internal generalized forces (units k_n d for x, y; k_n d^2 for theta).
    K : (n, n) CSR
        dR/du.
    contacts
        The contacts' kinematic data (each one's rho).
    parameters
        The law's parameters (``alpha0`` per contact).
    forces : (c, 2)
        Stored forces (N, T) at the state, in units of k_n d.
    blocks : (c, 6, 6)
        Each contact's rho^2 (J^T D* J + Q* H) on (x_a, y_a, theta_a, x_b, y_b, theta_b).
    jacobian : (c, 2, 6) or None
        Each contact's J = d(l, beta)/du_e (for the branches of :mod:`ncstab.operators.friction_branches`).
    law_tangent : (c, 2, 2) or None
        Each contact's D* = dQ*/dq.
    conjugates : (c, 2) or None
        Each contact's Q* = (-N*, l T*).
    lengths : (c,) or None
        Each contact's l = |d|/rho.
    """

    R: np.ndarray
    K: Any
    contacts: GrainContacts
    parameters: dict[str, Any]
    forces: np.ndarray
    blocks: np.ndarray
    jacobian: np.ndarray | None = None
    law_tangent: np.ndarray | None = None
    conjugates: np.ndarray | None = None
    lengths: np.ndarray | None = None


def packing_contacts(packing: Packing, scale: np.ndarray | None = None) -> tuple[GrainContacts, int]:
    """The contacts of ``packing`` on its free dofs, and n; held dofs point at slot n (always 0)."""
    n = packing.n_dof
    index = packing.dof_index()
    index[index < 0] = n
    a, b = packing.contacts[:, 0], packing.contacts[:, 1]
    branch = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    total = packing.radius[a] + packing.radius[b]
    lever = np.column_stack([packing.radius[a] / total, packing.radius[b] / total])
    scale = np.linalg.norm(branch, axis=1) if scale is None else scale
    return GrainContacts(np.concatenate([index[a], index[b]], axis=1), branch, lever, scale), n


def _parameters(response: LawResponse, gamma: float, alpha0: np.ndarray) -> dict[str, Any]:
    values: dict[str, Any] = {"gamma": gamma, "alpha0": alpha0}
    missing = [p for p in response.parameter_names if p not in values]
    if missing:
        raise PackingError(f"law {response.law.name!r} needs parameter(s) {', '.join(missing)}, which a packing "
                           "analysis does not set (only gamma and each contact's alpha0)")
    return values


def contact_references(packing: Packing, response: LawResponse, gamma: float,
                       iterations: int = 40) -> tuple[np.ndarray, np.ndarray]:
    """Each contact's length scale rho and reference angle alpha0: the law's forces at the state are the packing's.

    A force of the law with a total form (N of every seed law, T of a total law)
    is matched by Newton's method over all contacts at once, on (rho, alpha0):
    rho N*(|d|/rho, beta; alpha0) = N and rho T*(...) = T (start: rho = |d| + N,
    alpha0 = beta, where the seed's laws are exactly N and 0: zero iterations for
    a packing without tangential forces).  A force without total form (a rate
    law's T) is the packing's, N*/T* = N/rho, T/rho.

    Returns
    -------
    rho, alpha0 : (c,)
    """
    if response.forces != 2 or response.k != 2:
        raise PackingError(f"law {response.law.name!r} is not a contact law (q = (l, alpha), forces N, T)")
    contacts, _ = packing_contacts(packing)
    distance = contacts.scale
    beta = np.arctan2(contacts.branch[:, 1], contacts.branch[:, 0])
    given = np.column_stack([packing.normal_force, packing.tangential_force])
    rho, alpha0 = distance + given[:, 0], beta.copy()
    if (rho <= 0).any():
        i = int(np.flatnonzero(rho <= 0)[0])
        raise PackingError(f"{packing.source}: variable 'normal_force': entry {i} is {given[i, 0]:g}, a tension "
                           f"larger than the contact's length {distance[i]:g} (no rest length)")
    solve = [i not in response.internal for i in range(2)]
    solve[1] = solve[1] and "alpha0" in response.parameter_names
    if not any(solve):
        return rho, alpha0

    def residual(r, a0):
        q = np.column_stack([distance / r, beta])
        f = response.stored_forces(q, given / r[:, None], _parameters(response, gamma, a0))
        return r[:, None] * f - given

    unknowns = [k for k in range(2) if solve[k]]
    for _ in range(iterations):
        res = residual(rho, alpha0)[:, unknowns]
        if np.all(np.abs(res) <= 1e-12 * (1 + np.abs(given[:, unknowns]))):
            return rho, alpha0
        columns = []
        for k in unknowns:  # forward differences, both unknowns at once for every contact
            h = 1e-7 * (rho if k == 0 else 1.0)
            shifted = residual(rho + h, alpha0) if k == 0 else residual(rho, alpha0 + h)
            columns.append((shifted[:, unknowns] - res) / (h[:, None] if k == 0 else h))
        jac = np.stack(columns, axis=2)  # (c, e, e)
        step = _solve_small(jac, res)
        if step is None:
            break
        for j, k in enumerate(unknowns):
            if k == 0:
                rho = rho - step[:, j]
            else:
                alpha0 = alpha0 - step[:, j]
    res = residual(rho, alpha0)[:, unknowns]
    bad = ~np.all(np.abs(res) <= 1e-9 * (1 + np.abs(given[:, unknowns])), axis=1)
    i = int(np.flatnonzero(bad)[0]) if bad.any() else 0
    raise PackingError(f"{packing.source}: variable 'tangential_force': entry {i} is {given[i, 1]:g}, which law "
                       f"{response.law.name!r} with gamma = {gamma:g} cannot carry at this contact's state")


def _solve_small(jac: np.ndarray, res: np.ndarray) -> np.ndarray | None:
    """Solve the (c, e, e) systems; None where one is singular."""
    det = np.linalg.det(jac)
    if not np.all(np.abs(det) > 1e-300):
        return None
    return np.linalg.solve(jac, res[:, :, None])[:, :, 0]


def packing_tangent(packing: Packing, law: Any, gamma: float, u: np.ndarray | None = None,
                    internal: np.ndarray | None = None) -> PackingTangent:
    """R and K of ``packing`` with ``law`` at the free dofs ``u`` (default: the packing's state, u = 0).

    The contacts' rho and alpha0 are those of the state u = 0
    (:func:`contact_references`); the stored forces of a rate law are
    ``internal`` ``(c, 2)`` (N, T in units of k_n d; default the packing's: its
    internal variables do not move with u unless given).
    """
    response = law_response(law)
    rho, alpha0 = contact_references(packing, response, gamma)
    contacts, n = packing_contacts(packing, scale=rho)
    full = np.zeros(n + 1)
    if u is not None:
        full[:n] = u
    params = _parameters(response, gamma, alpha0)
    q, J, H = grain_contact_kinematics(contacts, full)
    if internal is None:
        internal = np.column_stack([packing.normal_force, packing.tangential_force])
    given = np.asarray(internal, dtype=float) / rho[:, None]
    f = response.stored_forces(q, given, params)
    Q, D, _ = response.response(q, f, params)
    w = rho * rho
    R = np.bincount(contacts.dofs.ravel(), (w[:, None] * np.einsum("mkl,mk->ml", J, Q)).ravel(), minlength=n + 1)[:n]
    blocks = w[:, None, None] * (np.einsum("mka,mkp,mpb->mab", J, D, J) + np.einsum("mk,mkab->mab", Q, H))
    rows = np.repeat(contacts.dofs, 6, axis=1).ravel()
    cols = np.tile(contacts.dofs, (1, 6)).ravel()
    keep = (rows < n) & (cols < n)
    K = sparse.csr_matrix((blocks.ravel()[keep], (rows[keep], cols[keep])), shape=(n, n))
    K.sum_duplicates()
    return PackingTangent(R, K, contacts, params, f * rho[:, None], blocks, J, D, Q, q[:, 0])


def second_order_work(K, directions: np.ndarray) -> np.ndarray:
    """d^T K d / d^T d for each direction (rows of ``directions``, ``(p, n)``): negative where Hill's condition fails."""
    d = np.atleast_2d(np.asarray(directions, dtype=float))
    return np.einsum("pn,pn->p", d, (K @ d.T).T) / np.einsum("pn,pn->p", d, d)


@dataclass
class PackingAnalysis:
    """The indicators of a packing's K (see :func:`analyse_packing`).

    Attributes
    ----------
    tangent
        R and K.
    hill
        The smallest eigenvalue of K_sym.
    negative_eigenvalues, zero_eigenvalues
        Eigenvalues of K_sym below -tolerance and within +-tolerance.
    tolerance
        ZERO_TOLERANCE times max |diag K_sym|.
    det_sign
        Sign of det K (0: K is singular: no held grain, a free grain without contact,
        or a symmetric K with zero eigenvalues); by LU, or for a symmetric K by its inertia.
    asymmetry
        max |K - K^T| / max |K|.
    mode_values : (k,)
        The k smallest eigenvalues of K_sym, ascending.
    modes : (k, n)
        Their unit eigenvectors (largest component positive).
    participation : (k, g)
        Each mode's share of its squared norm on each grain (sum 1 per mode; held grains 0).
    """

    tangent: PackingTangent
    hill: float
    negative_eigenvalues: int
    zero_eigenvalues: int
    tolerance: float
    det_sign: int
    asymmetry: float
    mode_values: np.ndarray
    modes: np.ndarray
    participation: np.ndarray


def analyse_packing(packing: Packing, law: Any, gamma: float = 1.0, modes: int = 6) -> PackingAnalysis:
    """K of ``packing`` with ``law`` (:func:`packing_tangent`) and its indicators (see the module docstring)."""
    from ncstab.operators.sparse_indicators import determinant, hill_eigenvalue, negative_pivots

    tangent = packing_tangent(packing, law, gamma)
    K = tangent.K
    n = K.shape[0]
    if n == 0:
        raise PackingError(f"{packing.source}: every grain is held (variable 'fixed'): no free dof to analyse")
    S = ((K + K.T) * 0.5).tocsr()
    size = float(abs(K).max()) if K.nnz else 0.0
    asymmetry = float(abs(K - K.T).max()) / size if size > 0 else 0.0
    scale = float(np.max(np.abs(S.diagonal()))) if K.nnz else 0.0
    tolerance = ZERO_TOLERANCE * max(scale, 1e-300)
    k = max(0, min(int(modes), n - (0 if n <= DENSE_DOFS else 1)))
    if n <= DENSE_DOFS:
        values, vectors = np.linalg.eigh(S.toarray())
        hill = float(values[0])
        negative = int(np.sum(values < -tolerance))
        zero = int(np.sum(np.abs(values) <= tolerance))
        mode_values, mode_vectors = values[:k], vectors[:, :k]
    else:
        import scipy.sparse.linalg as splinalg

        eye = sparse.identity(n, format="csr")
        order = _fill_reducing_order(S, tolerance)
        P = S[order][:, order].tocsr()
        below = negative_pivots(P + tolerance * eye)  # eigenvalues < -tol (Sylvester), LDL^T in that order
        within = negative_pivots(P - tolerance * eye) - below
        negative, zero = below, within
        if below or not k:  # the lowest eigenvalue places the shift (shifted: a singular K_sym factorizes)
            hill = hill_eigenvalue(P + tolerance * eye) - tolerance
            shift = hill - max(tolerance, 1e-6 * scale)
        else:  # every eigenvalue >= -tol: a shift below -tol is below them all
            hill, shift = np.nan, -tolerance - max(tolerance, 1e-6 * scale)
        if k:
            mode_values, vectors = splinalg.eigsh(P.tocsc(), k=k, sigma=shift, which="LM", tol=1e-12)
            sort = np.argsort(mode_values)
            mode_values = mode_values[sort]
            mode_vectors = np.empty_like(vectors)
            mode_vectors[order] = vectors[:, sort]
            hill = float(mode_values[0]) if np.isnan(hill) else hill
        else:
            mode_values, mode_vectors = np.zeros(0), np.zeros((n, 0))
    symmetric = asymmetry <= SYMMETRY_TOLERANCE
    singular = not packing.fixed.any() or _free_without_contact(packing) or (symmetric and zero > 0)
    if singular:
        det_sign = 0
    elif symmetric:  # Sylvester: det K_sym = product of eigenvalues
        det_sign = -1 if negative % 2 else 1
    else:
        det_sign = int(determinant(K if n > DENSE_DOFS else K.toarray())[0])
    mode_vectors = mode_vectors.T
    flip = np.sign(mode_vectors[np.arange(len(mode_vectors)), np.argmax(np.abs(mode_vectors), axis=1)])
    mode_vectors = mode_vectors * np.where(flip == 0, 1.0, flip)[:, None]
    return PackingAnalysis(tangent, hill, negative, zero, tolerance, det_sign, asymmetry, np.asarray(mode_values),
                           mode_vectors, participation(packing, mode_vectors))


def _fill_reducing_order(S, tolerance: float) -> np.ndarray:
    """A symmetric fill-reducing order of S (SuperLU's minimum degree on S + S^T, from one
    symbolic-and-numeric factorization of S + tol I); reverse Cuthill-McKee where that fails.

    An LDL^T without pivoting (:func:`~ncstab.operators.sparse_indicators.negative_pivots`)
    of S in this order has a quarter of the fill of the banded order at 10,000 grains.
    """
    import scipy.sparse.linalg as splinalg
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    n = S.shape[0]
    try:
        lu = splinalg.splu((S + tolerance * sparse.identity(n, format="csr")).tocsc(), permc_spec="MMD_AT_PLUS_A",
                           diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    except RuntimeError:
        return reverse_cuthill_mckee(S, symmetric_mode=True)
    order = np.empty(n, dtype=np.intp)
    order[lu.perm_c] = np.arange(n)
    return order


def _free_without_contact(packing: Packing) -> bool:
    touched = np.zeros(packing.n_grains, dtype=bool)
    touched[packing.contacts.ravel()] = True
    return bool(np.any(~packing.fixed & ~touched))


def participation(packing: Packing, modes: np.ndarray) -> np.ndarray:
    """Each mode's share of its squared norm on each grain, ``(k, g)`` (held grains 0; rows sum to 1)."""
    per_grain = mode_components(packing, modes)
    energy = np.sum(per_grain**2, axis=2)
    total = energy.sum(axis=1, keepdims=True)
    return energy / np.where(total > 0, total, 1.0)


def mode_components(packing: Packing, modes: np.ndarray) -> np.ndarray:
    """Modes over the free dofs ``(k, n)`` as ``(k, g, 3)`` (x, y, theta; held grains 0)."""
    out = np.zeros((len(modes), packing.n_grains, 3))
    out[:, packing.free] = modes.reshape(len(modes), len(packing.free), 3)  # (also no mode: --modes 0)
    return out
