"""The path engine against the seed's closed forms and independent computations.

Every reference value here is computed in this file, by hand-written formulas
of the seed (Challamel et al. 2022) or by scipy, never taken from the engine:

* equilibrium and the load-rotation closed forms, Eq. (49), (53), (58);
* the maximum of alpha of the McNamara chain, where Eq. (48) has a double root;
* Cundall--Strack paths integrated by ``solve_ivp`` from the rate form, Eq. (38);
* the limit point of Eq. (53) and the Hill / limit points of the weakly
  hypoelastic law, whose total form Eq. (27) makes F(u) explicit;
* a 1,000-case sweep against single-case runs;
* statuses, stop events and secondary contacts.

All quantities are dimensionless (seed Eq. 37).  Forces, displacements and K
entries are O(1) on these paths, so absolute tolerances are used throughout.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import KroghInterpolator
from scipy.optimize import brentq, minimize_scalar, newton, root

from ncstab import DiamondChain, make_law
from ncstab.operators import generalized_forces, tangent_operator
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.paths.programme import EVENTS

ALPHA0 = np.pi / 4
IGNORE = SystemSpec(secondary_contacts="ignore")
#: Uniaxial compression (seed Fig. 3-8, 12-13): F2 = 0, Delta_1* driven.
UNIAXIAL_END = 0.45
UNIAXIAL = [{"hold": {"F2": 0.0}, "drive": {"D1": UNIAXIAL_END}}]
#: Lateral preload F2* = F2l from rest, then Delta_1* driven with F2 held (seed Fig. 9-11).
PRELOAD_END = 0.6
PRELOADED = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2l"}},
    {"hold": {"F2": "current"}, "drive": {"D1": PRELOAD_END}},
]

#: Equilibrium tolerance.  Laws with a total form are Newton-projected onto
#: F(u) = prescribed values to newton_tol = 1e-12 (max norm) after every step
#: and at every located event; 1e-10 leaves two decades for the rounding of
#: the independent force evaluation (a few ulps of O(1) numbers).
EQUILIBRIUM_TOL = 1e-10


def case_states(path, law: str, **parameters: float):
    """(stored states, events, status) of one case, states cut to n_steps."""
    result, k = path.case(law, **parameters)
    n = int(result.n_steps[k])
    states = {key: value[k, :n] for key, value in result.steps.items()}
    events = {
        name: {field: values[k] for field, values in table.items()}
        for name, table in result.events.items()
    }
    return states, events, str(result.status[k])


# --- closed forms of the seed, written by hand -------------------------------------------------


def mcnamara_uniaxial_f1(alpha, gamma, alpha0, sign=-1.0):
    """Seed Eq. (48); the minus sign is Eq. (49), the branch through the unloaded state."""
    return (1 + sign * np.sqrt(1 + 4 * gamma * (alpha0 - alpha) / np.tan(alpha))) / np.cos(alpha)


def mcnamara_lateral_f1(alpha, f2, gamma, alpha0, sign=-1.0):
    """Seed Eq. (53) under a lateral force F2*."""
    b = np.sin(alpha) - f2 / 2 + f2 * np.cos(alpha) ** 2
    delta = b**2 + 2 * np.cos(alpha) * np.sin(alpha) * (
        -f2 * np.cos(alpha) * (1 - f2 / 2 * np.sin(alpha)) + 2 * gamma * (alpha0 - alpha)
    )
    return (b + sign * np.sqrt(delta)) / (np.sin(alpha) * np.cos(alpha))


def turco_uniaxial_f1(alpha, gamma, alpha0):
    """Seed Eq. (58)."""
    s = np.sin(2 * alpha - alpha0)
    return (
        2
        * (s - np.sqrt(s**2 + gamma * np.sin(2 * alpha) * np.sin(2 * alpha0 - 2 * alpha)))
        / np.sin(2 * alpha)
    )


def cundall_strack_stiffness(u, forces, gamma, alpha0=ALPHA0):
    """Seed Eq. (38): K of the hypoelastic law at displacements u carrying forces F."""
    x, y = np.cos(alpha0) - u[0], np.sin(alpha0) - u[1]
    length, alpha = np.hypot(x, y), np.arctan2(y, x)
    c, s = np.cos(alpha), np.sin(alpha)
    f1, f2 = forces
    return np.array(
        [
            [
                2 * c * c + 2 * gamma * s * s - s / length * f2,
                2 * (1 - gamma) * c * s + c / length * f2,
            ],
            [
                2 * (1 - gamma) * c * s + s / length * f1,
                2 * s * s + 2 * gamma * c * c - c / length * f1,
            ],
        ]
    )


# --- module fixtures: each path is followed once -------------------------------------------------


@pytest.fixture(scope="module")
def uniaxial():
    """F2 = 0, Delta_1 driven to 0.45: three laws, gamma in {0.5, 2} (about 3 s)."""
    return follow(
        IGNORE,
        ["mcnamara", "turco", "cundall_strack"],
        UNIAXIAL,
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0},
    )


@pytest.fixture(scope="module")
def preloaded():
    """Preload F2l in {0.3, 0.75}, then Delta_1 driven to 0.6 (about 7 s)."""
    return follow(
        IGNORE,
        ["mcnamara", "weakly_hypoelastic", "cundall_strack"],
        PRELOADED,
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0, "F2l": [0.3, 0.75]},
    )


# --- 1. equilibrium and the closed forms --------------------------------------------------------


def assert_equilibrium(states, law: str, gamma: float) -> None:
    """Stored F equals the law's total-form forces recomputed from the stored u."""
    law_instance = make_law(law, gamma=gamma, alpha0=ALPHA0)
    recomputed = generalized_forces(DiamondChain(alpha0=ALPHA0), law_instance, states["u"])
    np.testing.assert_allclose(states["F"], recomputed, rtol=0, atol=EQUILIBRIUM_TOL)


