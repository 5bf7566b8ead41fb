"""General models: the unreduced diamond, rings, columns and Ziegler's pendulum as values.

Every expected number here comes from outside the model code: the seed's
reduced diamond (its own hand-written kinematics, :class:`DiamondChain`),
closed forms (Hencky's and Ziegler's critical loads), potentials written out
in the test and differentiated with sympy, or finite differences.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np
import pytest
import sympy as sp

import ncstab
from ncstab import DiamondChain, make_law
from ncstab.laws import law_definition
from ncstab.operators import generalized_forces
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.api import case_batch, resolve_model
from ncstab.paths.grid import ParameterGrid
from ncstab.systems import SystemDefinition, system_definition

SEED_LAWS = ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"]
HYPERELASTIC = ["mcnamara", "turco"]
TOTAL_FORMS = ["weakly_hypoelastic", "mcnamara", "turco"]

#: The preload-then-drive programme, reduced and on the four axes.
REDUCED = [
    {"hold": {"F1": 0.0}, "drive": {"F2": 0.3}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.4}},
]
AXES = [
    {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": 0.3, "F_right": 0.3}},
    {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.4, "D_bottom": 0.4}},
]


def _batch(spec: SystemSpec, law: str | None, parameters: dict):
    grid = ParameterGrid.from_mapping(parameters)
    model = resolve_model(spec, [law] if law else None)
    return case_batch(model.laws[0], model, grid.case_values(), grid.size)


# --- the unreduced diamond follows the reduced one ------------------------------------------------


@pytest.mark.parametrize("law", SEED_LAWS)
def test_the_axes_diamond_on_a_symmetric_programme_follows_the_reduced_path(law):
    """F_top = F1 at every D1 (ARCHITECTURE.md, the axes diamond).

    For a law with a total form, F_top at each stored state of the axes diamond
    is compared with the reduced diamond's forces evaluated at that state by
    its own kinematics (seed Eq. 1-4, :class:`DiamondChain`): 1e-9, the Newton
    projection's tolerance (1e-12) amplified by K (|K| < 10 here) with margin.
    For Cundall-Strack (T an internal variable) the end states are compared
    with the reduced path's, to 1e-8: both are integrated at rtol = 1e-10 over
    an arclength of about 1 (their error bound), in different coordinates.
    """
    gamma = 0.8
    axes = follow(SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), [law], AXES, {"gamma": gamma})
    reduced = follow(SystemSpec("diamond", secondary_contacts="ignore"), [law], REDUCED, {"gamma": gamma})
    a, r = axes.to_dataset(), reduced.to_dataset()
    assert str(a["status"].item()) == str(r["status"].item()) == "finished"
    n = int(a["n_steps"].item())
    u = a["u"].isel(law=0).values[:n]
    np.testing.assert_allclose(u[:, 0], u[:, 1], rtol=0, atol=1e-12)  # D_top = D_bottom
    np.testing.assert_allclose(u[:, 2], u[:, 3], rtol=0, atol=1e-12)  # D_left = D_right
    F = a["F"].isel(law=0).values[:n]
    if law in TOTAL_FORMS:
        reduced_forces = generalized_forces(
            DiamondChain(np.pi / 4), make_law(law, gamma=gamma, alpha0=np.pi / 4), u[:, [0, 2]]
        )
        np.testing.assert_allclose(F[:, 0], reduced_forces[:, 0], rtol=0, atol=1e-9)
        np.testing.assert_allclose(F[:, 2], reduced_forces[:, 1], rtol=0, atol=1e-9)
    m = int(r["n_steps"].item())
    np.testing.assert_allclose(u[-1, [0, 2]], r["u"].isel(law=0).values[m - 1], rtol=0, atol=1e-8)
    np.testing.assert_allclose(F[-1, [0, 2]], r["F"].isel(law=0).values[m - 1], rtol=0, atol=1e-8)
    # Every contact carries the reduced contact's forces (each its own internal variable for CS).
    for name in ("N", "T", "l", "alpha"):
        values = a[name].isel(law=0).values[n - 1]
        assert values.shape == (4,)
        np.testing.assert_allclose(values, r[name].isel(law=0).values[m - 1], rtol=0, atol=1e-8)


def test_a_stage_reached_at_once_does_not_stop_a_system_with_inertia():
    """A lateral preload of 0 is reached where the first stage starts, so no case enters
    that stage's stepping (its batch is empty).  The axes diamond has inertia, and its
    flutter-onset test of an empty batch was a scalar NaN: the event table failed to
    build and the run ended with a ValueError (before 2026-12-02).  Now it finishes,
    and D_top = D_bottom (to 1e-12) along the path (symmetric programme)."""
    programme = [
        {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": "F2l", "F_right": "F2l"}},
        {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.05, "D_bottom": 0.05}},
    ]
    ds = follow(SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), "mcnamara", programme,
                {"gamma": 2.0, "F2l": 0.0}).to_dataset()
    assert str(ds["status"].item()) == "finished"
    n = int(ds["n_steps"].item())
    u = ds["u"].isel(law=0).values[:n]
    np.testing.assert_allclose(u[:, 0], u[:, 1], rtol=0, atol=1e-12)
    assert u[-1, 0] == pytest.approx(0.05, abs=1e-12)


@pytest.mark.parametrize("law", ["mcnamara", "cundall_strack"])
def test_a_ring_of_four_grains_is_the_axes_diamond_at_alpha0_pi_over_4(law):
    """ring(4): grains 1-4 at the top, right, bottom and left: the same mechanics as the
    axes diamond (its contacts measure alpha from other axes, and the seed's laws are
    odd in alpha - alpha0), so the same forces at the same displacements (1e-9 as above)."""
    ring = follow(
        SystemSpec("ring", grains=4, secondary_contacts="ignore"), [law],
        [
            {"hold": {"F1": 0.0, "F3": 0.0}, "drive": {"F2": 0.2, "F4": 0.2}},
            {"hold": {"F2": "current", "F4": "current"}, "drive": {"D1": 0.3, "D3": 0.3}},
        ],
        {"gamma": 0.6},
    ).to_dataset()
    axes = follow(
        SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), [law],
        [
            {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_right": 0.2, "F_left": 0.2}},
            {"hold": {"F_right": "current", "F_left": "current"}, "drive": {"D_top": 0.3, "D_bottom": 0.3}},
        ],
        {"gamma": 0.6},
    ).to_dataset()
    order = ["D_top", "D_right", "D_bottom", "D_left"]
    n, m = int(ring["n_steps"].item()), int(axes["n_steps"].item())
    np.testing.assert_allclose(
        ring["u"].isel(law=0).values[n - 1], axes["u"].isel(law=0).sel(dof=order).values[m - 1], rtol=0, atol=1e-9
    )
    np.testing.assert_allclose(
        ring["F"].isel(law=0).values[n - 1], axes["F"].isel(law=0).sel(dof=order).values[m - 1], rtol=0, atol=1e-9
    )


def test_the_axes_diamond_carries_the_antisymmetric_block_the_reduction_hides():
    """On the symmetric path, K of the axes diamond restricted to symmetric modes is
    the reduced K (exactly, by the chain rule: 1e-12), and it has antisymmetric
    modes (D_top - D_bottom, D_left - D_right) the reduced system cannot see."""
    batch = _batch(SystemSpec("diamond", reduction="axes"), "mcnamara", {"gamma": [0.5, 2.0]})
    d1, d2 = 0.05, -0.02
    u = np.tile([d1, d1, d2, d2], (2, 1))
    K = batch.evaluate(u, np.zeros((2, 0))).stiffness
    reduced = ncstab.tangent_operator(
        DiamondChain(np.pi / 4), make_law("mcnamara", gamma=np.array([0.5, 2.0]), alpha0=np.pi / 4), np.tile([d1, d2], (2, 1))
    )
    symmetric = np.array([[1, 0], [1, 0], [0, 1], [0, 1]]) / np.sqrt(2)
    antisymmetric = np.array([[1, 0], [-1, 0], [0, 1], [0, -1]]) / np.sqrt(2)
    np.testing.assert_allclose(symmetric.T @ K @ symmetric, reduced, rtol=0, atol=1e-12)
    np.testing.assert_allclose(symmetric.T @ K @ antisymmetric, 0.0, atol=1e-12)  # the modes decouple
    assert np.all(np.abs(antisymmetric.T @ K @ antisymmetric) > 0)


# --- Ziegler's pendulum and Hencky's column on their straight paths --------------------------------


def test_ziegler_follower_load_on_the_straight_path():
    """K = [[2 - P, P - 1], [-1, 1]] (k/l), det K = 1, Hill's condition lost at P = 2
    exactly (K_sym singular: (2 - P)(6 - P)/4 = 0), located to event_tol (1e-10)."""
    ds = follow(SystemSpec("ziegler", load="follower"), None, [{"drive": {"P": 3.0}}]).to_dataset()
    n = int(ds["n_steps"].item())
    P = ds["load"].isel(law=0).values[:n]
    K = ds["K"].isel(law=0).values[:n]
    expected = np.stack([np.stack([2 - P, P - 1], -1), np.stack([-np.ones_like(P), np.ones_like(P)], -1)], -2)
    np.testing.assert_allclose(K, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(ds["det_K"].isel(law=0).values[:n], 1.0, rtol=0, atol=1e-14)
    assert abs(float(ds["hill_loss_load"].item()) - 2.0) <= 1e-10
    for event in ("limit_point", "bifurcation", "divergence"):  # det K never vanishes
        assert np.isnan(float(ds[f"{event}_load"].item()))
    np.testing.assert_array_equal(ds["u"].isel(law=0).values[:n], 0.0)  # the straight state
    assert str(ds["law"].item()) == "linear_spring" and str(ds["law_class"].item()) == "hyperelastic"


def test_ziegler_dead_load_on_the_straight_path():
    """K = [[2 - P, -1], [-1, 1 - P]]: det K = P^2 - 3P + 1, first zero (3 - sqrt 5)/2 (1e-10),
    a simple bifurcation of the straight path."""
    ds = follow(SystemSpec("ziegler", load="dead"), None, [{"drive": {"P": 1.0}}]).to_dataset()
    n = int(ds["n_steps"].item())
    P = ds["load"].isel(law=0).values[:n]
    np.testing.assert_allclose(ds["det_K"].isel(law=0).values[:n], P**2 - 3 * P + 1, rtol=0, atol=1e-13)
    assert abs(float(ds["bifurcation_load"].item()) - (3 - np.sqrt(5)) / 2) <= 1e-10
    K = ds["K"].isel(law=0).values[:n]
    np.testing.assert_allclose(K, np.swapaxes(K, -1, -2), rtol=0, atol=0)  # dead load: conservative


def _column_hessian(n: int) -> sp.Matrix:
    """Hessian at w = 0 of the column's potential, written here (units C = a = 1):
    V = sum_j (theta_{j+1} - theta_j)^2 / 2 - P sum_i (1 - cos theta_i),
    theta_i = asin(w_i - w_{i-1}), w_0 = w_n = 0."""
    w = sp.symbols(f"w1:{n}", real=True)
    P = sp.Symbol("P")
    joints = (0, *w, 0)
    theta = [sp.asin(joints[i] - joints[i - 1]) for i in range(1, n + 1)]
    potential = sum((theta[j] - theta[j - 1]) ** 2 / 2 for j in range(1, n)) - P * sum(1 - sp.cos(t) for t in theta)
    return sp.hessian(potential, w).subs({x: 0 for x in w}), P


@pytest.mark.parametrize("links", [2, 3, 4, 6])
def test_column_stiffness_on_the_straight_path_is_the_hessian_of_its_potential(links):
    """K at every stored state of a load stage against the Hessian written in the
    test (1e-12: both exact expressions evaluated in floating point)."""
    hessian, P_symbol = _column_hessian(links)
    ds = follow(SystemSpec("column", links=links), None, [{"drive": {"P": 0.3}}]).to_dataset()
    n = int(ds["n_steps"].item())
    P = ds["load"].isel(law=0).values[:n]
    K = ds["K"].isel(law=0).values[:n]
    function = sp.lambdify(P_symbol, hessian, "numpy")
    expected = np.stack([np.asarray(function(p), dtype=float) for p in P])
    np.testing.assert_allclose(K, expected, rtol=0, atol=1e-12)


@pytest.mark.parametrize("links", [2, 3, 4, 5, 6, 7, 8])
def test_the_first_zero_of_det_K_of_the_column_is_henckys_load(links):
    """(4C/a) sin^2(pi/2n) to 1e-10 (event_tol): a simple bifurcation point, not a limit
    point (the load does not turn); with at_bifurcation = "continue" the path goes on
    straight through it (|w| < 1e-12: here exactly 0)."""
    expected = 4 * np.sin(np.pi / (2 * links)) ** 2
    ds = follow(SystemSpec("column", links=links), None, [{"drive": {"P": expected + 0.3}}]).to_dataset()
    assert str(ds["status"].item()) == "finished"
    assert abs(float(ds["bifurcation_load"].item()) - expected) <= 1e-10
    assert np.isnan(float(ds["limit_point_load"].item()))
    assert float(np.nanmax(np.abs(ds["u"].values))) < 1e-12
    n = int(ds["n_steps"].item())
    assert ds["load"].isel(law=0).values[n - 1] == pytest.approx(expected + 0.3, abs=1e-12)


# --- every tangent three ways -------------------------------------------------------------------

STATES = np.random.default_rng(20220712)

SYSTEM_CASES = {
    "diamond-axes": (SystemSpec("diamond", reduction="axes"), "mcnamara", {"gamma": 0.7}),
    "diamond-axes-turco": (SystemSpec("diamond", reduction="axes"), "turco", {"gamma": 1.3}),
    "ring5": (SystemSpec("ring", grains=5), "mcnamara", {"gamma": 0.9}),
    "ring6-weak": (SystemSpec("ring", grains=6), "weakly_hypoelastic", {"gamma": 0.9}),
    "column4": (SystemSpec("column", links=4), None, {}),
    "ziegler-follower": (SystemSpec("ziegler", load="follower"), None, {}),
    "ziegler-dead": (SystemSpec("ziegler", load="dead"), None, {}),
}


def _random_states(batch, count: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(7)
    u = rng.uniform(-0.08, 0.08, size=(count, batch.n_dof))
    load = rng.uniform(0.0, 2.0, size=count)
    return u, load


@pytest.mark.parametrize("name", list(SYSTEM_CASES))
def test_the_tangent_is_the_derivative_of_the_forces(name):
    """K = dF/du against central finite differences (h = 1e-6: truncation ~1e-12 times
    the third derivative, rounding ~1e-16/1e-6; 1e-8 with margin)."""
    spec, law, parameters = SYSTEM_CASES[name]
    batch = _batch(spec, law, parameters)
    u, load = _random_states(batch, 5)
    batch = batch.take(np.zeros(5, dtype=int))
    internal = np.zeros((5, 0))
    K = batch.evaluate(u, internal, load=load).stiffness
    h = 1e-6
    for j in range(batch.n_dof):
        step = np.zeros(batch.n_dof)
        step[j] = h
        difference = (batch.evaluate(u + step, internal, load=load).forces - batch.evaluate(u - step, internal, load=load).forces) / (2 * h)
        np.testing.assert_allclose(K[:, :, j], difference, rtol=0, atol=1e-8)


@pytest.mark.parametrize("name", ["diamond-axes", "diamond-axes-turco", "ring5", "column4", "ziegler-dead"])
def test_the_tangent_of_a_conservative_model_is_symmetric(name):
    """Hyperelastic laws and dead loads derive from a potential: K is its Hessian,
    symmetric at any state (to rounding, 1e-13)."""
    spec, law, parameters = SYSTEM_CASES[name]
    batch = _batch(spec, law, parameters)
    u, load = _random_states(batch, 5)
    batch = batch.take(np.zeros(5, dtype=int))
    K = batch.evaluate(u, np.zeros((5, 0)), load=load).stiffness
    np.testing.assert_allclose(K, np.swapaxes(K, -1, -2), rtol=0, atol=1e-13)


def test_the_tangent_of_the_weakly_hypoelastic_ring_is_not_symmetric():
    spec, law, parameters = SYSTEM_CASES["ring6-weak"]
    batch = _batch(spec, law, parameters)
    u, _ = _random_states(batch, 3)
    K = batch.take(np.zeros(3, dtype=int)).evaluate(u, np.zeros((3, 0))).stiffness
    assert np.abs(K - np.swapaxes(K, -1, -2)).max() > 1e-3


def _symbolic_stiffness(name: str) -> tuple[sp.Matrix, tuple[sp.Symbol, ...], sp.Symbol]:
    """K written independently of the model code: Hessians of potentials written here,
    and for the follower load the Jacobian of the equilibrium written by hand."""
    P = sp.Symbol("P")
    if name.startswith("ziegler"):
        p1, p2 = sp.symbols("phi1 phi2", real=True)
        springs = p1**2 / 2 + (p2 - p1) ** 2 / 2
        if name == "ziegler-dead":
            return sp.hessian(springs + P * (sp.cos(p1) + sp.cos(p2)), (p1, p2)), (p1, p2), P
        residual = sp.Matrix([sp.diff(springs, p1) + P * sp.sin(p2 - p1), sp.diff(springs, p2)])
        return residual.jacobian([p1, p2]), (p1, p2), P
    if name == "column4":
        w = sp.symbols("w1:4", real=True)
        joints = (0, *w, 0)
        theta = [sp.asin(joints[i] - joints[i - 1]) for i in range(1, 5)]
        potential = sum((theta[j] - theta[j - 1]) ** 2 / 2 for j in range(1, 4)) - P * sum(1 - sp.cos(t) for t in theta)
        return sp.hessian(potential, w), w, P
    # diamond on its axes, McNamara (energy seed Eq. 19 per contact, gamma = 0.7)
    d = sp.symbols("D_top D_bottom D_left D_right", real=True)
    a0 = sp.pi / 4
    energy = 0
    for vertical, side in ((0, 2), (0, 3), (1, 2), (1, 3)):
        x, y = sp.cos(a0) - d[vertical], sp.sin(a0) - d[side]
        length, angle = sp.sqrt(x**2 + y**2), sp.atan2(y, x)
        energy += (1 - length) ** 2 / 2 + sp.Rational(7, 10) * (angle - a0) ** 2 / 2
    return sp.hessian(energy, d), d, P


@pytest.mark.parametrize("name", ["diamond-axes", "column4", "ziegler-follower", "ziegler-dead"])
def test_the_tangent_is_the_symbolic_one(name):
    """K from the model's derivation against K derived here from the mechanics (1e-12)."""
    spec, law, parameters = SYSTEM_CASES[name]
    batch = _batch(spec, law, parameters)
    u, load = _random_states(batch, 4)
    K = batch.take(np.zeros(4, dtype=int)).evaluate(u, np.zeros((4, 0)), load=load).stiffness
    matrix, symbols, P = _symbolic_stiffness(name)
    function = sp.lambdify([*symbols, P], matrix, "numpy")
    expected = np.stack([np.asarray(function(*state, p), dtype=float) for state, p in zip(u, load)])
    np.testing.assert_allclose(K, expected, rtol=0, atol=1e-12)


