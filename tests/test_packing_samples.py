"""Laboratory samples (issue 57): every archive names its dofs, rattlers, the Love-Weber stress.

- ``dof_name`` is ``Packing.dof_names()`` of the analysed packing, in K's order (exact strings).
- Rattlers against an independent recursive count: the networkx 2-core of the force-carrying
  contact graph, the held grains kept by two anchor nodes joined to each of them (exact sets).
  Without rattlers, K is exactly (0 difference: the same sums in the same order) the K of the
  packing rebuilt in the test with the rattler grains deleted and the grains renumbered.
- ``stress`` against a Love-Weber sum written here contact by contact (1e-14 relative: a sum of
  O(100) terms of size O(0.1)), and against the closed form of a triangular lattice under a
  uniform N (counts of contacts per direction; 1e-14).
"""

from __future__ import annotations

import networkx as nx
import numpy as np
import xarray as xr

from ncstab.analyse_command import analyse
from ncstab.cli import main
from ncstab.laws.registry import law_definition
from ncstab.operators.packing_analysis import packing_tangent
from ncstab.operators.packing_stress import love_weber_stress
from ncstab.operators.rattlers import RATTLER_TOLERANCE, rattler_mask
from ncstab.systems.packing import Packing, triangular_lattice, write_packing


def _sparse_forces(rows: int, columns: int, seed: int, zero_share: float = 0.45) -> Packing:
    """A lattice (bottom row held) where a share of the contacts carries no force (N = 0 or 1e-13 N_max)."""
    packing = triangular_lattice(rows, columns, fix_bottom=True, jitter=0.05, seed=seed)
    rng = np.random.default_rng(seed)
    N = rng.uniform(0.01, 0.05, packing.n_contacts)
    off = rng.random(packing.n_contacts) < zero_share
    N[off] = np.where(rng.random(off.sum()) < 0.5, 0.0, 1e-13 * N.max())  # below the tolerance: not carrying
    return packing.with_forces(N, rng.uniform(-0.005, 0.005, packing.n_contacts))


def _two_core_rattlers(packing: Packing) -> np.ndarray:
    """Independent: free grains outside the 2-core of the carrying graph, held grains anchored."""
    graph = nx.Graph()
    graph.add_nodes_from(range(packing.n_grains))
    carrying = packing.normal_force > RATTLER_TOLERANCE * packing.normal_force.max()
    graph.add_edges_from(map(tuple, packing.contacts[carrying].tolist()))
    graph.add_edge("anchor_1", "anchor_2")
    for grain in np.flatnonzero(packing.fixed):
        graph.add_edge("anchor_1", int(grain))
        graph.add_edge("anchor_2", int(grain))
    core = set(nx.k_core(graph, 2).nodes)
    return np.array([i not in core for i in range(packing.n_grains)])


def test_rattlers_are_the_grains_outside_the_two_core_of_the_carrying_graph() -> None:
    deep = 0
    for seed in range(8):
        packing = _sparse_forces(7, 8, seed)
        found = rattler_mask(packing)
        assert np.array_equal(found, _two_core_rattlers(packing)), seed
        assert not found[packing.fixed].any()
        count = np.bincount(packing.contacts[packing.normal_force > RATTLER_TOLERANCE * packing.normal_force.max()]
                            .ravel(), minlength=packing.n_grains)
        deep += int(np.sum(found & (count >= 2)))  # rattlers only found by recursion
    assert deep > 0  # the recursion was exercised
    unloaded = triangular_lattice(3, 3)
    assert not rattler_mask(unloaded).any()  # no compressed contact: no rattler by this rule


def test_the_analysis_leaves_the_rattlers_out_of_K_unless_kept(tmp_path, monkeypatch, capsys) -> None:
    packing = _sparse_forces(6, 7, 3)
    rattler = _two_core_rattlers(packing)
    assert rattler.any()
    law = law_definition("cundall_strack")
    ds = analyse(packing, law, 0.5, modes=2)
    assert int(ds.rattlers) == rattler.sum() and np.array_equal(ds.rattler.values.astype(bool), rattler)
    assert np.array_equal(ds.fixed.values.astype(bool), packing.fixed)  # as given
    # the packing rebuilt without the rattler grains, grains renumbered
    kept = np.flatnonzero(~rattler)
    renumber = np.full(packing.n_grains, -1)
    renumber[kept] = np.arange(len(kept))
    contacts = ~(rattler[packing.contacts[:, 0]] | rattler[packing.contacts[:, 1]])
    rebuilt = Packing(packing.x[kept], packing.y[kept], packing.radius[kept], packing.fixed[kept],
                      renumber[packing.contacts[contacts]], packing.normal_force[contacts],
                      packing.tangential_force[contacts])
    expected = packing_tangent(rebuilt, law, 0.5).K.toarray()
    n = ds.sizes["dof"]
    K = np.zeros((n, n))
    np.add.at(K, (ds.K_row.values, ds.K_col.values), ds.K_value.values)
    assert np.array_equal(K, expected)
    names = [f"{c}{kept[i]}" for i in range(len(kept)) if not rebuilt.fixed[i] for c in ("x", "y", "theta")]
    assert list(ds.dof_name.values) == names  # the rattlers' dofs are gone, the others in K's order
    monkeypatch.chdir(tmp_path)
    write_packing(packing, tmp_path / "p.nc")
    assert main(["analyse", "p.nc", "--law", "cundall_strack", "--gamma", "0.5", "--keep-rattlers", "-o",
                 "kept.nc"]) == 0
    assert f"rattlers = {rattler.sum()} (kept)" in capsys.readouterr().out
    with xr.open_dataset(tmp_path / "kept.nc") as kept_ds:
        assert list(kept_ds.dof_name.values) == packing.dof_names()
        assert int(kept_ds.rattlers) == rattler.sum() and kept_ds.rattler.attrs["kept"] == 1
        for name in ("dof_name", "rattler", "rattlers", "stress"):
            assert {"units", "long_name", "description"} <= set(kept_ds[name].attrs), name


