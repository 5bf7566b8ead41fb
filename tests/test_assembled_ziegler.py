"""Ziegler's pendulum as an assembled system, and its chain of n bars (the discretised Beck column).

The assembled chain (:mod:`ncstab.systems.assembled_chain`) against the derived
``ziegler`` (sympy, compiled) at two bars, against Ziegler's closed forms, and against
Beck's flutter load as the chain grows.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from ncstab.cli import main
from ncstab.operators.assembly import assemble
from ncstab.paths import SystemSpec, follow
from ncstab.paths.api import case_batch, resolve_model
from ncstab.paths.grid import ParameterGrid
from ncstab.systems.assembled import is_assembled
from ncstab.systems.assembled_chain import assembled_ziegler
from ncstab.systems.registry import system_definition

ZIEGLER_FLUTTER = 3.5 - math.sqrt(2)  # undamped follower load, m1 = 2, m2 = 1 (Ziegler 1952)
# dead load, straight state: K = [[2 - P, -1], [-1, 1 - P]], det K = P^2 - 3P + 1 = 0
DEAD_BUCKLING = (3 - math.sqrt(5)) / 2
#: Beck's column (Beck 1952): a cantilever of uniform mass under a follower tip load flutters at
#: P L^2 / EI = 20.05 (20.0509..., Bolotin 1963).
BECK = 20.05

CASES = [("follower", {}), ("dead", {}), ("follower", {"b1": 0.3, "b2": 0.7}), ("dead", {"m1": 1.5, "m2": 0.4, "b1": 0.2, "b2": 0.1})]


def _derived(load: str, parameters: dict):
    """The derived ziegler's compiled evaluation (the batch tests/test_models.py evaluates)."""
    grid = ParameterGrid.from_mapping(parameters)
    model = resolve_model(SystemSpec("ziegler", load=load))
    return case_batch(model.laws[0], model, grid.case_values(), grid.size)


def _assembled_state(system, u: np.ndarray, P: float):
    return assemble(system, None, {}, u, {"springs": np.zeros((system.springs.size, 1))}, load=P)


