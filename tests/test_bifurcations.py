"""Simple bifurcation points: located, told from limit points, stepped through, switched.

Expected values come from closed forms (Hencky, Ziegler), from equilibrium
equations and a Lyapunov--Schmidt coefficient written out here by hand, and
from a one-dof system whose branches are known exactly.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import turco_bifurcation  # tests/turco_bifurcation.py (the tests folder is on the path)
from ncstab.laws.spring import THETA, SpringLaw
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.studies import parse_study, run_study
from ncstab.systems import InteractionFamily, LoadDefinition, SystemDefinition, dof_symbols

ZIEGLER_BIFURCATION = (3 - np.sqrt(5)) / 2


def _ziegler_residual(phi: np.ndarray, P: np.ndarray) -> np.ndarray:
    """Equilibrium of Ziegler's pendulum under a dead tip load, written out here (k = l = 1):
    dV/dphi = 0 with V = phi1^2/2 + (phi2 - phi1)^2/2 + P (cos phi1 + cos phi2)."""
    p1, p2 = phi[..., 0], phi[..., 1]
    return np.stack([2 * p1 - p2 - P * np.sin(p1), p2 - p1 - P * np.sin(p2)], axis=-1)


@pytest.mark.parametrize("direction", [1, -1])
def test_ziegler_dead_load_switches_to_its_post_buckling_branch(direction):
    """Bifurcation at (3 - sqrt 5)/2 (1e-10); every state of the switched branch
    satisfies the equilibrium written in the test (1e-10: the Newton projection's
    1e-12 on F, times |K| < 3); the branch is the mirror image either way."""
    programme = [{"drive": {"P": 0.6}, "at_bifurcation": {"switch": True, "direction": direction}}]
    ds = follow(SystemSpec("ziegler", load="dead"), None, programme).to_dataset()
    assert str(ds["status"].item()) == "finished"
    assert abs(float(ds["bifurcation_load"].item()) - ZIEGLER_BIFURCATION) <= 1e-10
    n = int(ds["n_steps"].item())
    phi, P = ds["u"].isel(law=0).values[:n], ds["load"].isel(law=0).values[:n]
    np.testing.assert_allclose(_ziegler_residual(phi, P), 0.0, atol=1e-10)
    branch = ds["branch_index"].isel(law=0).values[:n]
    after = branch == direction
    assert after.sum() > 10 and np.all(branch[~after] == 0)
    assert np.all(np.sign(phi[after, 0]) == direction)  # off the straight state, the chosen way
    assert np.all(P[after] >= ZIEGLER_BIFURCATION - 1e-12)  # a supercritical pitchfork: P grows


def test_the_switched_branch_starts_with_the_lyapunov_schmidt_curvature():
    """Near the bifurcation the branch is P = P_c + c xi^2 + O(xi^4), xi the amplitude of
    the buckling mode phi0 (K(P_c) phi0 = 0).  By hand: with R = K_s phi - P sin(phi),
    phi = xi phi0 + O(xi^3), projecting R = 0 on phi0 (K symmetric) gives
    c = P_c sum(phi0^4) / (6 sum(phi0^2)).  The branch's (P - P_c)/xi^2 at small xi
    tends to c (error O(xi^2): 1e-3 relative at xi ~ 0.03)."""
    P_c = ZIEGLER_BIFURCATION
    phi0 = np.array([1.0, 2 - P_c])  # (K_s - P_c I) phi0 = 0: 2 - P_c - (2 - P_c) = 0, -1 + (1 - P_c)(2 - P_c) = 0
    assert np.allclose(np.array([[2 - P_c, -1], [-1, 1 - P_c]]) @ phi0, 0.0, atol=1e-14)
    c = P_c * np.sum(phi0**4) / (6 * np.sum(phi0**2))
    programme = [{"drive": {"P": P_c + 2e-4}, "at_bifurcation": "switch"}]
    ds = follow(SystemSpec("ziegler", load="dead"), None, programme, options=PathOptions(max_step=1e-3)).to_dataset()
    n = int(ds["n_steps"].item())
    phi, P = ds["u"].isel(law=0).values[:n], ds["load"].isel(law=0).values[:n]
    xi = phi @ phi0 / (phi0 @ phi0)
    near = (np.abs(xi) > 5e-3) & (np.abs(xi) < 0.04)
    assert near.sum() >= 3
    np.testing.assert_allclose((P[near] - P_c) / xi[near] ** 2, c, rtol=2e-3)


def _transcritical_system() -> SystemDefinition:
    """One dof u, a spring M = u + u^2 and a dead load doing the work P u^2 / 2:
    R(u, P) = u + u^2 - P u, so u = 0 and u = P - 1 cross at P = 1 (transcritical)."""
    (u,) = dof_symbols(("u",))
    spring = SpringLaw("quadratic_spring", "a spring stiffening in one direction", "M = theta + theta^2",
                       moment=THETA + THETA**2)
    return SystemDefinition(
        name="transcritical", title="a transcritical bifurcation", dofs=("u",), forces=("F",),
        families=(InteractionFamily("springs", "spring", ("spring",), ((u,),), law=spring),),
        load=LoadDefinition("P", "dead", (u,)),
    )


def test_a_transcritical_bifurcation_is_located_and_switched_to_its_exact_branch():
    system = _transcritical_system()
    continued = follow(system, None, [{"drive": {"P": 1.5}}]).to_dataset()
    assert abs(float(continued["bifurcation_load"].item()) - 1.0) <= 1e-10
    assert np.isnan(float(continued["limit_point_load"].item()))
    assert float(np.nanmax(np.abs(continued["u"].values))) == 0.0
    switched = follow(system, None, [{"drive": {"P": 1.5}, "at_bifurcation": "switch"}]).to_dataset()
    n = int(switched["n_steps"].item())
    u, P = switched["u"].isel(law=0).values[:n, 0], switched["load"].isel(law=0).values[:n]
    after = switched["branch_index"].isel(law=0).values[:n] != 0
    np.testing.assert_allclose(u[after], P[after] - 1.0, rtol=0, atol=1e-10)  # the exact branch


def test_a_limit_point_of_the_unreduced_diamond_is_never_a_bifurcation():
    """The seed's Figs. 9-11 case (F2* = 0.75, gamma = 0.5) on the unreduced diamond: the
    limit load of F1 under displacement control is a limit point, not a bifurcation."""
    ds = follow(
        SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), ["mcnamara"],
        [
            {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": 0.75, "F_right": 0.75}},
            {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.6, "D_bottom": 0.6}},
        ],
        {"gamma": 0.5},
    ).to_dataset()
    assert np.isfinite(float(ds["limit_point_s"].item()))
    assert np.isnan(float(ds["bifurcation_s"].item()))


def test_a_fold_under_load_control_is_a_limit_point_not_a_bifurcation():
    """R(u, P) = u - u^3/3 - P (a softening spring, a dead load of fixed direction): the
    load reaches its maximum 2/3 at u = 1 (det K = 1 - u^2 = 0) and turns: a limit point
    at P = 2/3 (1e-10), where the driven quantity turns; no bifurcation."""
    (u,) = dof_symbols(("u",))
    spring = SpringLaw("softening", "softening spring", "M = theta - theta^3/3", moment=THETA - THETA**3 / 3)
    system = SystemDefinition(
        name="fold", title="a fold", dofs=("u",), forces=("F",),
        families=(InteractionFamily("springs", "spring", ("spring",), ((u,),), law=spring),),
        load=LoadDefinition("P", "dead", (sp.Integer(1),)),
    )
    ds = follow(system, None, [{"drive": {"P": 0.9}, "stop_at": ["limit_point"]}]).to_dataset()
    assert str(ds["status"].item()) == "stopped:limit_point"
    assert abs(float(ds["limit_point_load"].item()) - 2 / 3) <= 1e-10
    assert abs(float(ds["limit_point_u"].isel(dof=0).item()) - 1.0) <= 1e-5  # det K ~ 2 (u - 1): u to sqrt(1e-10)
    assert np.isnan(float(ds["bifurcation_s"].item()))


def test_a_study_following_every_branch_gets_a_branch_dimension():
    """at_bifurcation = "branches": the path continued and both halves of the pitchfork,
    mirror images of each other (to 1e-12)."""
    study = parse_study(
        """
