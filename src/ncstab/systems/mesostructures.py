"""Mesostructures of a packing: grain loops with their own Hill eigenvalue, and force chains.

*Grain loops* are the cycles of the contact graph (grains as nodes, contacts as
edges).  :func:`grain_loops` returns a cycle basis: the bounded faces of the
contact network drawn with straight branches (a planar drawing for disks, whose
branches cannot cross), found for every half-edge at once (the next half-edge
of a face is the one after the twin in clockwise order around the grain), after
grains and contacts that lie on no cycle (the 2-core, less the bridges) are
removed.  Their number is the cycle rank c - g + components (Euler).  On small
packings, ``method="networkx"`` gives ``networkx.minimum_cycle_basis`` instead
(seconds for a few hundred grains; the faces are used at 10,000).  Both have
the cycle rank's count; the faces are the packing's own loops (the voids
between grains) and on a lattice have the minimum basis's lengths, but they
are not always a minimum basis (where one long face borders a short one, the
minimum basis may prefer a shorter cycle around both).

*A loop as a ring* (:func:`loop_stiffness`): the loop's grains, all free, and
the loop's own contacts, with the packing's forces and law: its K is the sum of
those contacts' blocks rho^2 (J^T D J + Q H) (:mod:`ncstab.operators.packing_analysis`),
the seed's ring of grains taken out of the packing.  Its Hill eigenvalue is the
smallest eigenvalue of K_sym on the deformations of the ring: the complement of
its two translations and its rotation about its centroid (the rigid motions of
a free ring, null or, under unbalanced forces, nearly null).  Loops are ranked by
it: :func:`loop_table` lists first those that lose Hill's condition first.

*Force chains* (:func:`force_chains`, after Peters et al. 2005): the stress of
grain g is sigma_g = -sum_c x_c (x) f_c / (pi r_g^2) over its contacts (x_c from
its centre to the contact point, f_c the force on g; compression positive, as
N), symmetrised; its major principal
stress s_g and direction e_g.  A grain is in a chain where s_g is above the mean
over grains; two chain grains in contact are linked where the branch is within
``angle`` of both grains' e; chains are the connected groups of at least three
grains.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import sparse
from scipy.sparse.csgraph import connected_components

from ncstab.systems.packing import Packing

__all__ = ["ForceChains", "GrainLoops", "force_chains", "grain_loops", "loop_stiffness", "loop_table"]


@dataclass(frozen=True)
class GrainLoops:
    """Grain loops: ``grains[offsets[k]:offsets[k + 1]]`` and ``contacts[...]`` are loop k's, in order."""

    grains: np.ndarray
    contacts: np.ndarray
    offsets: np.ndarray

    @property
    def count(self) -> int:
        return len(self.offsets) - 1

    @property
    def lengths(self) -> np.ndarray:
        return np.diff(self.offsets)

    def loop(self, k: int) -> np.ndarray:
        return self.grains[self.offsets[k]:self.offsets[k + 1]]

    def padded(self) -> np.ndarray:
        """``(loops, longest)`` grain indices, -1 past each loop's end."""
        out = np.full((self.count, int(self.lengths.max(initial=0))), -1, dtype=np.int64)
        rows = np.repeat(np.arange(self.count), self.lengths)
        cols = np.arange(len(self.grains)) - np.repeat(self.offsets[:-1], self.lengths)
        out[rows, cols] = self.grains
        return out


def _cyclic_contacts(packing: Packing) -> np.ndarray:
    """Indices of the contacts that lie on some cycle (not bridges, not in trees hanging off the network)."""
    import networkx as nx

    graph = nx.Graph()
    graph.add_edges_from((int(a), int(b), {"k": k}) for k, (a, b) in enumerate(packing.contacts))
    bridges = {frozenset(edge) for edge in nx.bridges(graph)}
    keep = np.array([frozenset((int(a), int(b))) not in bridges for a, b in packing.contacts], dtype=bool)
    return np.flatnonzero(keep) if len(keep) else np.zeros(0, dtype=np.intp)


