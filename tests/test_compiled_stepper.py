"""The compiled (numba) stepper, the path engine of ``follow`` for the diamond chain.

Every check holds the engine to something it did not compute itself:

1. the seed directly: the McNamara limit point (maximum of Eq. 53), a scipy
   integration of the Cundall--Strack rate form (Eq. 38), and the singular
   point of Turco's chain at gamma = 2 (the double root of Eq. 56, crossed
   from the branch of Eq. 58 onto the other root of Eq. 57);
2. located switches, by the kinematics of seed Eq. (1): a secondary contact
   is located where its gap is zero (and nothing closed before it), a
   no_tension contact opens and closes where its overlap (Eq. 15, 28) is zero,
   with N = <overlap> at every stored state; cycle stages close each turn
   and show Green's paradox (no work over a turn for the hyperelastic laws,
   work for the hypoelastic ones, forces that do not come back for
   Cundall--Strack);
3. the step options: ``sample_step`` pieces, ``max_steps`` counting steps and
   not their pieces, ``min_step`` failing a case;
4. batch independence: a case alone and inside a batch give the same bits;
5. option validation (``PathOptions.backend``, study files), the engine named
   in the archive, the loop's cache.

numba compiles each law's loop once per process (a few seconds per law), so
the shared paths are followed once (module-level cache).
"""

from __future__ import annotations

import math
import sys
import tempfile
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.optimize import minimize_scalar

pytest.importorskip("numba")

from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.systems.closed_forms import mcnamara_load_rotation, turco_load_rotation

ALPHA0 = math.pi / 4
IGNORE = SystemSpec(secondary_contacts="ignore")
STOP = SystemSpec(secondary_contacts="stop")
ACTIVATE = SystemSpec(secondary_contacts="activate")
LAWS = ("cundall_strack", "weakly_hypoelastic", "mcnamara", "turco")

UNIAXIAL = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
PRELOAD = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]
PRELOAD_STOP = [PRELOAD[0], {**PRELOAD[1], "stop_at": ["limit_point"]}]

UNIAXIAL_GRID = {"gamma": list(np.linspace(0.1, 2.0, 4)), "alpha0": list(np.linspace(0.3, 1.2, 4))}
#: 64 cases; low gamma and high F2* reach limit points, Hill loss and
#: controllability loss (seed Fig. 9-11); gamma = 0.5, F2* = 0.75 is the
#: McNamara limit point of test 1; F2* = 0 makes the first stage zero-length.
PRELOAD_GRID = {
    "gamma": [0.1, 0.25, 0.4, 0.5, 0.75, 1.0, 1.5, 1.9],
    "alpha0": ALPHA0,
    "F2_lateral": [0.0, 0.2, 0.4, 0.5, 0.6, 0.7, 0.75, 0.8],
}

#: name -> (programme, parameters): the paths shared by several tests.
RUNS = {
    "uniaxial": (UNIAXIAL, UNIAXIAL_GRID),
    "preload": (PRELOAD, PRELOAD_GRID),
    "preload_stop_limit": (PRELOAD_STOP, PRELOAD_GRID),
}

_CACHE: dict[tuple[str, str], object] = {}


def run(law: str, name: str):
    """The Path of ``law`` on the shared programme ``name`` (followed once per module)."""
    key = (law, name)
    if key not in _CACHE:
        programme, parameters = RUNS[name]
        _CACHE[key] = follow(IGNORE, law, programme, parameters, PathOptions())
    return _CACHE[key]


@pytest.fixture(scope="module", autouse=True)
def _clear_cache():
    yield
    _CACHE.clear()


def one_case(result, k: int) -> dict:
    """Case ``k`` of a CaseResult, states cut to its n_steps."""
    n = int(result.n_steps[k])
    return {
        "status": result.status[k],
        "message": result.message[k],
        "n_steps": result.n_steps[k],
        **{f"counter_{name}": values[k] for name, values in result.counters.items()},
        **{f"step_{key}": values[k, :n] for key, values in result.steps.items()},
        **{f"{name}_{key}": values[k] for name, table in result.events.items() for key, values in table.items()},
    }


# --- 1. the compiled stepper against the seed, directly ----------------------------------------


