"""Mesostructures of packings (issue 38): grain loops, each loop's Hill eigenvalue as a ring, force chains,
and the figures (drawn, not judged: they must build at any size from collections)."""

from __future__ import annotations

import numpy as np

from ncstab.laws.registry import law_definition
from ncstab.operators.packing_analysis import packing_tangent
from ncstab.systems.mesostructures import force_chains, grain_loops, loop_stiffness, loop_table
from ncstab.systems.packing import Packing, triangular_lattice


def _holed(seed: int = 0) -> Packing:
    """A 7 x 8 lattice with a fifth of its contacts removed and two rattlers' worth of dangling contacts:
    loops of several lengths, bridges and trees."""
    lattice = triangular_lattice(7, 8, fix_bottom=True, jitter=0.05, seed=seed)
    keep = np.random.default_rng(seed).random(lattice.n_contacts) > 0.2
    contacts = lattice.contacts[keep]
    rng = np.random.default_rng(seed + 1)
    return Packing(lattice.x, lattice.y, lattice.radius, lattice.fixed, contacts,
                   rng.uniform(0.005, 0.03, len(contacts)), rng.uniform(-0.005, 0.005, len(contacts)))


def test_faces_are_a_cycle_basis_as_short_as_networkx_minimum_cycle_basis_on_a_lattice() -> None:
    """Faces: as many loops as the cycle rank, each a closed walk along contacts; on a lattice the same
    lengths as networkx's minimum cycle basis, elsewhere at least its total length (a minimum basis may
    prefer a 7-cycle through two faces to an 8-grain face)."""
    import networkx as nx

    lattice = triangular_lattice(5, 6, jitter=0.1)
    assert sorted(grain_loops(lattice).lengths) == sorted(grain_loops(lattice, method="networkx").lengths)

    for seed in range(3):
        packing = _holed(seed)
        faces = grain_loops(packing)
        exact = grain_loops(packing, method="networkx")
        graph = nx.Graph(packing.contacts.tolist())
        rank = graph.number_of_edges() - graph.number_of_nodes() + nx.number_connected_components(graph)
        assert faces.count == exact.count == rank
        assert faces.lengths.sum() >= exact.lengths.sum()
        # every loop is a closed walk along contacts: consecutive grains are the ends of the listed contact
        for k in range(faces.count):
            grains, contacts = faces.loop(k), faces.contacts[faces.offsets[k]:faces.offsets[k + 1]]
            pairs = {frozenset(p) for p in packing.contacts[contacts].tolist()}
            assert pairs == {frozenset((grains[i], grains[(i + 1) % len(grains)])) for i in range(len(grains))}


def test_a_loops_hill_eigenvalue_equals_the_ring_taken_out_and_analysed_densely() -> None:
    """The batched ring stiffness against packing_tangent of the ring as its own packing (all grains free),
    projected on the complement of its rigid motions, by numpy's eigh: 1e-10 (rounding of O(1) sums)."""
    packing = _holed(1)
    law = law_definition("cundall_strack")
    loops = grain_loops(packing)
    hill = loop_stiffness(packing, loops, packing_tangent(packing, law, 0.6).blocks)
    for k in np.argsort(hill)[:3].tolist() + [int(np.argmax(loops.lengths))]:
        grains = loops.loop(k)
        contacts = loops.contacts[loops.offsets[k]:loops.offsets[k + 1]]
        local = {g: i for i, g in enumerate(grains)}
        ring = Packing(packing.x[grains], packing.y[grains], packing.radius[grains], np.zeros(len(grains), bool),
                       np.array([[local[a], local[b]] for a, b in packing.contacts[contacts]]),
                       packing.normal_force[contacts], packing.tangential_force[contacts])
        K = packing_tangent(ring, law, 0.6).K.toarray()
        X = np.column_stack([ring.x - ring.x.mean(), ring.y - ring.y.mean()])
        rigid = np.zeros((3 * len(grains), 3))
        rigid[0::3, 0] = rigid[1::3, 1] = 1
        rigid[0::3, 2], rigid[1::3, 2], rigid[2::3, 2] = -X[:, 1], X[:, 0], 1
        basis = np.linalg.svd(rigid, full_matrices=True)[0][:, 3:]
        expected = np.linalg.eigvalsh(basis.T @ (K + K.T) / 2 @ basis)[0]
        assert abs(hill[k] - expected) <= 1e-10
    table = loop_table(loops, hill, 5)
    assert [row["hill"] for row in table] == sorted(hill)[:5]


def test_a_ring_that_carries_a_large_compression_loses_hills_condition() -> None:
    """Hill's eigenvalue of a loop decreases with its compression (the geometric term -N/l), and is lost
    past some load: a triangle of the lattice under growing N."""
    packing = triangular_lattice(2, 2)
    law = law_definition("mcnamara")
    values = []
    for N in (0.0, 0.2, 0.6):
        loaded = packing.with_forces(np.full(packing.n_contacts, N), np.zeros(packing.n_contacts))
        loops = grain_loops(loaded)
        values.append(loop_stiffness(loaded, loops, packing_tangent(loaded, law, 0.05).blocks).min())
    assert values[0] > values[1] > values[2] and values[0] > 0 > values[2]


def test_force_chains_follow_the_major_principal_stress() -> None:
    """A square packing of 9 x 9 disks whose column x = 4 carries N = 1 and every other contact N = 0.01:
    the column is the one chain; its inner grains have sigma = 2 r N / (pi r^2) e_y (x) e_y along y exactly
    (the lateral contacts load sigma_xx only)."""
    from ncstab.systems.packing import contacts_from_geometry

    i, j = np.divmod(np.arange(81), 9)
    x, y, r = j.astype(float), i.astype(float), np.full(81, 0.5)
    contacts = contacts_from_geometry(x, y, r)
    a, b = contacts.T
    vertical = (x[a] == 4) & (x[b] == 4)
    packing = Packing(x, y, r, np.zeros(81, bool), contacts, np.where(vertical, 1.0, 0.01), np.zeros(len(a)))
    chains = force_chains(packing)
    assert np.array_equal(np.flatnonzero(chains.chain >= 0), np.flatnonzero(x == 4))
    assert len(np.unique(chains.chain[x == 4])) == 1
    inner = np.flatnonzero((x == 4) & (y > 0) & (y < 8))
    assert np.allclose(chains.major[inner], 2 * 0.5 * 1.0 / (np.pi * 0.25), atol=1e-12)
    assert np.allclose(np.abs(chains.direction[inner, 1]), 1.0, atol=1e-12)
    assert np.array_equal(np.sort(chains.links), np.flatnonzero(vertical))


def test_figures_draw_from_an_archive(tmp_path) -> None:
    import ncstab
    from ncstab.plotting.packing import draw_packing_figures

    packing = _holed(2)
    dataset = ncstab.analyse(packing, "cundall_strack", 0.5, modes=2)
    paths = draw_packing_figures(dataset, tmp_path, stem="holed")
    assert [p.name for p in paths] == ["holed_forces.png", "holed_mode.png", "holed_loops.png"]
    assert all(p.stat().st_size > 10_000 for p in paths)