def grain_loops(packing: Packing, method: str = "faces") -> GrainLoops:
    """The grain loops of ``packing`` (see the module docstring); ``method`` ``"faces"`` or ``"networkx"``."""
    if method == "networkx":
        return _networkx_loops(packing)
    if method != "faces":
        raise ValueError(f"method must be 'faces' or 'networkx', not {method!r}")
    kept = _cyclic_contacts(packing)
    if not len(kept):
        return GrainLoops(np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros(1, np.int64))
    edges = packing.contacts[kept]
    origin = np.concatenate([edges[:, 0], edges[:, 1]])
    target = np.concatenate([edges[:, 1], edges[:, 0]])
    contact = np.concatenate([kept, kept])
    m = len(edges)
    twin = np.concatenate([np.arange(m, 2 * m), np.arange(m)])
    angle = np.arctan2(packing.y[target] - packing.y[origin], packing.x[target] - packing.x[origin])
    order = np.lexsort((angle, origin))  # counter-clockwise around each grain
    rank = np.empty(2 * m, dtype=np.int64)
    rank[order] = np.arange(2 * m)
    first = np.searchsorted(origin[order], origin[order], side="left")
    count = np.bincount(origin, minlength=packing.n_grains)[origin[order]]
    # clockwise neighbour of h around its origin: the previous one in counter-clockwise order (cyclically)
    previous = np.empty(2 * m, dtype=np.int64)
    previous[order] = order[first + (np.arange(2 * m) - first - 1) % count]
    following = previous[twin]  # next half-edge of the face on the left of h
    graph = sparse.csr_matrix((np.ones(2 * m), (np.arange(2 * m), following)), shape=(2 * m, 2 * m))
    _, face = connected_components(graph, directed=True, connection="strong")
    x0, y0 = packing.x[origin], packing.y[origin]
    x1, y1 = packing.x[target], packing.y[target]
    area = np.bincount(face, 0.5 * (x0 * y1 - x1 * y0))
    bounded = area > 0
    # each face's half-edges in traversal order: walk `following` from each face's first half-edge
    keep = bounded[face]
    halves = np.flatnonzero(keep)
    sizes = np.bincount(face[halves], minlength=len(area))[bounded]
    starts = np.full(len(area), -1)
    starts[face[halves][::-1]] = halves[::-1]
    current = starts[bounded]
    steps = np.empty((int(sizes.max(initial=0)), len(current)), dtype=np.int64)
    for step in range(len(steps)):  # as many steps as the longest loop (a few tens), over all loops at once
        steps[step] = current
        current = following[current]
    valid = np.arange(len(steps))[:, None] < sizes[None, :]
    walk = steps.T[valid.T]
    offsets = np.concatenate([[0], np.cumsum(sizes)])
    return GrainLoops(origin[walk].astype(np.int64), contact[walk].astype(np.int64), offsets.astype(np.int64))


def _networkx_loops(packing: Packing) -> GrainLoops:
    import networkx as nx

    graph = nx.Graph()
    graph.add_edges_from((int(a), int(b)) for a, b in packing.contacts)
    index = {frozenset((int(a), int(b))): k for k, (a, b) in enumerate(packing.contacts)}
    grains, contacts, offsets = [], [], [0]
    for cycle in nx.minimum_cycle_basis(graph):
        ordered = _order_cycle(graph.subgraph(cycle))
        grains += ordered
        contacts += [index[frozenset((ordered[i], ordered[(i + 1) % len(ordered)]))] for i in range(len(ordered))]
        offsets.append(len(grains))
    return GrainLoops(np.array(grains, np.int64), np.array(contacts, np.int64), np.array(offsets, np.int64))


def _order_cycle(cycle) -> list[int]:
    start = min(cycle.nodes)
    ordered, previous = [start], None
    while len(ordered) < cycle.number_of_nodes():
        step = next(v for v in sorted(cycle.neighbors(ordered[-1])) if v != previous and v not in ordered[-1:])
        previous = ordered[-1]
        if step in ordered:
            break
        ordered.append(step)
    return ordered