def test_compiled_mcnamara_limit_point_is_the_maximum_of_eq53():
    path = run("mcnamara", "preload_stop_limit")
    result, k = path.case("mcnamara", gamma=0.5, F2_lateral=0.75)
    assert result.status[k] == "stopped:limit_point"
    limit = {key: values[k] for key, values in result.events["limit_point"].items()}
    assert limit["found"] and limit["stage"] == 1
    assert limit["s_upper"] - limit["s_lower"] <= 1e-10  # event_tol
    # The maximum of seed Eq. (53) (compression branch) at F2* = 0.75.
    alpha = np.linspace(0.5, 1.4, 20001)
    values = mcnamara_load_rotation(alpha, 0.5, ALPHA0, F2=0.75, branch=-1)
    best = int(np.nanargmax(values))
    found = minimize_scalar(
        lambda a: -mcnamara_load_rotation(a, 0.5, ALPHA0, F2=0.75, branch=-1),
        bounds=(alpha[best - 1], alpha[best + 1]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    f1_max = -found.fun
    assert abs(f1_max - 1.428769555) < 1e-9
    # dF1/dalpha = 0 at the maximum: the 1e-10 bracket in arclength costs ~1e-20
    # in F1; the stored F is on the equilibrium manifold to newton_tol 1e-12.
    assert abs(limit["F"][0] - f1_max) < 1e-9
    assert abs(limit["F"][1] - 0.75) < 1e-10
    assert abs(limit["alpha"] - found.x) < 1e-5  # alpha is only O(sqrt(F1 error)) at a maximum
    # The stop state is the last stored state.
    n = result.n_steps[k]
    assert result.steps["s"][k, n - 1] == limit["s"]


def cundall_strack_rhs(gamma: float, alpha0: float):
    """dy/dD1 for y = (D2, F1) with F2 = 0 held, seed Eq. (38) and (35)
    (as benchmarks/bench_sweep_cundall_strack.py's baseline_rhs)."""
    c0, s0 = math.cos(alpha0), math.sin(alpha0)

    def rhs(d1: float, y: np.ndarray) -> list[float]:
        d2, f1 = y
        vertical, horizontal = c0 - d1, s0 - d2
        length = math.hypot(vertical, horizontal)
        c, s = vertical / length, horizontal / length
        k11 = 2 * c * c + 2 * gamma * s * s
        k12 = 2 * (1 - gamma) * c * s
        k21 = 2 * (1 - gamma) * c * s + s / length * f1
        k22 = 2 * s * s + 2 * gamma * c * c - c / length * f1
        dd2 = -k21 / k22
        return [dd2, k11 + k12 * dd2]

    return rhs


def test_compiled_cundall_strack_matches_solve_ivp_of_eq38():
    path = run("cundall_strack", "uniaxial")
    result = path.results[0]
    values = path.grid.case_values()
    assert np.all(result.status == "finished")
    assert not result.events["turning_point"]["found"].any()  # Delta_1 monotone: the ivp's variable
    for k in range(result.status.size):
        n = int(result.n_steps[k])
        u, forces = result.steps["u"][k, :n], result.steps["F"][k, :n]
        gamma, alpha0 = values["gamma"][k], values["alpha0"][k]
        reference = solve_ivp(
            cundall_strack_rhs(gamma, alpha0), (0.0, 0.2), [0.0, 0.0],
            method="DOP853", rtol=1e-12, atol=1e-14, dense_output=True,
        )
        assert reference.success
        expected = reference.sol(u[:, 0])
        # Cundall--Strack is not projected (T is an internal variable): the
        # engine's local rtol 1e-10 over <= 50 steps gives global errors
        # well below 1e-8 (measured 2e-11).
        np.testing.assert_allclose(u[:, 1], expected[0], rtol=0, atol=1e-8, err_msg=f"case {k}")
        np.testing.assert_allclose(forces[:, 0], expected[1], rtol=0, atol=1e-8, err_msg=f"case {k}")
        np.testing.assert_allclose(forces[:, 1], 0.0, rtol=0, atol=1e-8, err_msg=f"case {k}")
        assert abs(u[-1, 0] - 0.2) < 1e-9


#: Turco, gamma = 2, F2* = 0 held, D1* driven to 0.6 (the golden reduced stability diagram,
#: tests/test_golden.py).  With F2* = 0 every equilibrium satisfies seed Eq. (56), a
#: quadratic in F1* whose two roots (Eq. 57) coincide where its discriminant
#: sin^2(2 alpha - alpha0) + gamma sin(2 alpha) sin(2 alpha0 - 2 alpha) vanishes: for
#: alpha0 = pi/4 and gamma = 2 at alpha = 3 pi/8 (1 + 2 (sqrt 2/2)(-sqrt 2/2) = 0), where
#: F1* = 2 sin(pi/2) / sin(3 pi/4) = 2 sqrt 2 and Delta_1* = 0.5607.  There the branch of
#: Eq. (58) through the unloaded state meets the other root, K21 and K22 vanish together
#: and the path's cofactor tangent passes through zero and changes sign.
SINGULAR = [{"hold": {"F1": 0.0}, "drive": {"F2": 0.0}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
SINGULAR_ALPHA = 3 * math.pi / 8
SINGULAR_F1 = 2 * math.sqrt(2)


def turco_f2_zero_terms(alpha: np.ndarray, f1: np.ndarray, gamma: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Seed Eq. (56) at F2* = 0: its residual, its discriminant and the root's sign.

    The residual -sin(2 alpha) F1*^2 / 4 + F1* sin(2 alpha - alpha0) + gamma sin(2 alpha0 - 2 alpha)
    (zero at every equilibrium), the discriminant of Eq. (57), and the sign before its square
    root: F1* sin(2 alpha) / 2 - sin(2 alpha - alpha0) = +-sqrt(discriminant) (-1: Eq. 58).
    """
    b = np.sin(2 * alpha - ALPHA0)
    residual = -0.25 * np.sin(2 * alpha) * f1**2 + f1 * b + gamma * np.sin(2 * ALPHA0 - 2 * alpha)
    discriminant = b**2 + gamma * np.sin(2 * alpha) * np.sin(2 * ALPHA0 - 2 * alpha)
    return residual, discriminant, np.sign(f1 * np.sin(2 * alpha) / 2 - b)


def test_the_path_goes_straight_on_across_the_singular_point_of_turcos_chain():
    """Each tangent continues the motion at the start of its step (tangent_field
    ._continue_reference): across the singular point the path goes straight on, D1* never
    decreasing, from the root of Eq. (58) onto the other root of Eq. (57), and ends at its
    target.  Every stored state satisfies Eq. (56) to 1e-10 (F and u on equilibrium to
    newton_tol 1e-12, the residual's derivatives of order 10; measured 2e-13), F2* = 0 to
    1e-10, and F1* is Eq. (57)'s root to 1e-9 where the discriminant exceeds 1e-4 (near the
    double root the closed form loses digits as 1/sqrt(discriminant)).  The singular point
    is located (bifurcation and controllability loss) at alpha = 3 pi/8, F1* = 2 sqrt 2,
    and Delta_1* from Eq. (55) and seed Eq. (1), each to 1e-9 (event_tol = 1e-10 in
    arclength, along which they move at rates up to 1/l* ~ 3; measured 9e-11)."""
    path = follow(IGNORE, "turco", SINGULAR, {"gamma": [2.0]}, PathOptions(max_step=0.05))
    result = path.results[0]
    assert result.engine.startswith("compiled stepper (numba ")
    assert result.status[0] == "finished", result.message[0]
    n = int(result.n_steps[0])
    u, forces, alpha = result.steps["u"][0, :n], result.steps["F"][0, :n], result.steps["alpha"][0, :n]
    assert np.all(np.diff(u[:, 0]) >= 0)  # straight on: no turn back at the point
    assert abs(u[-1, 0] - 0.6) < 1e-9
    residual, discriminant, root = turco_f2_zero_terms(alpha, forces[:, 0], 2.0)
    assert np.abs(residual).max() <= 1e-10, np.abs(residual).max()
    assert np.abs(forces[:, 1]).max() <= 1e-10
    clear = discriminant > 1e-4
    before, after = clear & (alpha < SINGULAR_ALPHA), clear & (alpha > SINGULAR_ALPHA)
    assert before.sum() >= 10 and after.sum() >= 10  # states on both sides of the point
    assert np.all(root[before] == -1) and np.all(root[after] == 1)
    for mask, branch in ((before, -1), (after, 1)):
        expected = turco_load_rotation(alpha[mask], 2.0, ALPHA0, branch=branch)
        np.testing.assert_allclose(forces[mask, 0], expected, rtol=0, atol=1e-9, err_msg=f"branch {branch}")
    length = math.cos(SINGULAR_ALPHA - ALPHA0) - SINGULAR_F1 * math.cos(SINGULAR_ALPHA) / 2  # Eq. (55)
    for name in ("bifurcation", "controllability_loss"):
        event = {key: values[0] for key, values in result.events[name].items()}
        assert event["found"] and event["stage"] == 1, name
        assert abs(event["alpha"] - SINGULAR_ALPHA) <= 1e-9, (name, event["alpha"] - SINGULAR_ALPHA)
        assert abs(event["F"][0] - SINGULAR_F1) <= 1e-9, (name, event["F"][0] - SINGULAR_F1)
        assert abs(event["u"][0] - (math.cos(ALPHA0) - length * math.cos(SINGULAR_ALPHA))) <= 1e-9, name


# --- 2. located switches --------------------------------------------------------------------------

#: Top and bottom grains touch where 2 l cos(alpha) = 1, left and right where
#: 2 l sin(alpha) = 1; with seed Eq. (1), l cos(alpha) = cos(alpha0) - Delta_1 and
#: l sin(alpha) = sin(alpha0) - Delta_2.  F2 = 0 held: the top-bottom pair closes at
#: Delta_1 = cos(alpha0) - 1/2 (from 0.325 at alpha0 = 0.6 to 0.04 at alpha0 = 1.0), or,
#: for gamma = 2 and small alpha0 (Delta_2 grows), the left-right pair first.
CONTACT = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.4}}]
CONTACT_GRID = {"gamma": [0.5, 2.0], "alpha0": list(np.linspace(0.6, 1.0, 8))}
#: Gap at a located contact: the crossing is located to event_tol = 1e-10 in arclength,
#: along which the gaps move at |d gap/ds| <= 2 (|du/ds| <= 1).
GAP_TOL = 1e-9
#: Steps as long as the tolerances allow, cut into pieces of at most 0.02 on the
#: interpolant (PathOptions.sample_step): stored states and sign checks at the pieces'
#: ends, crossings located and steps cut inside a piece.
PIECES = PathOptions(max_step=0.5, sample_step=0.02)


def secondary_gaps(u: np.ndarray, alpha0) -> np.ndarray:
    """(top-bottom, left-right) gaps 2 (cos(alpha0) - Delta_1) - 1 and 2 (sin(alpha0) - Delta_2) - 1
    (seed Eq. 1), along the last axis."""
    alpha0 = np.asarray(alpha0)[..., None]
    return 2 * np.stack([np.cos(alpha0[..., 0]) - u[..., 0], np.sin(alpha0[..., 0]) - u[..., 1]], axis=-1) - 1


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("setting", ["stop", "activate", "activate_in_pieces"])
def test_a_secondary_contact_is_located_where_its_gap_closes(law, setting):
    """Every case meets a secondary contact: located where one of the two gaps, computed from
    Delta by seed Eq. (1), is zero to GAP_TOL, the other still open, and no stored state
    before it with a closed gap (the first contact is the one found).  ``stop`` ends the case
    there, on the event state; ``activate`` (kappa 1 and 3) switches the spring on and goes on
    to the target, Delta_1* = 0.4 to 1e-9 (the stage end located to event_tol); in pieces, the
    stored states are never further apart than sample_step."""
    spec = STOP if setting == "stop" else ACTIVATE
    grid = CONTACT_GRID if setting == "stop" else {**CONTACT_GRID, "kappa": [1.0, 3.0]}
    path = follow(spec, law, CONTACT, grid, PIECES if setting == "activate_in_pieces" else PathOptions())
    result = path.results[0]
    alpha0 = path.grid.case_values()["alpha0"]
    contact = result.events["secondary_contact"]
    assert contact["found"].all()
    gaps = secondary_gaps(contact["u"], alpha0)
    closing = np.abs(gaps).min(axis=1)
    assert closing.max() <= GAP_TOL, closing.max()
    assert np.abs(gaps).max(axis=1).min() > 0.01  # the other pair is still apart (measured >= 0.033)
    for k in range(result.status.size):
        n = int(result.n_steps[k])
        s, u = result.steps["s"][k, :n], result.steps["u"][k, :n]
        before = s < contact["s"][k]
        assert np.all(secondary_gaps(u[before], alpha0[k]) > -GAP_TOL), k
        if setting == "stop":
            assert result.status[k] == "stopped:secondary_contact"
            assert s[-1] == contact["s"][k]
            np.testing.assert_array_equal(u[-1], contact["u"][k])
        else:
            assert result.status[k] == "finished"
            assert abs(u[-1, 0] - 0.4) < 1e-9
    if setting == "activate_in_pieces":
        # several stored states per accepted step (the pieces), never two further apart than 0.02
        assert (result.n_steps > result.counters["accepted"] + 2).any()
        assert np.nanmax(np.diff(result.steps["s"], axis=1)) <= 0.02 * (1 + 1e-12)


#: Compression (Delta_1* to 0.05), extension (to -0.1), compression again (to 0.1), F2* = 0
#: held: a no_tension law's normal contact, closed through the first stage, opens inside
#: the second and closes again inside the third: two located switches per case.
TENSION = [
    {"hold": {"F2": 0.0}, "drive": {"D1": 0.05}},
    {"hold": {"F2": 0.0}, "drive": {"D1": -0.1}},
    {"hold": {"F2": 0.0}, "drive": {"D1": 0.1}},
]
TENSION_GRID = {"gamma": [0.5, 1.0, 2.0], "alpha0": [0.6, ALPHA0, 1.0]}
#: Overlap at a located switch: the crossing is located to event_tol = 1e-10 in
#: arclength, along which the overlap moves at |d delta/ds| <= 2.
SWITCH_TOL = 1e-9


def normal_overlap(law: str, length: np.ndarray, alpha: np.ndarray, alpha0: float) -> np.ndarray:
    """The normal overlap delta: 1 - l* (seed Eq. 15, 18, 26), cos(alpha - alpha0) - l* for Turco (Eq. 28)."""
    return np.cos(alpha - alpha0) - length if law == "turco" else 1 - length


@pytest.mark.parametrize("law", LAWS)
def test_a_no_tension_contact_opens_and_closes_where_its_overlap_is_zero(law):
    """The no_tension kink (seed Eq. 59) as located switches: at every stored state
    N = <delta>, the overlap of the law (seed Eq. 15, 28) from the stored l* and alpha, to
    1e-12 (both from the same numbers: rounding), so never tension and nothing on the open
    branch; the overlap never changes sign within a step: each switch is a stored state
    with delta = 0 to SWITCH_TOL (so N = 0 there), one inside the second stage where the
    contact opens and one inside the third where it closes again."""
    path = follow(IGNORE, f"{law}+no_tension", TENSION, TENSION_GRID)
    result = path.results[0]
    assert result.engine.startswith("compiled stepper (numba ")
    assert np.all(result.status == "finished"), result.message
    alpha0 = path.grid.case_values()["alpha0"]
    worst = 0.0
    for k in range(result.status.size):
        n = int(result.n_steps[k])
        stage = result.steps["stage"][k, :n]
        overlap = normal_overlap(law, result.steps["l"][k, :n], result.steps["alpha"][k, :n], alpha0[k])
        np.testing.assert_allclose(result.steps["N"][k, :n], np.maximum(overlap, 0.0), rtol=0, atol=1e-12)
        side = np.where(np.abs(overlap) <= SWITCH_TOL, 0.0, np.sign(overlap))
        assert not np.any(side[1:] * side[:-1] < 0), k  # from one side to the other only through a switch
        for switching, opening in ((1, True), (2, False)):
            inside = np.flatnonzero((stage == switching) & (side == 0))
            assert inside.size >= 1, (k, switching)
            first = inside[0]
            assert side[first - 1] == (1 if opening else -1) and side[inside[-1] + 1] == (-1 if opening else 1)
            worst = max(worst, float(np.abs(overlap[inside]).max()))
    assert worst <= SWITCH_TOL


#: Green's paradox: a linear stage, then two clockwise turns of a circle in the
#: (Delta_1*, Delta_2*) plane off the current state (each turn's end located as a
#: crossing), then one counterclockwise turn of another; for alpha0 = 0.6 the second
#: circle reaches the left-right contact (switched on where it is activated).
CYCLES = [
    {"hold": {"F2": 0.0}, "drive": {"D1": 0.05}},
    {"cycle": {"center": [0.03, 0.0], "turns": 2, "direction": -1}},
    {"cycle": {"center": [0.05, 0.04], "turns": 1, "direction": 1}},
]
#: (stage, turn) of each column of the cycle tables.
CYCLE_TURNS = ((1, 1), (1, 2), (2, 1))


@pytest.mark.parametrize("law", LAWS)
@pytest.mark.parametrize("spec", [IGNORE, ACTIVATE], ids=["ignore", "activate"])
def test_cycle_stages_close_their_turns_and_show_greens_paradox(law, spec):
    """Each turn ends where it started: Delta at lambda = 2 pi k equals Delta at the stage's
    start to 1e-9 (the turn's end located to event_tol = 1e-10 in arclength, |du/ds| <= 1).
    Green's paradox (seed Introduction, Eq. 17-29): the hyperelastic laws (and the
    frictionless secondary springs) do no work over a turn, |W| <= 1e-11 (the work is
    integrated with the path at rtol 1e-10 over a turn whose terms are of order 1e-3;
    measured 1e-14), and their forces come back, like the weakly hypoelastic law's (a total
    form), to 1e-9 (Delta back to 1e-9 times stiffnesses of order 1); the weakly hypoelastic
    and Cundall--Strack laws do work over a closed turn (|W| > 1e-6, measured >= 2e-5), and
    Cundall--Strack's forces do not come back (by more than 1e-4, measured >= 1.6e-3).
    For alpha0 = 0.6 the left-right contact is located on the second circle, its gap zero
    to GAP_TOL."""
    parameters = {"gamma": [0.5, 2.0], "alpha0": [0.6, ALPHA0]}
    path = follow(spec, law, CYCLES, parameters, PathOptions(max_step=0.2))
    result = path.results[0]
    assert result.engine.startswith("compiled stepper (numba ")
    assert np.all(result.status == "finished"), result.message
    work = result.cycles["work"]
    assert work.shape == (4, 3) and np.isfinite(work).all()  # every turn closed and tabled
    np.testing.assert_array_equal(result.cycles["stage"], [stage for stage, _ in CYCLE_TURNS])
    for k in range(result.status.size):
        n = int(result.n_steps[k])
        stage, lam = result.steps["stage"][k, :n], result.steps["lam"][k, :n]
        u, forces = result.steps["u"][k, :n], result.steps["F"][k, :n]
        for column, (cycle_stage, turn) in enumerate(CYCLE_TURNS):
            start = np.flatnonzero(stage == cycle_stage)[0]
            end = np.flatnonzero((stage == cycle_stage) & (np.abs(lam - 2 * np.pi * turn) <= 1e-8))
            assert end.size >= 1, (k, cycle_stage, turn)
            np.testing.assert_allclose(u[end[0]], u[start], rtol=0, atol=1e-9, err_msg=f"case {k}, turn {column}")
            force_gap = np.abs(forces[end[0]] - forces[start]).max()
            if law == "cundall_strack":
                assert force_gap > 1e-4, (k, column, force_gap)
                assert abs(work[k, column]) > 1e-6, (k, column)
            else:
                assert force_gap <= 1e-9, (k, column, force_gap)
                if law == "weakly_hypoelastic":
                    assert abs(work[k, column]) > 1e-6, (k, column)
                else:
                    assert abs(work[k, column]) <= 1e-11, (k, column, work[k, column])
    contact = result.events["secondary_contact"]
    alpha0 = path.grid.case_values()["alpha0"]
    np.testing.assert_array_equal(contact["found"], alpha0 == 0.6)
    assert np.all(contact["stage"][contact["found"]] == 2)
    lateral = secondary_gaps(contact["u"][contact["found"]], alpha0[contact["found"]])[:, 1]
    assert np.abs(lateral).max() <= GAP_TOL


# --- 3. step options --------------------------------------------------------------------------------


def test_max_steps_counts_steps_not_their_pieces():
    """At most 3 steps as long as the tolerances allow (max_step 0.5), each stored in pieces
    of at most sample_step = 0.02: the cases that need more fail with max_steps after
    exactly 3 accepted steps, having stored more than the start and 3 states; the others
    finish at Delta_1* = 0.2 (to 1e-9: the stage end located to event_tol)."""
    options = PathOptions(max_step=0.5, sample_step=0.02, max_steps=3)
    path = follow(IGNORE, "mcnamara", UNIAXIAL, UNIAXIAL_GRID, options)
    result = path.results[0]
    failed = result.status == "failed:max_steps"
    assert 0 < failed.sum() < failed.size, result.status
    assert np.all(result.status[~failed] == "finished")
    assert np.all(result.counters["accepted"][failed] == 3), result.counters["accepted"]
    assert (result.n_steps[failed] > 4).all(), result.n_steps
    assert all("max_steps = 3" in message for message in result.message[failed])
    assert np.nanmax(np.diff(result.steps["s"], axis=1)) <= 0.02 * (1 + 1e-12)
    ends = result.steps["u"][np.arange(failed.size), result.n_steps - 1, 0]
    np.testing.assert_allclose(ends[~failed], 0.2, rtol=0, atol=1e-9)


def test_a_step_that_would_fall_below_min_step_fails_its_case_alone():
    """Steps of 0.1 that cannot shrink below 0.03: where a step is rejected and its
    shortened retry would fall below min_step, the case fails with step_size_underflow
    (its message says so), its stored states finite and short of the target; its
    neighbours in the batch finish at Delta_1* = 0.6 (to 1e-9: the stage end located to
    event_tol)."""
    grid = {"gamma": [0.1, 0.5, 1.0, 1.9], "alpha0": ALPHA0, "F2_lateral": [0.0, 0.4, 0.75]}
    path = follow(IGNORE, "mcnamara", PRELOAD, grid, PathOptions(initial_step=0.1, max_step=0.1, min_step=0.03))
    result = path.results[0]
    failed = result.status == "failed:step_size_underflow"
    assert 0 < failed.sum() < failed.size, result.status
    assert np.all(result.status[~failed] == "finished")
    last = result.n_steps - 1
    ends = result.steps["u"][np.arange(failed.size), last, 0]
    np.testing.assert_allclose(ends[~failed], 0.6, rtol=0, atol=1e-9)
    for k in np.flatnonzero(failed):
        assert "fell below min_step" in result.message[k], result.message[k]
        assert np.isfinite(result.steps["u"][k, : last[k] + 1]).all()
        assert ends[k] < 0.6 - 1e-3


# --- 4. a case's result does not depend on its batch --------------------------------------------


@pytest.mark.parametrize("law", ["mcnamara", "cundall_strack"])
@pytest.mark.parametrize(("gamma", "f2"), [(0.5, 0.75), (1.9, 0.0), (0.1, 0.8)])
def test_compiled_case_alone_equals_the_case_in_a_batch_of_64(law, gamma, f2):
    batch_path = run(law, "preload")
    assert batch_path.results[0].status.size == 64
    result, k = batch_path.case(law, gamma=gamma, F2_lateral=f2)
    alone = follow(IGNORE, law, PRELOAD, {"gamma": gamma, "alpha0": ALPHA0, "F2_lateral": f2}, PathOptions())
    expected, got = one_case(result, k), one_case(alone.results[0], 0)
    assert set(got) == set(expected)
    for key in expected:
        np.testing.assert_array_equal(got[key], expected[key], err_msg=key)


# --- 5. options, the engine named, the cache --------------------------------------------------


def test_the_dataset_records_which_engine_ran_each_law():
    """``engine`` attribute: the compiled stepper with numba's version, for each law (the
    pure-shear limit too, on the general models' loop)."""
    import numba

    laws = ["cundall_strack", "mcnamara+no_tension"]
    grid = {"gamma": [0.5, 2.0], "alpha0": ALPHA0}
    path = follow(IGNORE, laws, UNIAXIAL, grid)
    parts = dict(part.split(": ", 1) for part in path.to_dataset().attrs["engine"].split("; "))
    assert list(parts) == laws
    for law in laws:
        assert parts[law].startswith("compiled stepper (numba "), parts[law]
        assert f"numba {numba.__version__}" in parts[law], parts[law]
    rigid = SystemSpec(normal="rigid", secondary_contacts="ignore")
    pure_shear = [{"hold": {"F2": 0.0}, "drive": {"F1": 1.0}}]
    on_rigid = follow(rigid, ["mcnamara", "cundall_strack"], pure_shear, {"alpha0": [0.7, ALPHA0]})
    parts = dict(part.split(": ", 1) for part in on_rigid.to_dataset().attrs["engine"].split("; "))
    assert list(parts) == ["mcnamara", "cundall_strack"]
    for law in ("mcnamara", "cundall_strack"):
        assert parts[law].startswith("compiled stepper (numba "), parts[law]


def test_without_numba_the_engine_asks_for_it(monkeypatch):
    """numba is a core dependency: an install without it gets a sentence saying what to
    install, with the default options (there is no other engine to fall back on)."""
    import ncstab.paths.compiled as compiled_module

    monkeypatch.setattr(compiled_module, "NUMBA_AVAILABLE", False)
    with pytest.raises(RuntimeError, match=r"numba, a dependency of ncstab that is not installed here: pip install numba"):
        follow(IGNORE, "mcnamara", UNIAXIAL, {"gamma": 0.5, "alpha0": ALPHA0}, PathOptions())


def test_backend_option_is_validated():
    assert PathOptions().backend == "auto"
    assert PathOptions(backend="compiled").backend == "compiled"
    assert PathOptions(backend="python").backend == "python"
    with pytest.raises(ValueError, match="backend"):
        PathOptions(backend="fortran")
    with pytest.raises(ValueError, match=r"PathOptions\.backend"):
        PathOptions(backend=3)


def test_the_retired_numpy_backend_is_an_error_that_says_so():
    """An old script or study file asking for the numpy stepper is told it was retired
    and what to do, in Python and as a study-file error naming the field (exit code 2)."""
    from ncstab.studies import StudyFileError, parse_study

    with pytest.raises(ValueError, match=r"the numpy stepper was retired.*remove the option"):
        PathOptions(backend="numpy")
    with pytest.raises(StudyFileError) as info:
        parse_study(STUDY + '[options]\nbackend = "numpy"\n', "study.toml")
    assert "options.backend" in info.value.fields
    assert "the numpy stepper was retired" in str(info.value)


STUDY = """\
[study]
name = "compiled"
[laws]
names = ["mcnamara"]
[parameters]
gamma = 0.5
[[loading]]
hold = { F2 = 0.0 }
drive = { D1 = 0.05 }
"""


def test_a_study_file_may_choose_the_compiled_backend():
    from ncstab.studies import parse_study

    study = parse_study(STUDY + '[options]\nbackend = "compiled"\n', "study.toml")
    assert study.options.backend == "compiled"
    assert parse_study(STUDY).options.backend == "auto"
    assert parse_study(STUDY + '[options]\nbackend = "auto"\n').options.backend == "auto"


@pytest.mark.parametrize("value", ["3", '"x"', '"fortran"', "true"])
def test_a_study_file_with_a_bad_backend_is_rejected_naming_the_field(value):
    from ncstab.studies import StudyFileError, parse_study

    with pytest.raises(StudyFileError) as info:
        parse_study(STUDY + f"[options]\nbackend = {value}\n", "study.toml")
    assert "options.backend" in info.value.fields, info.value.errors


def test_the_compiled_loop_is_cached_on_disk_once_for_every_law():
    """The loop's machine code is kept in one folder of the cache, named by a hash of the
    loop's modules (its three entry points, one index each, which holds the reduced
    diamond's code for every law); each law's kernel is a module of the cache folder, with
    numba's cache beside it."""
    from ncstab.cache import cache_directory
    from ncstab.engine_cache import engine_digest, engine_folder
    from ncstab.paths.loop_cases import run_cases
    from ncstab.paths.loop_records import DiamondModel
    from ncstab.paths.loop_route import machine_code_cached

    follow(SystemSpec(secondary_contacts="ignore"), "cundall_strack", [{"hold": {"F2": 0.0}, "drive": {"D1": 0.01}}],
           {"gamma": 1.0}, PathOptions())
    directory = cache_directory("compiled")
    assert engine_folder() == directory / f"engine_{engine_digest()}"
    entries = {p.name.split(".")[1].split("-")[0] for p in engine_folder().glob("*.nbi")}
    assert entries == {"run_cases", "start", "settle"}, entries
    assert machine_code_cached(run_cases, DiamondModel(rate_form=True))  # Cundall-Strack's form
    assert machine_code_cached(run_cases, DiamondModel(rate_form=False))  # the same code: a field of the record
    kernels = [sys.modules[m.stem] for m in directory.glob("ncstab_law_*.py") if m.stem in sys.modules]
    assert kernels and all(hasattr(module, "LAW") for module in kernels), kernels
    index = {p.name.split(".")[1].split("-")[0] for p in (directory / "__pycache__").glob("*.nbi")}
    assert "LAW" in index, index


def test_a_cache_directory_that_cannot_be_written_falls_back_to_a_temporary_one(tmp_path, monkeypatch):
    from ncstab.paths import compiled_source

    blocked = tmp_path / "file"
    blocked.write_text("not a directory")
    monkeypatch.setenv("NCSTAB_CACHE_DIR", str(blocked / "cache"))  # mkdir fails: a file is in the way
    (tmp_path / "tmp").mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(tmp_path / "tmp"))
    source = '"""A generated module."""\nVALUE = 42\n'
    module = compiled_source.load_module(source, "ncstab_test")
    assert module.VALUE == 42
    assert Path(module.__file__).parent.parent == tmp_path / "tmp"
    assert compiled_source.load_module(source, "ncstab_test") is module  # loaded once per process


def test_a_long_stage_grows_the_recorder_once_not_at_every_doubling(monkeypatch):
    """Paused cases (recorder full) get room for the rest of their stage at once, estimated
    from their progress in lambda: 200 states per case take one growth beyond the first
    call's, where doubling from 8 would take five.  The states are those of one case alone."""
    from ncstab.paths.recorder import Recorder

    growths = []
    reserve = Recorder.reserve

    def counting(self, needed, **kwargs):
        before = self.capacity
        reserve(self, needed, **kwargs)
        if self.capacity > before:
            growths.append(self.capacity)

    monkeypatch.setattr(Recorder, "reserve", counting)
    programme = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.2}}]
    options = PathOptions(max_step=0.002)
    grid = {"gamma": [0.5, 1.0, 1.5]}
    path = follow(IGNORE, "cundall_strack", programme, grid, options)
    steps = int(path.results[0].n_steps.max())
    assert steps > 100
    assert len(growths) <= 2, growths  # the first call's pause, then the estimate
    assert growths[-1] >= steps
    monkeypatch.setattr(Recorder, "reserve", reserve)
    alone = follow(IGNORE, "cundall_strack", programme, {"gamma": 1.0}, options).to_dataset()
    in_sweep = path.to_dataset()["u"].sel(gamma=1.0).values[0, : alone.sizes["step"]]
    np.testing.assert_array_equal(alone["u"].values[0], in_sweep)