@pytest.mark.parametrize("gamma", [0.5, 2.0])
def test_mcnamara_uniaxial_is_in_equilibrium_and_follows_eq49(uniaxial, gamma):
    states, _, status = case_states(uniaxial, "mcnamara", gamma=gamma)
    assert status == "finished"
    assert_equilibrium(states, "mcnamara", gamma)
    # The held force stays at its value (Newton projection to 1e-12).
    np.testing.assert_allclose(states["F"][:, 1], 0.0, rtol=0, atol=EQUILIBRIUM_TOL)
    # The stage ends on its target: located to event_tol = 1e-10 in arclength,
    # |dDelta_1/ds| <= 1, then projected; 1e-9 covers both.
    assert abs(states["u"][-1, 0] - UNIAXIAL_END) < 1e-9
    # Eq. (49) on the branch through the unloaded state: before alpha's maximum
    # (the whole path for gamma = 0.5; seed Fig. 8: a maximum only for gamma > 1).
    before = slice(0, int(np.argmax(states["alpha"])))
    assert before.stop >= 20
    expected = mcnamara_uniaxial_f1(states["alpha"][before], gamma, ALPHA0)
    np.testing.assert_allclose(states["F"][before, 0], expected, rtol=0, atol=EQUILIBRIUM_TOL)
    assert states["F"][-1, 0] > 0.1  # compression was actually applied


@pytest.mark.parametrize("gamma", [0.5, 2.0])
@pytest.mark.parametrize("f2_preload", [0.3, 0.75])
def test_mcnamara_preloaded_is_in_equilibrium_and_follows_eq53(preloaded, gamma, f2_preload):
    states, _, status = case_states(preloaded, "mcnamara", gamma=gamma, F2l=f2_preload)
    assert status == "finished"
    assert_equilibrium(states, "mcnamara", gamma)
    stage, forces = states["stage"], states["F"]
    preload, compression = stage == 0, stage == 1
    assert preload.sum() >= 10 and compression.sum() >= 20
    # Stage 1: F1 held at 0, F2 is the driven quantity lambda, ending at F2l.
    np.testing.assert_allclose(forces[preload, 0], 0.0, rtol=0, atol=EQUILIBRIUM_TOL)
    np.testing.assert_allclose(
        forces[preload, 1], states["lam"][preload], rtol=0, atol=EQUILIBRIUM_TOL
    )
    # Stage 2: F2 held at its value 'current' = F2l.
    np.testing.assert_allclose(forces[compression, 1], f2_preload, rtol=0, atol=EQUILIBRIUM_TOL)
    # Eq. (53), minus sign, on the branch through the preloaded state (F1 = 0)
    # up to alpha's maximum; the plus sign after it.  Near that maximum (a fold:
    # the square root in Eq. 53 goes to zero) the closed form amplifies the
    # state's own residuals (F2 held to newton_tol, alpha rounded) by its
    # sensitivity |dF1/dF2|, which reaches ~1e2 there: the tolerance is scaled
    # by 1 + |dF1/dF2| (central difference, step 1e-7).
    alpha = states["alpha"][compression]
    f1 = forces[compression, 0]
    top = int(np.argmax(alpha))
    for branch, sign in ((slice(0, top), -1.0), (slice(top + 1, None), +1.0)):
        closed_form = mcnamara_lateral_f1(alpha[branch], f2_preload, gamma, ALPHA0, sign=sign)
        step = 1e-7
        sensitivity = (
            mcnamara_lateral_f1(alpha[branch], f2_preload + step, gamma, ALPHA0, sign=sign)
            - mcnamara_lateral_f1(alpha[branch], f2_preload - step, gamma, ALPHA0, sign=sign)
        ) / (2 * step)
        error = np.abs(f1[branch] - closed_form)
        assert np.all(error <= EQUILIBRIUM_TOL * (1 + np.abs(sensitivity))), error.max()


@pytest.mark.parametrize("gamma", [0.5, 2.0])
def test_turco_uniaxial_is_in_equilibrium_and_follows_eq58(uniaxial, gamma):
    states, _, status = case_states(uniaxial, "turco", gamma=gamma)
    assert status == "finished"
    assert_equilibrium(states, "turco", gamma)
    np.testing.assert_allclose(states["F"][:, 1], 0.0, rtol=0, atol=EQUILIBRIUM_TOL)
    before = slice(0, int(np.argmax(states["alpha"])))
    assert before.stop >= 20
    # Eq. (58) has 0/0 at alpha = alpha0 (the first state): start at the second.
    alpha = states["alpha"][1 : before.stop]
    np.testing.assert_allclose(
        states["F"][1 : before.stop, 0],
        turco_uniaxial_f1(alpha, gamma, ALPHA0),
        rtol=0,
        atol=EQUILIBRIUM_TOL,
    )


# --- 2. the maximum of alpha (seed Fig. 3-5) ---------------------------------------------------


def test_mcnamara_gamma2_passes_the_maximum_of_alpha_where_l_is_one_half(uniaxial):
    gamma = 2.0
    states, _, status = case_states(uniaxial, "mcnamara", gamma=gamma)
    assert status == "finished"
    # Eq. (48) has a double root where its discriminant vanishes:
    # tan(alpha) = 4 gamma (alpha - alpha0); the first root beyond alpha0 lies
    # before the minimum of tan(a) - 4 gamma (a - a0), at cos^2(a) = 1/(4 gamma).
    alpha_max = brentq(
        lambda a: np.tan(a) - 4 * gamma * (a - ALPHA0),
        ALPHA0,
        np.arccos(1 / np.sqrt(4 * gamma)),
        xtol=1e-15,
    )
    alpha, length, s, du = states["alpha"], states["l"], states["s"], states["du"]
    # No equilibrium state beyond the double root (Eq. 48 has no real solution);
    # 1e-12: the states are exact to the Newton tolerance.
    assert alpha.max() <= alpha_max + 1e-12
    # Rates along the path from the stored unit tangent, seed Eq. (10)-(11).
    dalpha = (np.sin(alpha) * du[:, 0] - np.cos(alpha) * du[:, 1]) / length
    dlength = -np.cos(alpha) * du[:, 0] - np.sin(alpha) * du[:, 1]
    turns = np.flatnonzero((dalpha[:-1] > 0) & (dalpha[1:] <= 0))
    assert turns.size == 1
    j = int(turns[0])
    assert 1 <= j <= s.size - 3
    # Hermite interpolation (values and slopes at 4 stored states, degree 7):
    # error O(h^8) with h <= max_step = 0.02, i.e. ~1e-13 here; 1e-10 is ample
    # and still 100x below the error of a plain cubic fit.
    nodes = np.arange(j - 1, j + 3)

    def hermite(values, slopes):
        data = np.empty(2 * nodes.size)
        data[0::2], data[1::2] = values[nodes], slopes[nodes]
        return KroghInterpolator(np.repeat(s[nodes], 2), data)

    alpha_of_s, length_of_s = hermite(alpha, dalpha), hermite(length, dlength)
    s_top = brentq(lambda x: alpha_of_s.derivatives(x, 2)[1], s[j], s[j + 1], xtol=1e-15)
    assert abs(alpha_of_s(s_top) - alpha_max) < 1e-10
    assert abs(length_of_s(s_top) - 0.5) < 1e-10  # l* = 1/2 exactly there (Eq. 46 with F1 = 1/cos)
    # The load keeps increasing through and after the maximum of alpha ...
    assert np.all(np.diff(states["F"][:, 0]) > 0)
    # ... and the later states follow the + branch of Eq. (48).  Close to the
    # double root the closed form amplifies the 1e-12 projection residual by
    # 1/sqrt(discriminant) ~ 1e3: still far below 1e-10.
    after = s > s_top
    assert after.sum() >= 5
    np.testing.assert_allclose(
        states["F"][after, 0],
        mcnamara_uniaxial_f1(alpha[after], gamma, ALPHA0, sign=+1.0),
        rtol=0,
        atol=EQUILIBRIUM_TOL,
    )