@pytest.mark.parametrize("load, parameters", CASES, ids=["follower", "dead", "follower-damped", "dead-damped"])
def test_two_bars_equal_the_derived_ziegler(load, parameters):
    """R, K, dR/dP, M and C of the assembled pendulum at 6 random states equal the derived system's
    compiled kernel (tests/test_models.py) to 1e-12: the same closed forms, evaluated by two codes
    (their difference is rounding, ~1e-15)."""
    system = assembled_ziegler(2, load).for_values({**parameters})
    batch = _derived(load, parameters)
    rng = np.random.default_rng(37)
    u = rng.uniform(-0.6, 0.6, size=(6, 2))
    P = rng.uniform(0.0, 3.0, size=6)
    derived = batch.take(np.zeros(6, dtype=int)).evaluate(u, np.zeros((6, 0)), load=P)
    for k in range(6):
        state = _assembled_state(system, u[k], P[k])
        np.testing.assert_allclose(state.R, derived.forces[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(state.K, derived.stiffness[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(state.dR_dload, derived.dF_dload[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(system.inertia.mass(u[k]), derived.mass[k], rtol=0, atol=1e-12)
        np.testing.assert_allclose(system.inertia.damping(), derived.damping[k], rtol=0, atol=1e-12)


@pytest.mark.parametrize("links", [2, 5])
@pytest.mark.parametrize("load", ["follower", "dead"])
def test_K_is_the_derivative_of_R(load, links):
    """K against central differences of R (h = 1e-6: truncation h^2 |R'''| ~ 1e-12, rounding
    1e-16 / 1e-6 = 1e-10; 1e-6 relative to max |K| with margin); the follower's K is not symmetric."""
    system = assembled_ziegler(links, load)
    u = np.random.default_rng(3).uniform(-0.5, 0.5, links)
    K = _assembled_state(system, u, 1.3).K
    h = 1e-6
    fd = np.empty_like(K)
    for j in range(links):
        e = np.zeros(links)
        e[j] = h
        fd[:, j] = (_assembled_state(system, u + e, 1.3).R - _assembled_state(system, u - e, 1.3).R) / (2 * h)
    np.testing.assert_allclose(K, fd, rtol=0, atol=1e-6 * np.abs(K).max())
    asymmetry = np.abs(K - K.T).max()
    assert asymmetry > 0.1 if load == "follower" else asymmetry < 1e-14


def test_the_chain_s_matrices_are_the_derived_chain_s():
    """Three bars: the derived chain (sympy, ``links = 3``, compiled) and the assembled one give
    the same R, K, dR/dP, M and C at random states (1e-12), masses m1 at the joints and m2 at the tip."""
    values = {"m1": 1.7, "m2": 0.6, "b1": 0.2, "b2": 0.45}
    for load in ("follower", "dead"):
        grid = ParameterGrid.from_mapping(values)
        model = resolve_model(SystemSpec("ziegler", load=load, links=3))
        batch = case_batch(model.laws[0], model, grid.case_values(), grid.size).take(np.zeros(4, dtype=int))
        system = assembled_ziegler(3, load).for_values(values)
        rng = np.random.default_rng(8)
        u, P = rng.uniform(-0.4, 0.4, size=(4, 3)), rng.uniform(0.0, 2.0, size=4)
        derived = batch.evaluate(u, np.zeros((4, 0)), load=P)
        for k in range(4):
            state = _assembled_state(system, u[k], P[k])
            np.testing.assert_allclose(state.R, derived.forces[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(state.K, derived.stiffness[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(state.dR_dload, derived.dF_dload[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(system.inertia.mass(u[k]), derived.mass[k], rtol=0, atol=1e-12)
            np.testing.assert_allclose(system.inertia.damping(), derived.damping[k], rtol=0, atol=1e-12)


def _loads(ds) -> dict[str, float]:
    return {k[: -len("_load")]: float(ds[k].item()) for k in ds.data_vars if k.endswith("_load")}


def test_the_sparse_engine_locates_ziegler_s_flutter_load():
    """Undamped follower load, m = (2, 1): flutter_onset at 7/2 - sqrt 2 (Ziegler's closed form,
    det(M s^2 + K) = 2 s^4 + (7 - 2P) s^2 + 1 has a double root s^2 where (7 - 2P)^2 = 8) to 1e-8
    (measured 2e-13: the onset's level moves it by (1e-7)^2), at the frequency 2^(-1/4); det K = 1:
    no divergence."""
    ds = follow(assembled_ziegler(2, "follower"), None, [{"drive": {"P": 3.0}}]).to_dataset()
    assert str(ds["status"].item()) == "finished"
    assert abs(float(ds["flutter_onset_load"].item()) - ZIEGLER_FLUTTER) <= 1e-8
    assert abs(float(ds["flutter_onset_frequency"].item()) - 2 ** -0.25) <= 1e-6
    assert np.isnan(float(ds["divergence_load"].item()))
    n = int(ds["n_steps"].item())
    P, growth = ds["load"].values[0, :n], ds["flutter"].values[0, :n]
    assert np.all(np.abs(growth[P < ZIEGLER_FLUTTER - 1e-6]) < 1e-12) and np.all(growth[P > ZIEGLER_FLUTTER + 1e-6] > 0)


def test_the_sparse_engine_locates_the_dead_load_s_divergence():
    """Dead load: divergence (det K = P^2 - 3P + 1 = 0 on the straight state) at (3 - sqrt 5)/2
    to 1e-8 (measured 3e-14), with the bifurcation there; no flutter (the roots mu = s^2 stay real)."""
    ds = follow(assembled_ziegler(2, "dead"), None, [{"drive": {"P": 1.0}}]).to_dataset()
    loads = _loads(ds)
    assert abs(loads["divergence"] - DEAD_BUCKLING) <= 1e-8
    assert abs(loads["bifurcation"] - DEAD_BUCKLING) <= 1e-8
    assert np.isnan(loads["flutter_onset"])


@pytest.mark.parametrize("load, parameters, P", [("follower", {}, 3.0), ("dead", {}, 1.0),
                                                 ("follower", {"b1": 0.1, "b2": 0.1}, 3.0),
                                                 ("follower", {"b1": 1e-5, "b2": 1e-5}, 2.5)],
                         ids=["follower", "dead", "damped", "paradox"])
def test_both_routes_find_the_same_events_at_the_same_loads(load, parameters, P):
    """The same programme through ``follow`` on the derived route (compiled loop) and on the
    assembled one (sparse engine): the same events, at the same loads to 1e-8 (each located to
    1e-10 of a step by its engine; measured below 1e-11).  Damped: the derived route locates the
    Hurwitz determinant's zero, the sparse engine the root's Re s = 0; the paradox's b = 1e-5
    flutters at 41/28, far below the undamped 2.086."""
    programme = [{"drive": {"P": P}}]
    derived = _loads(follow(SystemSpec("ziegler", load=load), None, programme, parameters).to_dataset())
    assembled = _loads(follow(assembled_ziegler(2, load), None, programme, parameters).to_dataset())
    assert {k for k, v in derived.items() if np.isfinite(v)} == {k for k, v in assembled.items() if np.isfinite(v)}
    for event, value in derived.items():
        if np.isfinite(value):
            assert abs(assembled[event] - value) <= 1e-8, event


def _chain_flutter(links: int) -> float:
    ds = follow(SystemSpec("ziegler", links=links), None,
                [{"drive": {"P": 25.0 / links**2}, "stop_at": ["flutter_onset"]}]).to_dataset()
    assert str(ds["status"].item()) == "stopped:flutter_onset"
    return float(ds["flutter_onset_load"].item())


def test_a_long_chain_flutters_at_beck_s_load():
    """The chain of n bars of length l, springs k, masses 2 at the joints and 1 at the tip is Beck's
    column of length L = n l, EI = k l and uniform mass: P_n n^2 (= P L^2 / EI) tends to 20.05.
    Measured: 18.9587 at 20 bars, 19.5257 at 40 (an O(1/n) error, 21/n); the Richardson
    extrapolation 2 P_40 (40)^2 - P_20 (20)^2 = 20.093 is within 0.3 % of Beck's (tolerance 1 %),
    and each value is within 6 % (20 bars) and 3 % (40 bars) below it."""
    twenty, forty = _chain_flutter(20) * 20**2, _chain_flutter(40) * 40**2
    assert twenty < forty < BECK
    assert abs(twenty - BECK) <= 0.06 * BECK and abs(forty - BECK) <= 0.03 * BECK
    assert abs(2 * forty - twenty - BECK) <= 0.01 * BECK


def test_the_registry_hands_a_long_chain_to_the_sparse_engine():
    assert not is_assembled(system_definition("ziegler", (("links", 8), ("load", "follower"))))
    chain = system_definition("ziegler", (("links", 9), ("load", "dead")))
    assert is_assembled(chain) and chain.dofs[-1] == "phi9" and chain.load.kind == "dead"
    two = system_definition("ziegler", (("links", 2), ("load", "follower")))
    assert two.dofs == ("phi1", "phi2") and [p.name for p in two.parameters] == ["m1", "m2", "b1", "b2"]


STUDY = """\
[study]
name = "ziegler_chain"
[system]
name = "ziegler"
links = 12
masses = [2.0, 1.0]
[[loading]]
drive = {{ P = 0.3 }}
{extra}
[output]
figures = []
"""


def test_a_study_of_twelve_bars_writes_its_flutter_load(tmp_path):
    """``links = 12`` through ``ncstab run``: the archive's flutter_onset_load is the sparse engine's
    (0.12606 k/l: 18.15 = P n^2, between 8.34 at two bars and 18.96 at 20)."""
    import xarray as xr

    study = tmp_path / "chain.toml"
    study.write_text(STUDY.format(extra=""))
    assert main(["run", str(study), "-o", str(tmp_path / "chain.nc")]) == 0
    with xr.open_dataset(tmp_path / "chain.nc") as ds:
        P = float(ds["flutter_onset_load"].values.reshape(-1)[0])
        assert "sparse engine" in ds.attrs["engine"]
    assert 0.12 < P < 0.13 and 17.5 < P * 144 < 18.96


def test_a_dynamic_stage_on_a_long_chain_is_refused(tmp_path, capsys):
    study = tmp_path / "chain.toml"
    study.write_text(STUDY.format(extra="[[loading]]\ndynamic = { duration = 1.0, perturbation = { phi1 = 1e-6 } }"))
    assert main(["run", str(study), "-o", str(tmp_path / "chain.nc")]) == 2
    assert "assembled from elements" in capsys.readouterr().err
