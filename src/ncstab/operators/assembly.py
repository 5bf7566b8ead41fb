"""Assembly of R and K from element arrays: K = sum_e A_e^T K_e A_e, dense or sparse.

For every element family of an :class:`~ncstab.systems.assembled.AssembledSystem`
(seed Eq. 5, 9, 16 and their derivative, Eq. 30-34 for a contact):

    R = sum_e w J_e^T Q_e - P Q_ext + gap springs,
    K = dR/du = sum_e w [J_e^T D_e J_e + sum_c Q_ec H_ec] - P dQ_ext/du + gap springs,

with J_e, H_e the members' kinematics on their own dofs (the element protocol
of :mod:`ncstab.elements`: a contact is a branch, ``BranchElements``, or a
contact between rotating disks, ``GrainContacts``, whose w = rho_e^2 is its own;
both give q = (l, alpha) -- alpha is beta for rotating disks -- with J and H),
Q_e, D_e the law's response
(:func:`ncstab.elements.law_response`), Q_ext the axial load per unit P
(:func:`ncstab.elements.shortening`) or the tip load's (follower or dead,
:func:`ncstab.elements.tip_load_terms`: dQ_ext/du as 2 x 2 blocks, not symmetric for a
follower load), and each closed secondary contact a
frictionless spring of energy w kappa g^2 / 2 (g = centre distance - 1):
F += w kappa g grad g, K += w kappa (grad g grad g^T + g hess g).  Element
matrices are scattered by their dof maps in one vectorised call, into a dense
array (small n) or a ``scipy.sparse`` CSR matrix (large n), as a finite-element
code assembles (scikit-fem's ``asm``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import scipy.sparse as sparse

from ncstab.elements import BranchElements, branch_kinematics, law_response, shortening, tip_load_terms
from ncstab.systems.assembled import AssembledSystem

__all__ = ["AssembledState", "assemble", "energy_forms", "gap_candidates", "gap_elements", "gap_springs",
           "member_responses"]


@dataclass
class AssembledState:
    """R, K and the members' variables at one state.

    Attributes
    ----------
    R : (n,)
        Internal generalized forces minus the loads.
    K : (n, n) array or CSR matrix
        dR/du (load stiffness included).
    dR_dload : (n,)
        dR/dP = -Q_ext (zeros without a load).
    members
        Per family name: ``q`` (m, k), ``f`` stored forces (m, forces), ``J``
        (m, k, L), ``C`` rate rows (m, forces, k), ``dofs`` (m, L).
    gaps : (p,)
        Distances of the candidate gaps (:func:`gap_candidates`) given.
    """

    R: np.ndarray
    K: Any
    dR_dload: np.ndarray
    members: dict[str, dict[str, np.ndarray]]
    gaps: np.ndarray


def _scatter(n: int, dofs: np.ndarray, blocks: np.ndarray, dense: bool):
    """Sum element blocks ``(m, L, L)`` into an n x n matrix by their dof maps ``(m, L)``."""
    L = dofs.shape[1]
    rows = np.repeat(dofs, L, axis=1).ravel()
    cols = np.tile(dofs, (1, L)).ravel()
    if dense:
        out = np.zeros(n * n)
        np.add.at(out, rows * n + cols, blocks.ravel())
        return out.reshape(n, n)
    return sparse.csr_matrix((blocks.ravel(), (rows, cols)), shape=(n, n))


def _weights(weight, m: int) -> np.ndarray:
    """The members' weights ``(m,)`` (one for the family, or one per member)."""
    return np.broadcast_to(np.asarray(weight, dtype=float), (m,))


def member_responses(system: AssembledSystem, law: Any, parameters: dict[str, float], u: np.ndarray,
                     internal: dict[str, np.ndarray]):
    """Each family of members at ``u``: (dofs (m, L), J (m, k, L), H (m, k, L, L), Q (m, k),
    D = dQ/dq (m, k, k), weights (m,)) -- the contacts under ``law`` (each with the system's
    alpha0), the springs under their own law; ``internal``: the stored forces per family."""
    if system.contacts is not None:
        yield _responses(system.contacts, law_response(law), {**parameters, "alpha0": system.contact_alpha0},
                         internal["contacts"], u)
    if system.springs is not None:
        yield _responses(system.springs, law_response(system.spring_law), parameters, internal["springs"], u)


def _responses(elements, response, values, internal, u):
    q, J, H = elements.kinematics(u)
    Q, D, _ = response.response(q, response.stored_forces(q, internal, values), values)
    return elements.dofs, J, H, Q, D, _weights(elements.weight, len(q))