# --- 3. Cundall--Strack against solve_ivp ------------------------------------------------------

#: solve_ivp reference tolerances: 100x tighter than the engine's (rtol 1e-10).
IVP = {"method": "DOP853", "rtol": 1e-12, "atol": 1e-14, "dense_output": True}
#: Engine vs reference: the engine's local tolerance is rtol = 1e-10 per step
#: and Cundall--Strack is not projected (T is an internal variable), so global
#: errors of ~100 steps stay below ~1e-8; observed ~1e-11.
HYPOELASTIC_TOL = 1e-8


def integrate_compression(gamma, start_u, f2_held, d1_end):
    """F2 held, Delta_1 driven, seed Eq. (35), (38).

    d(D2, F1)/dD1 = (-K21/K22, K11 + K12 dD2/dD1).
    """

    def rate(d1, y):
        stiffness = cundall_strack_stiffness((d1, y[0]), (y[1], f2_held), gamma)
        dd2 = -stiffness[1, 0] / stiffness[1, 1]
        return [dd2, stiffness[0, 0] + stiffness[0, 1] * dd2]

    solution = solve_ivp(rate, (start_u[0], d1_end), [start_u[1], 0.0], **IVP)
    assert solution.success
    return solution


@pytest.mark.parametrize("gamma", [0.5, 2.0])
def test_cundall_strack_uniaxial_matches_solve_ivp(uniaxial, gamma):
    states, _, status = case_states(uniaxial, "cundall_strack", gamma=gamma)
    assert status == "finished"
    reference = integrate_compression(gamma, (0.0, 0.0), 0.0, UNIAXIAL_END)
    expected = reference.sol(states["u"][:, 0])
    np.testing.assert_allclose(states["u"][:, 1], expected[0], rtol=0, atol=HYPOELASTIC_TOL)
    np.testing.assert_allclose(states["F"][:, 0], expected[1], rtol=0, atol=HYPOELASTIC_TOL)
    np.testing.assert_allclose(states["F"][:, 1], 0.0, rtol=0, atol=HYPOELASTIC_TOL)
    assert abs(states["u"][-1, 0] - UNIAXIAL_END) < 1e-9


@pytest.mark.parametrize(("gamma", "f2_preload"), [(0.5, 0.3), (2.0, 0.3), (2.0, 0.75)])
def test_cundall_strack_preloaded_matches_solve_ivp(preloaded, gamma, f2_preload):
    states, events, status = case_states(preloaded, "cundall_strack", gamma=gamma, F2l=f2_preload)
    assert status == "finished"
    assert not events["turning_point"]["found"]  # Delta_1 monotone: it can be the ivp's variable
    stage, u, forces = states["stage"], states["u"], states["F"]
    preload, compression = stage == 0, stage == 1

    # Stage 1, independently: F1 = 0, F2 the variable, du/dF2 = K^{-1} (0, 1).
    def preload_rate(f2, y):
        return np.linalg.solve(cundall_strack_stiffness(y, (0.0, f2), gamma), [0.0, 1.0])

    first = solve_ivp(preload_rate, (0.0, f2_preload), [0.0, 0.0], **IVP)
    assert first.success
    np.testing.assert_allclose(
        u[preload], first.sol(forces[preload, 1]).T, rtol=0, atol=HYPOELASTIC_TOL
    )
    np.testing.assert_allclose(forces[preload, 0], 0.0, rtol=0, atol=HYPOELASTIC_TOL)

    # Stage 2 from the reference's own end state.
    second = integrate_compression(gamma, first.y[:, -1], f2_preload, PRELOAD_END)
    expected = second.sol(u[compression, 0])
    np.testing.assert_allclose(u[compression, 1], expected[0], rtol=0, atol=HYPOELASTIC_TOL)
    np.testing.assert_allclose(forces[compression, 0], expected[1], rtol=0, atol=HYPOELASTIC_TOL)
    np.testing.assert_allclose(forces[compression, 1], f2_preload, rtol=0, atol=HYPOELASTIC_TOL)


def test_cundall_strack_turns_back_where_controllability_is_lost(preloaded):
    """gamma = 0.5, F2l = 0.75: K22 vanishes (seed Eq. 35) and Delta_1 turns back there."""
    states, events, status = case_states(preloaded, "cundall_strack", gamma=0.5, F2l=0.75)
    assert status == "finished"
    turning, control = events["turning_point"], events["controllability_loss"]
    assert turning["found"] and control["found"] and turning["stage"] == 1
    # One root of one quantity: dlambda/ds is proportional to det K_SS = K22.
    assert abs(turning["s"] - control["s"]) < 1e-8  # both located to event_tol = 1e-10
    # K22 = 0 there: 1e-8 of K's scale (O(1)), the located state is exact to
    # the bracket width times |dK22/ds| = O(1).
    assert abs(turning["K"][1, 1]) < 1e-8
    np.testing.assert_allclose(
        turning["K"], cundall_strack_stiffness(turning["u"], turning["F"], 0.5), rtol=0, atol=1e-12
    )
    # Delta_1 is at a local maximum: stored states around it are below it.
    near = np.abs(states["s"] - turning["s"]) < 0.1
    assert near.sum() >= 3
    assert np.all(states["u"][near, 0] <= turning["u"][0] + 1e-12)