# --- the n-dof Newton projection -----------------------------------------------------------------


def test_the_newton_projection_of_an_n_dof_system_converges_quadratically():
    """From a state 1e-3 off equilibrium, the residual of the axes diamond's mixed
    control falls as r_{k+1} <= C r_k^2 (C = 10 here) to below 1e-13 in a few
    iterations (before the fix of the shared correction array it stalled at 1e-11)."""
    from ncstab.paths.cofactor import minimum_norm_steps
    from ncstab.paths.tangent_field import StageArrays, control_matrix

    batch = _batch(SystemSpec("diamond", reduction="axes"), "mcnamara", {"gamma": 1.1})
    stage = StageArrays.empty(1, 4)
    stage.force_controlled[:] = [False, False, True, True]
    stage.offset[:] = [0.0, 0.0, 0.05, 0.05]
    stage.slope[:] = [1.0, 1.0, 0.0, 0.0]
    u = np.array([[0.1, 0.1, 0.01, 0.01]]) + 1e-3 * np.array([[0.3, -0.7, 0.5, 0.2]])
    lam = np.array([0.1])
    residuals = []
    for _ in range(6):
        evaluation = batch.evaluate(u, np.zeros((1, 0)))
        r = stage.residual(evaluation.displacements, evaluation.forces, lam)
        residuals.append(float(np.abs(r).max()))
        if residuals[-1] < 1e-14:
            break
        _, dg = stage.control_path(lam)
        matrix = control_matrix(evaluation.du_dv, evaluation.dF_dv, stage.force_controlled)
        dv, dlam, solved = minimum_norm_steps(matrix, dg, r)  # the loop's correction, case by case
        assert solved.all()
        u = u + dv
        lam = lam + dlam
    assert residuals[-1] < 1e-13
    for before, after in zip(residuals[:-1], residuals[1:]):
        if before > 1e-7:
            assert after <= 10 * before**2
    assert len(residuals) <= 5