def gap_springs(system: AssembledSystem, closed: np.ndarray, u: np.ndarray, kappa: float):
    """The springs of closed secondary contacts ``closed`` (grain pairs), stiffness kappa, at
    ``u``: (dofs (p, L), gaps g = l - 1 (p,), forces (p, L), stiffness blocks (p, L, L))."""
    springs = gap_elements(system, closed)
    q, J, H = branch_kinematics(springs, u)
    g = q[:, 0] - 1.0
    scale = springs.weight * kappa
    grad, hess = J[:, 0], H[:, 0]
    return springs.dofs, g, scale * g[:, None] * grad, scale * (grad[:, :, None] * grad[:, None, :] + g[:, None, None] * hess)


def _family(kinematics, response, weight, parameters, internal, n, dense):
    q, J, H = kinematics
    f = response.stored_forces(q, internal, parameters)
    Q, D, C = response.response(q, f, parameters)
    w = _weights(weight, len(q))
    forces = w[:, None] * np.einsum("mkl,mk->ml", J, Q)
    blocks = w[:, None, None] * (np.einsum("mka,mkp,mpb->mab", J, D, J) + np.einsum("mk,mkab->mab", Q, H))
    return q, f, J, C, forces, blocks


def gap_elements(system: AssembledSystem, pairs: np.ndarray) -> BranchElements:
    """The branches X_a - X_b of grain pairs ``(p, 2)`` in the global frame (their l is the centre distance)."""
    grains = system.grains
    assert grains is not None
    a, b = pairs[:, 0], pairs[:, 1]
    return BranchElements(
        names=tuple(f"{x + 1}_{y + 1}" for x, y in pairs),
        dofs=np.concatenate([grains.dofs[a], grains.dofs[b]], axis=1),
        matrix=np.concatenate([grains.matrix[a], -grains.matrix[b]], axis=2),
        origin=grains.origin[a] - grains.origin[b],
        weight=grains.gap_weight,
    )


def gap_candidates(system: AssembledSystem, u: np.ndarray, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """Pairs of grains not in contact through an element whose centres are closer than
    ``1 + reach`` (a k-d tree, not all pairs), and their gaps (distance - 1)."""
    from scipy.spatial import cKDTree

    grains = system.grains
    if grains is None:
        return np.zeros((0, 2), dtype=np.intp), np.zeros(0)
    X = grains.at(u)
    pairs = cKDTree(X).query_pairs(1.0 + reach, output_type="ndarray")
    if pairs.size == 0:
        return np.zeros((0, 2), dtype=np.intp), np.zeros(0)
    pairs = np.sort(pairs, axis=1)
    neighbours = np.sort(grains.neighbours, axis=1)
    g = len(X)
    keep = ~np.isin(pairs[:, 0] * g + pairs[:, 1], neighbours[:, 0] * g + neighbours[:, 1])
    pairs = pairs[keep]
    pairs = pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]
    return pairs, np.linalg.norm(X[pairs[:, 0]] - X[pairs[:, 1]], axis=1) - 1.0