# --- 4. limit point of Eq. (53) -----------------------------------------------------------------


def test_mcnamara_limit_point_is_the_maximum_of_eq53(preloaded):
    gamma, f2_preload = 0.5, 0.75
    states, events, status = case_states(preloaded, "mcnamara", gamma=gamma, F2l=f2_preload)
    assert status == "finished"
    limit, hill = events["limit_point"], events["hill_loss"]
    assert limit["found"] and hill["found"] and limit["stage"] == 1
    assert limit["s_lower"] <= limit["s"] <= limit["s_upper"]
    assert limit["s_upper"] - limit["s_lower"] <= 1e-10  # PathOptions.event_tol
    # The maximum of Eq. (53) along the compression branch (minus sign): scan
    # the stage's range of alpha, then refine the bracket of the best point.
    alpha = states["alpha"][states["stage"] == 1]
    grid = np.linspace(alpha[0], alpha.max(), 2001)
    values = mcnamara_lateral_f1(grid, f2_preload, gamma, ALPHA0)
    best = int(np.argmax(values))
    assert 0 < best < grid.size - 1  # an interior maximum: a true limit load
    found = minimize_scalar(
        lambda a: -mcnamara_lateral_f1(a, f2_preload, gamma, ALPHA0),
        bounds=(grid[best - 1], grid[best + 1]),
        method="bounded",
        options={"xatol": 1e-12},
    )
    f1_max = -found.fun
    assert abs(f1_max - 1.42876955) < 1e-8  # the value quoted in the issue (seed Fig. 9-10)
    # dF1/dalpha = 0 at the maximum, so an alpha error of ~1e-6 costs only ~1e-12 in F1.
    assert abs(limit["F"][0] - f1_max) < 1e-9
    assert abs(limit["F"][1] - f2_preload) < EQUILIBRIUM_TOL
    # K is symmetric (hyperelastic, Eq. 41): det K = 0 and its smallest
    # eigenvalue = 0 at the same point.  Scale-free tolerances: the located
    # state is exact to the 1e-10 bracket, |d(det K)/ds| = O(|K|^2).
    stiffness = limit["K"]
    scale = np.linalg.norm(stiffness)
    assert abs(np.linalg.det(stiffness)) < 1e-8 * scale**2
    assert abs(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0]) < 1e-8 * scale
    assert abs(hill["s"] - limit["s"]) < 1e-8
    # Past the limit point the load decreases under Delta_1 control.
    after = states["s"] > limit["s"]
    assert after.sum() >= 3 and np.all(states["F"][after, 0] < limit["F"][0])


# --- 5. weakly hypoelastic: Hill's condition fails before the limit point ----------------------


def weakly_forces(u, gamma, alpha0=ALPHA0):
    """Total form Eq. (27) in Eq. (4): N = 1 - l, T = gamma (alpha - alpha0)."""
    x, y = np.cos(alpha0) - u[0], np.sin(alpha0) - u[1]
    length, alpha = np.hypot(x, y), np.arctan2(y, x)
    normal, tangential = 1 - length, gamma * (alpha - alpha0)
    return np.array(
        [
            2 * normal * np.cos(alpha) + 2 * tangential * np.sin(alpha),
            2 * normal * np.sin(alpha) - 2 * tangential * np.cos(alpha),
        ]
    )


def weakly_stiffness(u, gamma, alpha0=ALPHA0):
    """K = dF/d(l, alpha) . d(l, alpha)/du by hand (chain rule with Eq. 10-11)."""
    x, y = np.cos(alpha0) - u[0], np.sin(alpha0) - u[1]
    length, alpha = np.hypot(x, y), np.arctan2(y, x)
    c, s = np.cos(alpha), np.sin(alpha)
    normal, tangential = 1 - length, gamma * (alpha - alpha0)
    d_forces = np.array(
        [
            [-2 * c, -2 * normal * s + 2 * gamma * s + 2 * tangential * c],
            [-2 * s, 2 * normal * c - 2 * gamma * c + 2 * tangential * s],
        ]
    )
    d_contact = np.array([[-c, -s], [s / length, -c / length]])
    return d_forces @ d_contact


def test_weakly_hypoelastic_stiffness_by_hand_matches_finite_differences():
    """Guard for the reference of the next test: central differences, h = 1e-6,
    truncation error O(h^2) ~ 1e-12 plus rounding 1e-16/h ~ 1e-10."""
    u, h = np.array([0.1, 0.2]), 1e-6
    differences = np.column_stack(
        [
            (weakly_forces(u + h * e, 0.5) - weakly_forces(u - h * e, 0.5)) / (2 * h)
            for e in np.eye(2)
        ]
    )
    np.testing.assert_allclose(weakly_stiffness(u, 0.5), differences, rtol=0, atol=1e-8)