[study]
name = "ziegler_branches"
[system]
name = "ziegler"
load = "dead"
[[loading]]
drive = { P = 0.6 }
at_bifurcation = "branches"
"""
    )
    ds = run_study(study)
    assert list(ds["branch"].values) == [0.0, 1.0, -1.0]
    assert list(ds["status"].values.ravel()) == ["finished"] * 3
    last = ds["n_steps"].values[0] - 1
    ends = np.stack([ds["u"].values[0, b, last[b]] for b in range(3)])
    np.testing.assert_array_equal(ends[0], 0.0)
    np.testing.assert_allclose(ends[1], -ends[2], rtol=0, atol=1e-12)
    assert ds["branch_index"].values[0, 1, last[1]] == 1 and ds["branch_index"].values[0, 2, last[2]] == -1


def test_a_case_bifurcates_and_switches_the_same_alone_or_in_a_sweep():
    """Batch independence: the column's bifurcation and its switched branch do not depend
    on the other cases of the sweep (bit for bit)."""
    programme = [{"drive": {"P": 1.5}, "at_bifurcation": "switch"}]
    alone = follow(SystemSpec("ziegler", load="dead"), None, programme, {"m1": 2.0}).to_dataset()
    swept = follow(SystemSpec("ziegler", load="dead"), None, programme, {"m1": [1.0, 2.0, 3.0]}).to_dataset()
    one = swept.sel(m1=2.0)
    n = int(alone["n_steps"].item())
    np.testing.assert_array_equal(one["u"].values[0, :n], alone["u"].values[0, :n])
    np.testing.assert_array_equal(one["bifurcation_load"].values, alone["bifurcation_load"].values)


# --- The reduced diamond: Turco, gamma = 2, F2* = 0 (the stability diagram's case) ---

TURCO_PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2l"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]


def _turco_gamma_2(max_step: float):
    path = follow(
        SystemSpec(secondary_contacts="ignore"), "turco", TURCO_PROGRAMME,
        {"gamma": 2.0, "F2l": 0.0, "alpha0": np.pi / 4},
        PathOptions(max_step=max_step, sample_step=0.05),
    )
    return path.to_dataset().squeeze()


def test_turco_gamma_2_meets_a_simple_bifurcation_point_known_in_closed_form():
    """The located bifurcation is the closed form's (tests/turco_bifurcation.py): alpha =
    3 pi/8, l = sin(pi/8), F = (2 sqrt 2, 0), K = diag(8 + 4 sqrt 2, 0), so K21 = K22 = 0
    and [M | g'] loses rank under F2 held: two branches cross.  It is a `bifurcation`,
    not a `limit_point` (det K = 0 where the path does not turn: the branch test changes
    sign with it), and Hill's condition and controllability are lost there too.
    Tolerances: the event's s to event_tol = 1e-10 moves u by as much and K by
    |dK/ds| * 1e-10 < 1e-8; 1e-8 on u, F, K, alpha, l."""
    u, F, K = turco_bifurcation.bifurcation_point()
    np.testing.assert_allclose(F, [2 * np.sqrt(2), 0.0], atol=1e-14)
    np.testing.assert_allclose(K, [[8 + 4 * np.sqrt(2), 0.0], [0.0, 0.0]], atol=1e-13)
    ds = _turco_gamma_2(1.0)
    assert str(ds["status"].item()) == "finished"
    np.testing.assert_allclose(ds["bifurcation_u"].values, u, atol=1e-8)
    np.testing.assert_allclose(ds["bifurcation_F"].values, F, atol=1e-8)
    np.testing.assert_allclose(ds["bifurcation_K"].values, K, atol=1e-8)
    assert abs(float(ds["bifurcation_alpha"]) - 3 * np.pi / 8) <= 1e-8
    assert abs(float(ds["bifurcation_l"]) - np.sin(np.pi / 8)) <= 1e-8
    assert np.isnan(float(ds["limit_point_s"])) and np.isnan(float(ds["turning_point_s"]))
    for event in ("hill_loss", "controllability_loss"):  # they vanish together there
        assert abs(float(ds[f"{event}_s"]) - float(ds["bifurcation_s"])) <= 1e-9


def test_turco_gamma_2_steps_over_its_bifurcation_point_along_its_branch_whatever_the_steps():
    """At a simple bifurcation point the path goes on along the branch it was on
    (at_bifurcation = "continue"), whatever the steps (ncstab.paths.over_steps).  Before
    over steps, max_step 0.05 came out on the crossing branch of neutral equilibria
    (F1* = 2 sqrt 2, D2* = 0.548 at D1* = 0.6) with a limit point found in the rounding of
    det K = 0 there; the other step sizes went straight on.

    Expected: the end state is the closed-form equilibrium F2 = 0 at D1* = 0.6 on the branch
    followed (Newton on the energy from D2* = 0.40; the neutral branch's is at 0.548),
    to 1e-10 (both projected onto equilibrium to newton_tol = 1e-12, |K^-1| < 1); the
    located point is the same for every step size to 1e-9 in s (two locations to
    event_tol = 1e-10, and the over step's arclength to O(kappa^2 L^3) < 1e-12)."""
    u_end, F_end = turco_bifurcation.equilibrium(0.6, 0.40)
    located = []
    for max_step in (1.0, 0.05, 0.01, 0.002):
        ds = _turco_gamma_2(max_step)
        assert str(ds["status"].item()) == "finished"
        last = int(ds["n_steps"]) - 1
        np.testing.assert_allclose(ds["u"].values[last], u_end, rtol=0, atol=1e-10)
        np.testing.assert_allclose(ds["F"].values[last], F_end, rtol=0, atol=1e-10)
        located.append([float(ds[f"{event}_s"]) for event in ("bifurcation", "hill_loss", "controllability_loss")])
    located = np.array(located)
    assert np.ptp(located) <= 1e-9, located


@pytest.mark.parametrize(("direction", "guess"), [(1, 0.55), (-1, 0.16)])
def test_turco_gamma_2_switches_onto_the_branch_of_neutral_equilibria(direction, guess):
    """at_bifurcation = switch on the reduced diamond (the compiled loop returns the case
    at the point, and the path leaves along the branch, branch_switching.leave_along_branch):
    from the point, the path follows the crossing branch, on which F1* = 2 sqrt 2 and
    F2* = 0 all along (so det K = 0 on it), either way, to D1* = 0.6.  Expected: F1* constant to 1e-10 after the point (every state projected to
    newton_tol = 1e-12), and the end state the closed-form equilibrium F2 = 0 at D1* = 0.6
    on that branch (Newton on the energy from D2* = 0.55 or 0.16; the branch followed
    before the point ends at 0.405), to 1e-10."""
    programme = [TURCO_PROGRAMME[0], {**TURCO_PROGRAMME[1], "at_bifurcation": {"switch": True, "direction": direction}}]
    path = follow(SystemSpec(secondary_contacts="ignore"), "turco", programme,
                  {"gamma": 2.0, "F2l": 0.0, "alpha0": np.pi / 4}, PathOptions())
    assert path.results[0].engine.startswith("compiled stepper (numba ")
    ds = path.to_dataset().squeeze()
    assert str(ds["status"].item()) == "finished"
    n = int(ds["n_steps"])
    after = ds["s"].values[:n] > float(ds["bifurcation_s"]) + 1e-6
    assert after.sum() > 3
    np.testing.assert_allclose(ds["F"].values[:n][after, 0], 2 * np.sqrt(2), rtol=0, atol=1e-10)
    u_end, F_end = turco_bifurcation.equilibrium(0.6, guess)
    assert abs(u_end[1] - 0.405) > 0.1  # not the branch followed before the point
    np.testing.assert_allclose(ds["u"].values[n - 1], u_end, rtol=0, atol=1e-10)
    np.testing.assert_allclose(ds["F"].values[n - 1], F_end, rtol=0, atol=1e-10)


# --- The unreduced diamond at the same point: a degenerate point (K's null space 2-D) ---

AXES_PROGRAMME = [
    {"hold": {"F_top": 0.0, "F_bottom": 0.0}, "drive": {"F_left": "F2l", "F_right": "F2l"}},
    {"hold": {"F_left": "current", "F_right": "current"}, "drive": {"D_top": 0.6, "D_bottom": 0.6}},
]


@pytest.mark.parametrize("max_step", [1.0, 0.05])
def test_the_unreduced_diamond_steps_over_turcos_degenerate_point_along_its_branch(max_step):
    """The 4-dof diamond (reduction = "axes") under the same symmetric programme meets
    Turco's point with K singular in both its symmetric and antisymmetric blocks: [M | g']
    loses rank by two, the cofactor vector vanishes quadratically without reversing, and
    before degenerate over steps (ncstab.paths.over_steps) max_step 1 turned onto the
    neutral branch (D_left* = D_right* = 0.548 at the end, with a `limit_point` found in
    the rounding of det K = 0 on it) while 0.05 went straight on.

    Expected: every step size ends at the closed-form equilibrium of the branch followed
    (the reduced diamond's, tests/turco_bifurcation.py: D2* = 0.40522161 at D1* = 0.6, F2 =
    0; by symmetry D_top = D_bottom = D1*, D_left = D_right = D2*, F_top = F_bottom = F1),
    to 1e-10 (projected onto equilibrium to newton_tol = 1e-12, |K^-1| < 1 there), and
    no limit point is found."""
    path = follow(
        SystemSpec("diamond", reduction="axes", secondary_contacts="ignore"), "turco", AXES_PROGRAMME,
        {"gamma": 2.0, "F2l": 0.0, "alpha0": np.pi / 4}, PathOptions(max_step=max_step),
    )
    ds = path.to_dataset().squeeze()
    assert str(ds["status"].item()) == "finished"
    u_end, F_end = turco_bifurcation.equilibrium(0.6, 0.40)
    last = int(ds["n_steps"]) - 1
    np.testing.assert_allclose(ds["u"].values[last], [u_end[0], u_end[0], u_end[1], u_end[1]], rtol=0, atol=1e-10)
    np.testing.assert_allclose(ds["F"].values[last], [F_end[0], F_end[0], 0.0, 0.0], rtol=0, atol=1e-10)
    assert np.isnan(float(ds["limit_point_s"]))