# --- models are values ------------------------------------------------------------------------------


def test_a_system_definition_and_a_batch_of_it_pickle():
    definition = system_definition("ring", (("grains", 5),))
    assert pickle.loads(pickle.dumps(definition)) == definition
    batch = _batch(SystemSpec("ring", grains=5), "mcnamara", {"gamma": [0.5, 1.0]})
    copy = pickle.loads(pickle.dumps(batch))
    u = np.full((2, 5), 0.01)
    np.testing.assert_array_equal(copy.evaluate(u, np.zeros((2, 0))).forces, batch.evaluate(u, np.zeros((2, 0))).forces)


def test_follow_takes_a_system_built_in_python():
    """A user's system as a value: a three-dof chain of springs (a column of 4 links
    built by hand) follows the same path as the shipped column."""
    shipped = system_definition("column", (("links", 4),))
    user = SystemDefinition(
        name="my_column", title="a column built by hand", dofs=shipped.dofs, forces=shipped.forces,
        families=shipped.families, load=shipped.load, domain=shipped.domain, parameters=shipped.parameters,
    )
    a = follow(user, None, [{"drive": {"P": 0.9}}]).to_dataset()
    b = follow(SystemSpec("column", links=4), None, [{"drive": {"P": 0.9}}]).to_dataset()
    np.testing.assert_array_equal(a["det_K"].values, b["det_K"].values)
    assert a.attrs["system"] == "my_column"