def test_weakly_hypoelastic_loses_hill_before_the_limit_point(preloaded):
    gamma, f2_preload = 0.5, 0.75
    states, events, status = case_states(
        preloaded, "weakly_hypoelastic", gamma=gamma, F2l=f2_preload
    )
    assert status == "finished"
    hill, limit = events["hill_loss"], events["limit_point"]
    assert hill["found"] and limit["found"] and hill["stage"] == 1 and limit["stage"] == 1
    assert hill["s"] < limit["s"]
    assert 2.2 < hill["s"] < 2.4 < limit["s"] < 2.5  # ~2.32 and ~2.41 (issue)
    # Engine forces and tangents equal the hand-written ones at every stored state.
    for u, forces, stiffness in zip(states["u"], states["F"], states["K"]):
        np.testing.assert_allclose(forces, weakly_forces(u, gamma), rtol=0, atol=EQUILIBRIUM_TOL)
        np.testing.assert_allclose(stiffness, weakly_stiffness(u, gamma), rtol=0, atol=1e-10)
    # K is far from symmetric here (Cauchy-elastic, not hyperelastic).
    skew = hill["K"][0, 1] - hill["K"][1, 0]
    assert abs(skew) > 0.1 * np.linalg.norm(hill["K"])

    # Independent path: preload by continuation in F2 (Newton at each level) ...
    def residual(v, level):
        return weakly_forces(v, gamma) - [0.0, level]

    def jacobian(v, level):
        return weakly_stiffness(v, gamma)

    u = np.zeros(2)
    for level in np.linspace(0.0, f2_preload, 16)[1:]:
        u = root(residual, u, args=(level,), jac=jacobian, tol=1e-14).x
        # (MINPACK may report that it cannot improve further: check the residual.)
        assert np.max(np.abs(residual(u, level))) < 1e-14

    # ... then the curve F2(u) = F2l parametrized by Delta_1, Delta_2 by Newton.
    def delta2(d1, guess):
        return newton(
            lambda d2: weakly_forces((d1, d2), gamma)[1] - f2_preload,
            guess,
            fprime=lambda d2: weakly_stiffness((d1, d2), gamma)[1, 1],
            tol=1e-15,
            maxiter=50,
        )

    def hill_eigenvalue(stiffness):
        return np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0]

    table, d2 = [], u[1]
    for d1 in np.arange(u[0], PRELOAD_END, 0.005):
        d2 = delta2(d1, d2)
        stiffness = weakly_stiffness((d1, d2), gamma)
        table.append((d1, d2, hill_eigenvalue(stiffness), np.linalg.det(stiffness)))
    table = np.array(table)

    def indicator(d1, column, guess):
        stiffness = weakly_stiffness((d1, delta2(d1, guess)), gamma)
        return hill_eigenvalue(stiffness) if column == 2 else np.linalg.det(stiffness)

    for column, event in ((2, hill), (3, limit)):
        sign_changes = np.flatnonzero(np.sign(table[:-1, column]) != np.sign(table[1:, column]))
        i = int(sign_changes[0])
        guess = table[i, 1]
        d1 = brentq(indicator, table[i, 0], table[i + 1, 0], args=(column, guess), xtol=1e-15)
        expected = np.array([d1, delta2(d1, guess)])
        # Located to 1e-10 in arclength (|du/ds| <= 1) on states exact to the
        # Newton tolerance; observed ~1e-11.
        np.testing.assert_allclose(event["u"], expected, rtol=0, atol=1e-8)


# --- 6. a sweep gives the single-case results ---------------------------------------------------


def test_a_1000_case_sweep_equals_single_case_runs():
    gammas = np.linspace(0.2, 2.0, 40)
    alpha0s = np.linspace(0.5, 1.1, 25)
    programme = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.3}}]
    # Tight tolerances and long steps: the step sizes are set by each case's
    # error estimate (not by max_step), so they differ from case to case and
    # any coupling between cases would change the step sequences.
    options = PathOptions(rtol=1e-12, atol=1e-14, max_step=0.1)
    sweep = follow(IGNORE, "mcnamara", programme, {"gamma": gammas, "alpha0": alpha0s}, options)
    assert sweep.status.shape == (1, 40, 25)
    assert np.all(sweep.status == "finished")
    batch = sweep.results[0]
    assert np.unique(batch.n_steps).size >= 5
    contact = batch.events["secondary_contact"]["found"]
    assert 0 < contact.sum() < contact.size  # both kinds of case are in the sweep
    rng = np.random.default_rng(20220712)
    picked = np.concatenate(
        [
            rng.choice(np.flatnonzero(contact), 5, replace=False),
            rng.choice(np.flatnonzero(~contact), 5, replace=False),
        ]
    )
    for flat in picked:
        i, j = np.unravel_index(flat, (gammas.size, alpha0s.size))
        single = follow(
            IGNORE, "mcnamara", programme, {"gamma": gammas[i], "alpha0": alpha0s[j]}, options
        )
        one, k = single.case("mcnamara")
        in_sweep, flat_index = sweep.case("mcnamara", gamma=gammas[i], alpha0=alpha0s[j])
        assert flat_index == flat
        # Every case's step sizes depend only on its own error estimates, so the
        # step sequences are the same; numbers may differ only where numpy's
        # vectorised transcendental functions round differently for different
        # array lengths (1 ulp, amplified by at most a few steps): 1e-13.
        assert one.n_steps[k] == in_sweep.n_steps[flat]
        assert one.status[k] == in_sweep.status[flat]
        n = one.n_steps[k]
        for key in ("s", "u", "F", "K", "lam", "work"):
            np.testing.assert_allclose(
                one.steps[key][k, :n], in_sweep.steps[key][flat, :n], rtol=0, atol=1e-13
            )
        for name, table in one.events.items():
            assert table["found"][k] == in_sweep.events[name]["found"][flat]
            if table["found"][k]:
                for field in ("s", "u", "F"):
                    np.testing.assert_allclose(
                        table[field][k], in_sweep.events[name][field][flat], rtol=0, atol=1e-13
                    )


# --- 8. statuses say what happened --------------------------------------------------------------


def test_a_case_leaving_the_domain_fails_while_its_neighbour_finishes():
    # Delta_1 = 1.2 > cos(alpha0): the top grain would pass the chain's centre (alpha -> pi/2).
    path = follow(
        IGNORE,
        "mcnamara",
        [{"hold": {"F2": 0.0}, "drive": {"D1": "D1_end"}}],
        {"gamma": 0.5, "alpha0": ALPHA0, "D1_end": [0.3, 1.2]},
    )
    assert path.status.tolist() == [["finished", "failed:left_domain"]]
    assert path.succeeded.tolist() == [[True, False]]
    message = path.message[0, 1]
    assert "admissible domain" in message and "stage 1" in message
    result = path.results[0]
    for k in range(2):
        n = result.n_steps[k]
        assert n >= 2
        for key in ("s", "u", "F", "l", "alpha", "K"):
            assert np.all(np.isfinite(result.steps[key][k, :n])), key  # never a silent NaN
    # The failed case stopped inside the domain, past Delta_1 = 0.3.
    last = result.steps["u"][1, result.n_steps[1] - 1]
    assert 0.3 < last[0] < np.cos(ALPHA0)