def test_dof_name_is_in_K_order() -> None:
    packing = triangular_lattice(3, 4, fix_bottom=True)
    packing = packing.with_forces(np.full(packing.n_contacts, 0.01), np.zeros(packing.n_contacts))
    ds = analyse(packing, "mcnamara", 1.0, modes=2)
    assert list(ds.dof_name.values) == [f"{c}{i}" for i in range(4, 12) for c in ("x", "y", "theta")]
    assert ds.dof_name.dims == ("dof",) and list(ds.dof_grain.values) == [int(n.lstrip("xythea")) for n in
                                                                          ds.dof_name.values]


def test_stress_is_the_love_weber_sum() -> None:
    packing = _sparse_forces(5, 6, 1)
    expected = np.zeros((2, 2))
    for (a, b), N, T in zip(packing.contacts, packing.normal_force, packing.tangential_force):
        l = np.array([packing.x[b] - packing.x[a], packing.y[b] - packing.y[a]])
        angle = np.arctan2(l[1], l[0])
        n, t = np.array([np.cos(angle), np.sin(angle)]), np.array([-np.sin(angle), np.cos(angle)])
        expected += np.outer(N * n - T * t, l)
    r = packing.radius
    volume = (max(packing.x + r) - min(packing.x - r)) * (max(packing.y + r) - min(packing.y - r))
    result = love_weber_stress(packing)
    assert abs(result.volume - volume) <= 1e-14 * volume
    assert np.allclose(result.stress, expected / volume, rtol=0, atol=1e-14 * np.abs(expected / volume).max())
    ds = analyse(packing, "mcnamara", 1.0, modes=2)
    assert np.array_equal(ds.stress.values, result.stress) and ds.stress.attrs["volume"] == result.volume
    assert "bounding box" in ds.stress.attrs["volume_rule"]


def test_stress_of_a_triangular_lattice_under_uniform_compression() -> None:
    """sigma = (N/V) sum over directions count m m^T; counts from the lattice (offset rows every other row)."""
    N, rows, columns = 0.02, 5, 6
    packing = triangular_lattice(rows, columns)
    packing = packing.with_forces(np.full(packing.n_contacts, N), np.zeros(packing.n_contacts))
    horizontal = rows * (columns - 1)
    pairs = np.arange(rows - 1)
    up60 = int(np.sum(np.where(pairs % 2 == 0, columns, columns - 1)))  # dx = +1/2
    up120 = int(np.sum(np.where(pairs % 2 == 0, columns - 1, columns)))  # dx = -1/2
    assert horizontal + up60 + up120 == packing.n_contacts
    volume = (columns + 0.5) * ((rows - 1) * np.sqrt(3) / 2 + 1)
    m60, m120 = np.array([0.5, np.sqrt(3) / 2]), np.array([-0.5, np.sqrt(3) / 2])
    closed = N / volume * (horizontal * np.diag([1.0, 0.0]) + up60 * np.outer(m60, m60) + up120 * np.outer(m120, m120))
    result = love_weber_stress(packing)
    assert np.allclose(result.stress, closed, rtol=0, atol=1e-14 * N)
    assert result.stress[0, 0] > 0 and result.stress[1, 1] > 0  # compression positive


def test_a_packing_of_rattlers_only_is_exit_2_pointing_at_keep_rattlers(tmp_path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    packing = Packing(np.array([0.0, 0.0]), np.array([0.0, 1.0]), np.full(2, 0.5), np.array([True, False]),
                      np.array([[0, 1]]), np.array([0.01]), np.array([0.0]))
    write_packing(packing, tmp_path / "p.nc")
    assert main(["analyse", "p.nc", "--law", "mcnamara"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "every free grain is a rattler" in err and "--keep-rattlers" in err
    assert not (tmp_path / "results").exists()
    assert main(["analyse", "p.nc", "--law", "mcnamara", "--keep-rattlers"]) == 0