def test_the_dataset_names_dofs_contacts_and_loads():
    ds = follow(
        SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), ["mcnamara"], AXES[:1], {"gamma": 0.5}
    ).to_dataset()
    assert list(ds["dof"].values) == ["D_top", "D_bottom", "D_left", "D_right"]
    assert list(ds["force"].values) == ["F_top", "F_bottom", "F_left", "F_right"]
    assert list(ds["contact"].values) == ["top_left", "top_right", "bottom_left", "bottom_right"]
    assert ds["N"].dims[-1] == "contact" and ds["limit_point_alpha"].dims[-1] == "contact"
    assert "load" not in ds
    for name, variable in ds.data_vars.items():
        assert "long_name" in variable.attrs and "description" in variable.attrs, name
    z = follow(SystemSpec("ziegler", load="dead"), None, [{"drive": {"P": 1.0}}]).to_dataset()
    assert z["load"].dims[-1] == "step" and "limit_point_load" in z
    assert list(z["spring"].values) == ["base", "middle"] and z["moment"].dims[-1] == "spring"
    assert z.attrs["load_kind"] == "dead" and z.attrs["force_unit"] == "k"


def test_a_system_built_in_python_reaches_the_workers_of_a_dask_run(tmp_path):
    """A Study around a SystemDefinition that no registry knows (a five-grain ring
    built here) runs on a dask worker in another process and gives the in-process
    archive (identical, ``created`` aside): the model travels as a value."""
    import dataclasses

    import xarray as xr

    distributed = pytest.importorskip("dask.distributed")
    from ncstab.studies import open_study, parse_study, run_study, run_study_chunked, write_dataset

    shipped = system_definition("ring", (("grains", 5),))
    mine = dataclasses.replace(shipped, name="my_ring", title="a ring built in Python")
    text = """
[study]
name = "python_ring"
[system]
name = "ring"
grains = 5
[laws]
names = ["mcnamara", "cundall_strack"]
[parameters]
gamma = [0.5, 1.5]
[[loading]]
hold = { F2 = 0.0, F3 = 0.0, F4 = 0.0, F5 = 0.0 }
drive = { D1 = 0.05 }
[options]
max_step = 0.05
"""
    study = dataclasses.replace(parse_study(text), system=mine)
    write_dataset(run_study(study), tmp_path / "in_process.nc")
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        run_study_chunked(study, tmp_path / "dask.nc", chunk_cases=2, scheduler=cluster.scheduler_address)
    a, b = open_study(tmp_path / "in_process.nc"), open_study(tmp_path / "dask.nc")
    for dataset in (a, b):
        dataset.attrs.pop("created")
    assert a.attrs["system"] == "my_ring"
    xr.testing.assert_identical(a, b)