def test_stop_at_ends_the_case_on_the_located_event(preloaded):
    path = follow(
        IGNORE,
        "weakly_hypoelastic",
        [PRELOADED[0], {**PRELOADED[1], "stop_at": ["hill_loss"]}],
        {"gamma": 0.5, "alpha0": ALPHA0, "F2l": 0.75},
        PathOptions(max_step=0.05),
    )
    states, events, status = case_states(path, "weakly_hypoelastic")
    assert status == "stopped:hill_loss"
    assert "hill_loss" in path.message[0] and "stage 2" in path.message[0]
    hill = events["hill_loss"]
    assert hill["found"]
    # The last stored state is the event state itself.
    assert states["s"][-1] == hill["s"]
    for field in ("u", "F", "K", "l", "alpha"):
        np.testing.assert_array_equal(states[field][-1], hill[field])
    # The limit point comes later on this path: never reached.
    assert not events["limit_point"]["found"]
    # Stopping does not move the event: same point as on the full path, which
    # took different steps (max_step 0.02); both are exact to ~1e-10.
    _, full_events, _ = case_states(preloaded, "weakly_hypoelastic", gamma=0.5, F2l=0.75)
    np.testing.assert_allclose(hill["u"], full_events["hill_loss"]["u"], rtol=0, atol=1e-8)


def test_max_steps_fails_the_case():
    path = follow(
        IGNORE, "mcnamara", UNIAXIAL, {"gamma": 0.5, "alpha0": ALPHA0}, PathOptions(max_steps=5, max_step=0.02)
    )
    result = path.results[0]
    assert path.status.tolist() == ["failed:max_steps"]
    assert "max_steps = 5" in path.message[0]
    assert result.counters["accepted"][0] == 5
    assert result.n_steps[0] == 6  # the start and 5 accepted steps (of one piece each: h <= sample_step)
    assert np.all(np.isfinite(result.steps["u"][0]))


def test_holding_a_force_away_from_its_value_fails_the_stage_start():
    path = follow(
        IGNORE,
        "mcnamara",
        [
            {"hold": {"F2": 0.0}, "drive": {"D1": 0.05}},
            {"hold": {"F2": "F2_held"}, "drive": {"D1": 0.1}},
        ],
        {"gamma": 0.5, "alpha0": ALPHA0, "F2_held": [0.0, 0.3]},
    )
    assert path.status.tolist() == [["finished", "failed:bad_stage_start"]]
    message = path.message[0, 1]
    assert "stage 2" in message and "F2" in message
    result = path.results[0]
    # The failed case keeps its first stage, and ends there.
    n = result.n_steps[1]
    assert n >= 2 and np.all(result.steps["stage"][1, :n] == 0)
    assert abs(result.steps["u"][1, n - 1, 0] - 0.05) < 1e-9


def test_a_single_case_failing_at_the_first_stage_start_has_a_status():
    path = follow(
        IGNORE,
        "mcnamara",
        [{"hold": {"F2": 0.3}, "drive": {"D1": 0.1}}],
        {"gamma": 0.5, "alpha0": ALPHA0},
    )
    assert path.status.tolist() == ["failed:bad_stage_start"]
    assert "stage 1" in path.message[0] and "F2" in path.message[0]
    assert path.results[0].n_steps.tolist() == [0]
    dataset = path.to_dataset()  # an empty path is still a valid archive
    assert dataset.sizes["step"] == 0 and dataset["status"].values.tolist() == [
        "failed:bad_stage_start"
    ]


# --- 9. secondary contacts ----------------------------------------------------------------------

#: Top and bottom grains touch where 2 l cos(alpha) = 1, i.e. 2 (cos(alpha0) - Delta_1) = 1.
CONTACT_D1 = np.cos(ALPHA0) - 0.5
#: Gap at a located contact: bracket 1e-10 in s times |d gap/ds| <= 2, on
#: states exact to the Newton tolerance.
GAP_TOL = 1e-9


def test_secondary_contact_stop_ends_the_case_at_the_contact():
    path = follow(
        SystemSpec(secondary_contacts="stop"),
        "mcnamara",
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.3}}],
        {"gamma": 0.5, "alpha0": ALPHA0},
    )
    states, events, status = case_states(path, "mcnamara")
    assert status == "stopped:secondary_contact"
    contact = events["secondary_contact"]
    assert contact["found"]
    assert abs(2 * contact["l"] * np.cos(contact["alpha"]) - 1) < GAP_TOL
    assert 2 * contact["l"] * np.sin(contact["alpha"]) - 1 > 0.1  # the other pair is still apart
    assert abs(contact["u"][0] - CONTACT_D1) < GAP_TOL
    assert states["s"][-1] == contact["s"]
    np.testing.assert_array_equal(states["u"][-1], contact["u"])


def test_secondary_contact_activate_adds_the_spring_and_continues():
    kappas = [1.0, 3.0]
    path = follow(
        SystemSpec(secondary_contacts="activate"),
        "mcnamara",
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.3}}],
        {"gamma": 0.5, "alpha0": ALPHA0, "kappa": kappas},
    )
    assert path.status.tolist() == [["finished", "finished"]]
    law = make_law("mcnamara", gamma=0.5, alpha0=ALPHA0)
    for kappa in kappas:
        states, events, _ = case_states(path, "mcnamara", kappa=kappa)
        contact = events["secondary_contact"]
        assert contact["found"]
        assert abs(2 * contact["l"] * np.cos(contact["alpha"]) - 1) < GAP_TOL
        assert abs(contact["u"][0] - CONTACT_D1) < GAP_TOL
        assert abs(states["u"][-1, 0] - 0.3) < 1e-9  # continued to the target
        # F1 = law force + kappa <1 - 2 (cos(alpha0) - Delta_1)> at every state.
        law_only = generalized_forces(DiamondChain(alpha0=ALPHA0), law, states["u"])
        spring = kappa * np.maximum(1 - 2 * (np.cos(ALPHA0) - states["u"][:, 0]), 0.0)
        assert spring.max() > 0.1  # states well past the contact exist
        np.testing.assert_allclose(
            states["F"][:, 0], law_only[:, 0] + spring, rtol=0, atol=EQUILIBRIUM_TOL
        )
        np.testing.assert_allclose(states["F"][:, 1], 0.0, rtol=0, atol=EQUILIBRIUM_TOL)
        # Its tangent d(kappa <1 - 2 cos(alpha0) + 2 Delta_1>)/dDelta_1 = 2 kappa
        # adds to K11 past the contact, nothing before it.
        law_tangent = tangent_operator(DiamondChain(alpha0=ALPHA0), law, states["u"])
        overlap = 1 - 2 * (np.cos(ALPHA0) - states["u"][:, 0])
        spring_tangent = np.zeros_like(law_tangent)
        spring_tangent[:, 0, 0] = 2 * kappa * (overlap > 0)
        # On the kink itself (the located contact state, |overlap| ~ 1e-12) the
        # tangent is two-sided; the engine stores it with the contact closed
        # (the spring switches on at the located crossing).
        on_kink = np.abs(overlap) < 1e-9
        assert on_kink.sum() >= 1
        np.testing.assert_allclose(states["K"][~on_kink], (law_tangent + spring_tangent)[~on_kink], rtol=0, atol=1e-10)
        np.testing.assert_allclose(states["K"][on_kink, 0, 0], law_tangent[on_kink, 0, 0] + 2 * kappa, rtol=0, atol=1e-10)