def assemble(
    system: AssembledSystem,
    law: Any,
    parameters: dict[str, float],
    u: np.ndarray,
    internal: dict[str, np.ndarray],
    load: float = 0.0,
    closed: np.ndarray | None = None,
    kappa: float = 1.0,
    dense: bool | None = None,
) -> AssembledState:
    """R, K and the members' variables of ``system`` at ``u`` (see the module docstring).

    Parameters
    ----------
    system
        The system.
    law
        The contact law (for a system with contacts); springs carry their own.
    parameters
        The case's law parameters (``gamma``); each contact's ``alpha0`` is the system's.
    u : (n,)
        The dofs.
    internal
        Per family name, the stored forces ``(m, forces)`` whose columns of internal
        variables (a rate law's) are used.
    load
        The load parameter P.
    closed : (p, 2) or None
        Grain pairs whose secondary contact is closed (a spring acts).
    kappa
        Stiffness ratio of secondary contacts.
    dense
        Dense arrays, or CSR (default: dense up to 64 dofs).
    """
    n = system.n_dof
    dense = n <= 64 if dense is None else dense
    R = np.zeros(n)
    dofs_parts, block_parts = [], []
    members: dict[str, dict[str, np.ndarray]] = {}
    if system.contacts is not None:
        elements = system.contacts
        values = {**parameters, "alpha0": system.contact_alpha0}
        q, f, J, C, forces, blocks = _family(elements.kinematics(u), law_response(law), elements.weight,
                                             values, internal["contacts"], n, dense)
        members["contacts"] = {"q": q, "f": f, "J": J, "C": C, "dofs": elements.dofs}
        np.add.at(R, elements.dofs, forces)
        dofs_parts.append(elements.dofs)
        block_parts.append(blocks)
    if system.springs is not None:
        elements = system.springs
        q, f, J, C, forces, blocks = _family(elements.kinematics(u), law_response(system.spring_law), elements.weight,
                                             parameters, internal["springs"], n, dense)
        members["springs"] = {"q": q, "f": f, "J": J, "C": C, "dofs": elements.dofs}
        np.add.at(R, elements.dofs, forces)
        dofs_parts.append(elements.dofs)
        block_parts.append(blocks)
    dR_dload = np.zeros(n)
    if system.axial_load is not None:
        bars = system.axial_load
        _, vector, stiffness, _ = shortening(bars.rise_dofs, bars.rise_signs, u, bars.lengths)
        np.add.at(dR_dload, bars.rise_dofs, -vector)
        R += load * dR_dload
        dofs_parts.append(bars.rise_dofs)
        block_parts.append(-load * stiffness)
    if system.tip_load is not None:
        vector, pairs, blocks = tip_load_terms(system.tip_load, u)
        np.add.at(dR_dload, system.tip_load.dofs, -vector)
        R += load * dR_dload
        dofs_parts.append(pairs)
        block_parts.append(-load * blocks)
    gaps = np.zeros(0)
    if closed is not None and len(closed):
        dofs, g, forces, blocks = gap_springs(system, closed, u, kappa)
        np.add.at(R, dofs, forces)
        dofs_parts.append(dofs)
        block_parts.append(blocks)
        gaps = g
    K = None
    for dofs, blocks in zip(dofs_parts, block_parts):
        part = _scatter(n, dofs, blocks, dense)
        K = part if K is None else K + part
    if not dense:
        K = K.tocsr()
    return AssembledState(R, K, dR_dload, members, gaps)


def energy_forms(
    system: AssembledSystem,
    law: Any,
    parameters: dict[str, float],
    u: np.ndarray,
    internal: dict[str, np.ndarray],
    left: np.ndarray,
    right: np.ndarray,
    closed: np.ndarray | None = None,
    kappa: float = 1.0,
) -> tuple[float, float]:
    """psi^T K_int phi and psi^T K_load phi (K = K_int - P K_load), element by element.

    Each member contributes w [(J psi_e)^T D (J phi_e) + sum_c Q_c psi_e^T H_c phi_e]
    and each bar cos(theta)^-3 (a . psi)(a . phi) (a tip load: psi^T dQ_ext/du phi over its
    blocks), computed from J phi_e and a . phi directly: no cancellation between the entries of an assembled K (a column of
    1,000 links has entries of order 6 and a critical eigenvalue of order 1e-10).
    Their ratio is the two-sided Rayleigh quotient of the pencil, stationary at
    the critical load (:func:`ncstab.paths.assembled_path.refine_critical_load`).
    """
    inner, outer = 0.0, 0.0
    for dofs, J, H, Q, D, w in member_responses(system, law, parameters, u, internal):
        a, b = np.einsum("mkl,ml->mk", J, left[dofs]), np.einsum("mkl,ml->mk", J, right[dofs])
        curvature = np.einsum("mkab,ma,mb->mk", H, left[dofs], right[dofs])
        member = np.einsum("mk,mkp,mp->m", a, D, b) + np.sum(Q * curvature, axis=1)
        inner += float(np.sum(w * member))
    if closed is not None and len(closed):  # each spring's own block, contracted: no assembled sum
        dofs, _, _, blocks = gap_springs(system, closed, u, kappa)
        inner += float(np.einsum("ma,mab,mb->", left[dofs], blocks, right[dofs]))
    if system.axial_load is not None:
        bars = system.axial_load
        r = np.einsum("bk,bk->b", bars.rise_signs, u[bars.rise_dofs])
        a = np.einsum("bk,bk->b", bars.rise_signs, left[bars.rise_dofs])
        b = np.einsum("bk,bk->b", bars.rise_signs, right[bars.rise_dofs])
        length = 1.0 if bars.lengths is None else bars.lengths
        outer += float(np.sum(length * (1.0 - r * r) ** -1.5 * a * b))
    if system.tip_load is not None:  # psi^T (dQ_ext/du) phi, block by block
        _, pairs, blocks = tip_load_terms(system.tip_load, u)
        outer += float(np.einsum("ma,mab,mb->", left[pairs], blocks, right[pairs]))
    return inner, outer