def _docs_table_row(law: str, gamma: str, F2: str) -> list[str]:
    text = (Path(__file__).parent.parent / "docs" / "models.md").read_text(encoding="utf-8")
    for line in text.splitlines():
        cells = [c.strip() for c in line.strip("|").split("|")]
        if cells[:3] == [law, gamma, F2]:
            return cells[3:]
    raise AssertionError(f"docs/models.md has no row for {law}, {gamma}, {F2}")


@pytest.mark.parametrize("law, gamma, F2", [("cundall_strack", 0.5, 0.75)])
def test_the_antisymmetric_modes_table_of_the_docs_is_what_the_script_computes(law, gamma, F2):
    """docs/models.md's finding, recomputed for two of its rows by the script that made it."""
    import importlib.util

    script = Path(__file__).parent.parent / "docs" / "scripts" / "antisymmetric_modes.py"
    spec = importlib.util.spec_from_file_location("antisymmetric_modes", script)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    losses = module.block_losses(law, gamma, F2)
    columns = ["symmetric Hill", "symmetric det", "antisymmetric Hill", "antisymmetric det"]
    computed = ["—" if np.isnan(losses[c]) else f"{losses[c]:.3f}" for c in columns]
    assert computed == _docs_table_row(law, f"{gamma:g}", f"{F2:g}")