def test_a_contact_that_opens_at_a_corner_follows_the_open_branch_into_its_side():
    """McNamara, gamma = 0.79, F2* = 0.58 held, D1* driven to 0.6: the left-right pair,
    closed since the preload, opens at D1* = 0.5994 where Delta2* comes back to
    sin(alpha0) - 1/2.  There the motion kept through the switch (F1* rising) would lead
    straight back into the closed side: F1* peaks at the corner and the open branch
    goes on with F1* falling.  The contacts chattered there (a step of ~event_tol each,
    ``max_steps`` spent, s stuck at 3.783251); now the open branch is followed into
    its own side to the target.  Checked against the model, not the engine: every
    stored state in equilibrium (law forces + the springs of the closed pairs,
    kappa <overlap>, EQUILIBRIUM_TOL), the pair open (overlap <= 0, to the gap's located 1e-9) at
    every state past the switch, and F1* falling there."""
    gamma, preload = 0.7909090909090909, 0.5818181818181819
    path = follow(
        SystemSpec(secondary_contacts="activate"),
        "mcnamara",
        [{"hold": {"F1": 0.0}, "drive": {"F2": preload}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}],
        {"gamma": gamma, "alpha0": ALPHA0},
        PathOptions(max_steps=2000),
    )
    states, _, status = case_states(path, "mcnamara")
    assert status == "finished"
    u, F = states["u"], states["F"]
    assert abs(u[-1, 0] - 0.6) < 1e-9
    law = make_law("mcnamara", gamma=gamma, alpha0=ALPHA0)
    overlap = 1 - 2 * (np.sin(ALPHA0) - u[:, 1])  # the left-right pair, kappa = 1
    open_at = int(np.flatnonzero(overlap > 1e-9)[-1]) + 1  # the corner, the open branch's first state
    assert 0.59 < u[open_at, 0] < 0.6 and (overlap[:open_at] > 0.0).sum() > 10
    assert (overlap[open_at:] <= 1e-9).all() and (overlap[-1] < -1e-3)
    # kappa = 1 on each closed pair: the top-bottom one closes in stage 2 (D1* > 0.207)
    expected = generalized_forces(DiamondChain(alpha0=ALPHA0), law, u)
    expected[:, 0] += np.maximum(1 - 2 * (np.cos(ALPHA0) - u[:, 0]), 0.0)
    expected[:, 1] += np.maximum(overlap, 0.0)
    np.testing.assert_allclose(F, expected, rtol=0, atol=EQUILIBRIUM_TOL)
    np.testing.assert_allclose(F[states["stage"] == 1, 1], preload, rtol=0, atol=EQUILIBRIUM_TOL)
    assert int(np.argmax(F[:, 0])) == open_at and (np.diff(F[open_at:, 0]) < 0).all()  # F1* peaks at the corner


@pytest.mark.parametrize("law_name", ["mcnamara+no_tension", "turco+no_tension"])
def test_a_no_tension_contact_pulled_by_a_force_fails_with_a_singular_control(law_name):
    """F2* driven to -0.3 (tension) with F1* held: the normal contact, touching at rest,
    opens at once, and on its open branch no force can be carried (N = 0, T = 0 at
    rest: K is singular, det of the force-controlled block 0).  The case fails
    there with ``singular_control``, at both gammas alike, the switch state
    stored (F = 0).  Before, the path ran off along the open branch (u* of -200
    with F = 0) until ``max_steps``, storing up to 50 states per step."""
    messages = []
    path = follow(
        SystemSpec(secondary_contacts="activate"), law_name, [{"hold": {"F1": 0.0}, "drive": {"F2": -0.3}}],
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0}, PathOptions(max_steps=50),
    )
    for gamma in (0.5, 2.0):
        states, _, status = case_states(path, law_name, gamma=gamma)
        assert status == "failed:singular_control"
        assert len(states["s"]) == 2 and np.abs(states["F"]).max() < 1e-12
        result, k = path.case(law_name, gamma=gamma)
        messages.append(str(result.message[k]))
    assert len(set(messages)) == 1 and messages[0].startswith("stage 1: a contact switch led onto a branch")


@pytest.mark.parametrize("law_name", ["mcnamara+no_tension", "turco+no_tension"])
def test_no_tension_contact_opens_and_closes_as_located_switches(law_name):
    """The no_tension kink (seed Eq. 59) is integrated as a piecewise-smooth
    system: pulled apart from rest (where the contact touches, delta = 0) the
    contact opens (N = 0, never tension), pushed back it closes again; every
    stored state carries exactly the law's forces and no step is rejected at
    the kink (the branch is frozen within a step, switched at the crossing).
    Steps of at most 0.1: longer ones grow while the contact is open (the chain
    moves force-free, the error is zero) and the first step on the closed branch
    is then rejected for its length, not for the kink."""
    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        law_name,
        [{"hold": {"F2": 0.0}, "drive": {"D1": -0.1}}, {"hold": {"F2": 0.0}, "drive": {"D1": 0.1}}],
        {"gamma": 0.5, "alpha0": ALPHA0},
        PathOptions(max_step=0.1),
    )
    result, k = path.case(law_name)
    n = result.n_steps[k]
    assert result.status[k] == "finished"
    assert result.counters["rejected"][k] == 0
    normal = result.steps["N"][k, :n]
    assert normal.min() >= 0.0  # no tension, ever
    assert (normal == 0).sum() >= 3 and (normal > 1e-3).sum() >= 3  # open, then closed again
    u = result.steps["u"][k, :n]
    law = make_law(law_name, gamma=0.5, alpha0=ALPHA0)
    # Equilibrium to 1e-10 (the Newton projection's tolerance, with margin).
    np.testing.assert_allclose(result.steps["F"][k, :n], generalized_forces(DiamondChain(alpha0=ALPHA0), law, u),
                               rtol=0, atol=1e-10)