def loop_stiffness(packing: Packing, loops: GrainLoops, blocks: np.ndarray):
    """Each loop's Hill eigenvalue as a ring (see the module docstring), ``(loops,)``.

    ``blocks`` are the contacts' (c, 6, 6) stiffness blocks
    (:attr:`~ncstab.operators.packing_analysis.PackingTangent.blocks`).  Loops of
    the same length are stacked and solved by one batched ``numpy.linalg.eigvalsh``.
    """
    hill = np.full(loops.count, np.nan)
    lengths = loops.lengths
    for L in np.unique(lengths):
        which = np.flatnonzero(lengths == L)
        grains = loops.grains[loops.offsets[which][:, None] + np.arange(L)]
        contacts = loops.contacts[loops.offsets[which][:, None] + np.arange(L)]
        # position of each contact's grains a, b in its loop
        a, b = packing.contacts[contacts, 0], packing.contacts[contacts, 1]
        pa = np.argmax(grains[:, :, None] == a[:, None, :], axis=1)
        pb = np.argmax(grains[:, :, None] == b[:, None, :], axis=1)
        dof = np.concatenate([3 * pa[..., None] + np.arange(3), 3 * pb[..., None] + np.arange(3)], axis=2)
        K = np.zeros((len(which), 3 * L, 3 * L))
        rows = np.repeat(dof, 6, axis=2)
        cols = np.tile(dof, (1, 1, 6))
        batch = np.broadcast_to(np.arange(len(which))[:, None, None], rows.shape)
        np.add.at(K, (batch, rows, cols), blocks[contacts].reshape(len(which), L, 36))
        X = np.stack([packing.x[grains], packing.y[grains]], axis=2)
        X = X - X.mean(axis=1, keepdims=True)
        rigid = np.zeros((len(which), 3 * L, 3))
        rigid[:, 0::3, 0] = 1.0
        rigid[:, 1::3, 1] = 1.0
        rigid[:, 0::3, 2], rigid[:, 1::3, 2], rigid[:, 2::3, 2] = -X[:, :, 1], X[:, :, 0], 1.0
        q, _ = np.linalg.qr(rigid, mode="complete")  # (batch, 3L, 3L): first 3 columns span the rigid motions
        basis = q[:, :, 3:]
        S = 0.5 * (K + np.swapaxes(K, 1, 2))
        reduced = np.swapaxes(basis, 1, 2) @ S @ basis
        hill[which] = np.linalg.eigvalsh(reduced)[:, 0]
    return hill


def loop_table(loops: GrainLoops, hill: np.ndarray, first: int | None = None) -> list[dict]:
    """The loops by increasing Hill eigenvalue (those that lose Hill's condition first come first)."""
    order = np.argsort(hill, kind="stable")[:first]
    return [{"loop": int(k), "length": int(loops.lengths[k]), "hill": float(hill[k]),
             "lost": bool(hill[k] < 0), "grains": loops.loop(k).tolist()} for k in order]


@dataclass(frozen=True)
class ForceChains:
    """Per grain: ``stress`` (g, 2, 2), ``major`` (g,) principal stress, ``direction`` (g, 2), ``chain`` (g,)
    the chain's index or -1; ``links`` the contacts that join chain grains."""

    stress: np.ndarray
    major: np.ndarray
    direction: np.ndarray
    chain: np.ndarray
    links: np.ndarray


def force_chains(packing: Packing, angle: float = np.pi / 4, minimum: int = 3) -> ForceChains:
    """Force chains by the major principal stress per grain (see the module docstring)."""
    a, b = packing.contacts[:, 0], packing.contacts[:, 1]
    d = np.column_stack([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
    n = d / np.linalg.norm(d, axis=1)[:, None]
    t = np.column_stack([-n[:, 1], n[:, 0]])
    on_b = packing.normal_force[:, None] * n - packing.tangential_force[:, None] * t
    stress = np.zeros((packing.n_grains, 2, 2))
    # compression positive (as N): sigma_g = -sum x_c (x) f_c / area, x_c = -r_b n for b (force on_b), r_a n for a
    np.add.at(stress, b, packing.radius[b, None, None] * n[:, :, None] * on_b[:, None, :])
    np.add.at(stress, a, packing.radius[a, None, None] * n[:, :, None] * on_b[:, None, :])
    stress /= (np.pi * packing.radius**2)[:, None, None]
    stress = 0.5 * (stress + np.swapaxes(stress, 1, 2))
    values, vectors = np.linalg.eigh(stress)
    major, direction = values[:, 1], vectors[:, :, 1]
    strong = major > major.mean()
    aligned = np.abs(np.einsum("ck,ck->c", n, direction[a])) >= np.cos(angle)
    aligned &= np.abs(np.einsum("ck,ck->c", n, direction[b])) >= np.cos(angle)
    links = np.flatnonzero(strong[a] & strong[b] & aligned)
    graph = sparse.csr_matrix((np.ones(len(links)), (a[links], b[links])), shape=(packing.n_grains,) * 2)
    _, label = connected_components(graph, directed=False)
    size = np.bincount(label)
    in_chain = (size[label] >= minimum)
    chain = np.full(packing.n_grains, -1)
    _, chain[in_chain] = np.unique(label[in_chain], return_inverse=True)
    links = links[in_chain[a[links]]]
    return ForceChains(stress, major, direction, chain, links)