def test_the_python_example_of_the_models_page_runs():
    """The softening two-link column of docs/models.md: bifurcation at 4C/a sin^2(pi/4) = 2."""
    import contextlib
    import io
    import re as regex

    text = (Path(__file__).parent.parent / "docs" / "models.md").read_text(encoding="utf-8")
    code = regex.findall(r"```python\n(.*?)```", text, regex.S)[0]  # the page's first (the others: test_docs_examples)
    printed = io.StringIO()
    with contextlib.redirect_stdout(printed):
        exec(compile(code, "docs/models.md", "exec"), {})
    law_class, load = printed.getvalue().split()
    assert law_class == "hyperelastic" and abs(float(load) - 2.0) <= 1e-10


def test_a_sweep_whose_every_case_fails_at_the_start_is_recorded_not_raised():
    """Holding F1 = eps from rest (where F1 = 0) fails each case with eps != 0 at
    its stage start; with no case left the engine still evaluates an empty batch
    (a regression: springs have no internal variables, and reshaping an empty
    array with -1 raised)."""
    programme = [{"hold": {"F2": 0.0, "F1": "eps"}, "drive": {"P": 0.3}}]
    ds = follow(SystemSpec("column", links=3), None, programme, {"eps": [1e-4, -1e-4]}).to_dataset()
    assert list(ds["status"].values.ravel()) == ["failed:bad_stage_start"] * 2