def test_stop_at_limit_point_still_records_the_coincident_hill_loss():
    """For a hyperelastic law (K symmetric, seed Eq. 41) Hill's condition is lost
    at the limit point itself; stopping there must still record hill_loss (its
    root may land within event_tol past the stop point)."""
    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        "mcnamara",
        [{"hold": {"F1": 0.0}, "drive": {"F2": 0.75}},
         {"hold": {"F2": "current"}, "drive": {"D1": 0.6}, "stop_at": ["limit_point"]}],
        {"gamma": 0.5, "alpha0": ALPHA0},
    )
    result, k = path.case("mcnamara")
    assert result.status[k] == "stopped:limit_point"
    assert result.events["hill_loss"]["found"][k]
    # Both located to event_tol = 1e-10 in arclength: they agree to 2 brackets.
    assert abs(result.events["hill_loss"]["s"][k] - result.events["limit_point"]["s"][k]) < 2e-10


def test_a_long_step_past_a_target_near_the_domain_edge_finishes():
    """Soft Cundall-Strack (gamma = 0.1), F2* = 0, D1* driven to 0.6: alpha ends at
    1.47, near pi/2.  A step of up to max_step = 1 reaches past the target, out of
    the admissible domain; the target is crossed in an earlier piece of the step,
    which ends the stage there: the case finishes (the end of a step is checked
    against the domain only when its turn comes, PathOptions.sample_step), at the
    state that steps of at most 0.02 reach.  Before, the step's end was checked
    first and the case failed with left_domain."""
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": 0.0}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
    parameters = {"gamma": 0.1, "alpha0": ALPHA0}
    long = follow(IGNORE, "cundall_strack", programme, parameters, PathOptions(max_step=1.0))
    short = follow(IGNORE, "cundall_strack", programme, parameters, PathOptions(max_step=0.02))
    assert long.status.tolist() == ["finished"] == short.status.tolist()
    assert long.results[0].counters["accepted"][0] < short.results[0].counters["accepted"][0] / 3
    end_long, end_short = (p.to_dataset().isel(law=0) for p in (long, short))
    for name in ("u", "F", "alpha"):
        a = end_long[name].isel(step=int(end_long["n_steps"]) - 1).values
        b = end_short[name].isel(step=int(end_short["n_steps"]) - 1).values
        # two integrations to rtol 1e-10 of one path (measured 1e-10): 1e-8
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8, err_msg=name)
    assert abs(float(end_long["alpha"].isel(step=int(end_long["n_steps"]) - 1))) > 1.4


def test_sampled_and_long_steps_find_the_events_of_a_tight_reference():
    """Weakly hypoelastic, lateral preload F2* = 0.6 then D1* driven to 0.6, F2 held.
    At gamma = 0.5, alpha0 = 0.6 the path (D2* constant: K21 = 0 along it) meets a simple
    bifurcation point at s = 2.2592, where K22 and so det K and the mixed control's
    determinant vanish together (the cofactor tangent (K22, -K21, K22) passes through
    zero).  Before over steps (ncstab.paths.over_steps) the outcome there depended on the
    steps: the tight reference turned back (turning_point and controllability_loss),
    steps of up to 1 went straight on (a limit_point and controllability_loss).  Now every
    option set steps over the point along the branch it was on: the tight reference
    (steps of at most 0.002, rtol 1e-12), the default sampling (sign checks and stored
    states every 0.02 on long steps) and steps of up to 1 with their ends the only sign
    checks agree in every status, every event found (the point a `bifurcation`) and every
    end state; the events' arclengths agree: hill_loss to 1e-9 (measured 2e-11); the events at the bifurcation
    point to 5e-6 (measured 9e-7 for the default sampling: located on a DOP853
    interpolant through the point, where the field is singular).  (The case gamma = 0.1,
    alpha0 = pi/4 also failed once, left_domain where it finishes: its long step reached
    past the stage target and out of the domain; completed to the domain's edge,
    ncstab.paths.domain_edge, it ends at the target.)"""
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": 0.6}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}]
    parameters = {"gamma": [0.1, 0.5], "alpha0": [0.6, ALPHA0]}

    def run(options):
        return follow(IGNORE, "weakly_hypoelastic", programme, parameters, options).to_dataset().isel(law=0)

    reference = run(PathOptions(max_step=0.002, sample_step=None, rtol=1e-12, atol=1e-14))
    default = run(PathOptions())
    only_steps = run(PathOptions(max_step=1.0, sample_step=None))
    assert default["accepted_steps"].sum() < reference["accepted_steps"].sum() / 10
    events = [name for name in EVENTS if f"{name}_stage" in reference]
    found = {name: reference[f"{name}_stage"].values >= 0 for name in events}
    assert found["bifurcation"][1, 0] and found["controllability_loss"][1, 0]
    assert not found["turning_point"].any() and not found["limit_point"].any()
    for run_ in (default, only_steps):
        np.testing.assert_array_equal(run_["status"].values, reference["status"].values)
        last = run_["n_steps"] - 1
        np.testing.assert_allclose(run_["u"].isel(step=last).values,
                                   reference["u"].isel(step=reference["n_steps"] - 1).values, rtol=0, atol=1e-8)
        for name in events:
            np.testing.assert_array_equal(run_[f"{name}_stage"].values >= 0, found[name], err_msg=name)
            at_point = name in ("controllability_loss", "bifurcation")
            np.testing.assert_allclose(run_[f"{name}_s"].values, reference[f"{name}_s"].values, rtol=0,
                                       atol=5e-6 if at_point else 1e-9, err_msg=name)
    # (and no longer lose a case: the step out of the domain is completed to its edge, past the target)
    np.testing.assert_array_equal(only_steps["status"].values, reference["status"].values)
