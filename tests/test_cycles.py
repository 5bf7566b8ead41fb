"""Closed kinematic cycles: Green's paradox (seed Introduction, Eq. 5, 9, 11, 13-29).

Both displacements are driven around a circle in the (Delta_1*, Delta_2*) plane;
the engine integrates the work per contact W = int F* . dDelta* / 2 (seed Eq. 5)
with the path and records it over every turn.  Over a closed cycle
(seed Eq. 9, 16)

    W = oint (-N dl + T l dalpha),

and with N = N(l) for every law of the catalogue the normal part vanishes.
Reference values come from scipy quadrature of the kinematics along the circle
(seed Eq. 1, 11), never from numbers the engine printed:

* hyperelastic laws: T l dalpha - N dl = dW (Eq. 17-19, 29), so W = 0 over any
  closed cycle and W(s) = W(l, alpha) - W(1, alpha0) along any path;
* Cundall--Strack (Eq. 13): dT = gamma l dalpha, T drifts by gamma I per turn,
  I = oint l dalpha, and turn k from rest costs gamma I^2 (k + 1/2);
* weakly hypoelastic (Eq. 27): T = gamma (alpha - alpha0), the forces come
  back, and every turn costs gamma oint (alpha - alpha0) l dalpha, with the sign
  of the direction.

See docs/green-paradox.md for the derivations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from matplotlib.figure import Figure
from scipy.integrate import dblquad, quad

from ncstab.laws import law_definition, make_law
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.plotting.cycles import (
    cycle_cases,
    cycle_force_drift_figure,
    cycle_paths_figure,
    cycle_work_figure,
)
from ncstab.plotting.style import law_display_name
from ncstab.symbolic import compile_law

ALPHA0 = math.pi / 4
SYSTEM = SystemSpec(secondary_contacts="ignore")
HYPERELASTIC = ("mcnamara", "turco", "mcnamara+no_tension", "turco+no_tension")

#: The lead's options for hyperelastic laws; max_step = 0.5 (about 13 steps per
#: turn) is enough for the work, which does not depend on the stored states.
HYPER_OPTIONS = PathOptions(rtol=1e-12, atol=1e-14, max_step=0.5)
#: For the hypoelastic laws the cycle work is a small net result of a work that
#: oscillates over the turn (|W| up to ~100 times the net), and the cycle end is
#: located in arclength to event_tol: rtol 1e-13, atol 1e-16 and event_tol 1e-13
#: bring the engine's error on W and T per turn to ~1e-11 relative (measured),
#: a margin of ~50 under the tolerances asserted below.
PRECISE_OPTIONS = PathOptions(rtol=1e-13, atol=1e-16, event_tol=1e-13, max_step=0.5)


# --- independent reference: the kinematics along the circle -----------------------------------


def circle_kinematics(
    lam: float, centre: np.ndarray, start: np.ndarray, direction: int
) -> tuple[float, float, float]:
    """(l*, alpha, l* dalpha/dlambda) at turned angle lambda on the circle through ``start``.

    The circle is centred at ``centre``, run counterclockwise in the
    (Delta_1*, Delta_2*) plane for direction = +1.  Seed Eq. (1):
    l cos(alpha) = cos(alpha0) - Delta_1, l sin(alpha) = sin(alpha0) - Delta_2;
    Eq. (11): l dalpha = sin(alpha) dDelta_1 - cos(alpha) dDelta_2.
    """
    radius = float(np.hypot(*(start - centre)))
    theta = math.atan2(start[1] - centre[1], start[0] - centre[0]) + direction * lam
    d1, d2 = centre[0] + radius * math.cos(theta), centre[1] + radius * math.sin(theta)
    dd1, dd2 = -direction * radius * math.sin(theta), direction * radius * math.cos(theta)
    x, y = math.cos(ALPHA0) - d1, math.sin(ALPHA0) - d2
    alpha = math.atan2(y, x)
    return math.hypot(x, y), alpha, math.sin(alpha) * dd1 - math.cos(alpha) * dd2


def loop_integral(integrand, centre, start, direction: int) -> float:
    """oint integrand(l*, alpha) l* dalpha over one turn, by adaptive quadrature.

    The integrand is smooth and periodic; epsrel = 1e-12 is reached without
    round-off warnings (pytest turns warnings into errors).
    """
    centre, start = np.asarray(centre, dtype=float), np.asarray(start, dtype=float)

    def f(lam: float) -> float:
        length, alpha, l_dalpha = circle_kinematics(lam, centre, start, direction)
        return integrand(length, alpha) * l_dalpha

    value, _ = quad(f, 0.0, 2 * math.pi, epsabs=0.0, epsrel=1e-12, limit=200)
    return value


def loop_I(centre, start, direction: int) -> float:
    """I = oint l* dalpha (not zero: l dalpha is not exact, seed Eq. 8)."""
    return loop_integral(lambda length, alpha: 1.0, centre, start, direction)


def loop_weakly(centre, start, direction: int) -> float:
    """oint (alpha - alpha0) l* dalpha: the weakly hypoelastic cycle work over gamma (Eq. 27)."""
    return loop_integral(lambda length, alpha: alpha - ALPHA0, centre, start, direction)


def cycle_stage_steps(result, case: int, stage: int) -> np.ndarray:
    """Indices of the stored states of one stage of one case."""
    n = int(result.n_steps[case])
    return np.flatnonzero(result.steps["stage"][case, :n] == stage)


# --- runs shared by several tests ----------------------------------------------------------------

#: Circles through u = 0 with centre (c1, c2): radii 0.05, 0.03, 0.05 and 0.03 * sqrt(2).
CENTRES_C1 = [0.05, -0.03]
CENTRES_C2 = [0.0, 0.04]


@pytest.fixture(scope="module")
def smooth_hyperelastic_path():
    """mcnamara and turco from rest, both directions, four circles: (path, cycle stages).

    2 turns counterclockwise around (c1, c2), then 2 clockwise around (c2, c1),
    a different circle through the same state; 8 cases (about 3 s).
    """
    path = follow(
        SYSTEM,
        ["mcnamara", "turco"],
        [
            {"cycle": {"center": ["c1", "c2"], "turns": 2, "direction": 1}},
            {"cycle": {"center": ["c2", "c1"], "turns": 2, "direction": -1}},
        ],
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0, "c1": CENTRES_C1, "c2": CENTRES_C2},
        HYPER_OPTIONS,
    )
    return path, (0, 1)


@pytest.fixture(scope="module")
def no_tension_path():
    """The no_tension hyperelastic laws across their kink: (path, cycle stages).

    A kinematic preload Delta_1* = 0.02 (a non-closed path), then one turn each
    way around (0, -0.02), a circle that crosses the kink N = 0 twice a turn,
    away from its start (tension where Delta_1* + Delta_2* < 0 near the origin).
    Each crossing costs ~50 rejected steps, hence one turn (about 10 s).
    """
    path = follow(
        SYSTEM,
        ["mcnamara+no_tension", "turco+no_tension"],
        [
            {"hold": {"D2": 0.0}, "drive": {"D1": 0.02}},
            {"cycle": {"center": [0.0, -0.02], "turns": 1, "direction": 1}},
            {"cycle": {"center": [0.0, -0.02], "turns": 1, "direction": -1}},
        ],
        {"gamma": [0.5, 2.0], "alpha0": ALPHA0},
        HYPER_OPTIONS,
    )
    return path, (1, 2)


@pytest.fixture(
    params=["smooth_hyperelastic_path", "no_tension_path"], ids=["smooth", "no_tension"]
)
def hyperelastic_path(request):
    """Each hyperelastic run in turn (the runs themselves are module fixtures)."""
    return request.getfixturevalue(request.param)


@pytest.fixture(scope="module", params=[1, -1], ids=["counterclockwise", "clockwise"])
def hypoelastic_path(request):
    """Cundall--Strack and weakly hypoelastic from rest, 3 turns, one direction (about 3 s)."""
    direction = request.param
    path = follow(
        SYSTEM,
        ["cundall_strack", "weakly_hypoelastic"],
        [{"cycle": {"center": ["c1", "c2"], "turns": 3, "direction": direction}}],
        {"gamma": [0.5, 0.8], "alpha0": ALPHA0, "c1": [0.05, 0.03], "c2": [0.0, -0.04]},
        PRECISE_OPTIONS,
    )
    return direction, path


def hypoelastic_cases():
    for gamma in (0.5, 0.8):
        for c1 in (0.05, 0.03):
            for c2 in (0.0, -0.04):
                yield gamma, c1, c2


@pytest.fixture(scope="module")
def preloaded_path():
    """A lateral preload (F1 = 0, F2 driven to 0.1), then 2 clockwise turns (about 4 s)."""
    return follow(
        SYSTEM,
        ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"],
        [
            {"hold": {"F1": 0.0}, "drive": {"F2": 0.1}},
            {"cycle": {"center": [0.05, 0.0], "turns": 2, "direction": -1}},
        ],
        {"gamma": [0.5, 1.0], "alpha0": ALPHA0},
        PRECISE_OPTIONS,
    )


@pytest.fixture(scope="module")
def study_dataset():
    """A small green_paradox study: four laws, two radii, 2 turns each way (about 3 s)."""
    path = follow(
        SYSTEM,
        ["cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"],
        [
            {"cycle": {"center": ["radius", 0.0], "turns": 2, "direction": 1}},
            {"cycle": {"center": ["radius", 0.0], "turns": 2, "direction": -1}},
        ],
        {"gamma": 0.5, "alpha0": ALPHA0, "radius": [0.03, 0.06]},
        PathOptions(rtol=1e-12, atol=1e-14, event_tol=1e-13, max_step=0.5),
    )
    return path.to_dataset()


# --- the reference itself ------------------------------------------------------------------------


@pytest.mark.parametrize("centre", [(0.05, 0.0), (0.03, -0.04), (-0.02, 0.06)])
def test_the_loop_integrals_are_area_integrals_over_the_disc(centre):
    # Green's theorem in the plane of (x, y) = (cos a0 - D1, sin a0 - D2) = l (cos a, sin a),
    # where dalpha dl = dx dy / l (the map D -> (x, y) is a half-turn: it keeps the
    # orientation):  oint l dalpha = iint dA / l  and
    # oint (alpha - alpha0) l dalpha = iint (alpha - alpha0) / l dA over the disc,
    # counterclockwise.  Two independent quadratures of each loop integral, both
    # to ~1e-12, compared to 1e-10.
    centre = np.asarray(centre)
    radius = float(np.hypot(*centre))

    def polar(rho: float, theta: float) -> tuple[float, float]:
        d1, d2 = centre[0] + rho * math.cos(theta), centre[1] + rho * math.sin(theta)
        x, y = math.cos(ALPHA0) - d1, math.sin(ALPHA0) - d2
        return math.hypot(x, y), math.atan2(y, x)

    def area_integral(f) -> float:
        def integrand(rho: float, theta: float) -> float:
            length, alpha = polar(rho, theta)
            return rho * f(alpha) / length

        value, _ = dblquad(integrand, 0.0, 2 * math.pi, 0.0, radius, epsabs=0.0, epsrel=1e-12)
        return value

    area = area_integral(lambda alpha: 1.0)
    assert loop_I(centre, np.zeros(2), 1) == pytest.approx(area, rel=1e-10)
    assert loop_I(centre, np.zeros(2), -1) == pytest.approx(-area, rel=1e-10)
    moment = area_integral(lambda alpha: alpha - ALPHA0)
    assert loop_weakly(centre, np.zeros(2), 1) == pytest.approx(moment, rel=1e-10)
    assert loop_weakly(centre, np.zeros(2), -1) == pytest.approx(-moment, rel=1e-10)


# --- hyperelastic laws: no work over any closed cycle -------------------------------------------


def test_every_hyperelastic_case_finishes(hyperelastic_path):
    path, _ = hyperelastic_path
    assert (path.status == "finished").all(), path.message


def test_hyperelastic_laws_do_no_work_over_a_closed_cycle(hyperelastic_path):
    # W = oint dW = 0 (seed Eq. 17-19, 29).  The engine's W is integrated at
    # rtol 1e-12 on values up to ~1e-2 and kept consistent through the Newton
    # projection (residual <= 1e-12); measured |W| per cycle <= ~1e-14 here
    # (1e-17 with max_step 0.05), so 1e-12 is a bound with a margin of ~100.
    path, stages = hyperelastic_path
    turns = sum(path.programme.stages[k].turns for k in stages)
    for result in path.results:
        work = result.cycles["work"]
        assert work.shape == (path.grid.size, turns)
        assert np.all(np.abs(work) < 1e-12)


def test_hyperelastic_forces_and_tangential_force_return_over_a_cycle(hyperelastic_path):
    # F = F(u) for a law with a total form: the same u gives the same F.  The
    # states are Newton-projected to a residual of 1e-12; 1e-10 leaves a margin.
    path, _ = hyperelastic_path
    for result in path.results:
        assert np.all(np.abs(result.cycles["force_gap"]) < 1e-10)
        assert np.all(np.abs(result.cycles["tangential_drift"]) < 1e-10)


def test_the_no_tension_cycles_cross_the_kink(no_tension_path):
    # The no_tension runs are meant to test the kink N = 0: every turn has
    # states in tension (N = 0, contact open) and in compression.
    path, stages = no_tension_path
    for result in path.results:
        for case in range(path.grid.size):
            for stage in stages:
                normal = result.steps["N"][case, cycle_stage_steps(result, case, stage)]
                assert (normal == 0).any() and (normal > 1e-3).any()


def test_hyperelastic_work_is_the_stored_energy_difference_at_every_state(hyperelastic_path):
    # Along any path (every stored state ends a non-closed path from rest):
    # W(s) = W_int(l, alpha) - W_int(1, alpha0), per contact, like the energy
    # (seed Eq. 19, 29; compile_law gives W_int in units of k_n (2R)^2).  Over a
    # closed cycle both sides are zero.  |W| reaches ~1e-2; the integration error
    # is ~1e-14 (measured 2e-14 at most), asserted to 1e-12.
    path, stages = hyperelastic_path
    gammas = path.grid.case_values()["gamma"]
    for law_name, result in zip(path.laws, path.results):
        compiled = compile_law(law_definition(law_name))
        for case in range(path.grid.size):
            law = make_law(law_name, gamma=gammas[case], alpha0=ALPHA0)
            n = int(result.n_steps[case])
            l, alpha = result.steps["l"][case, :n], result.steps["alpha"][case, :n]
            stored = compiled.energy(law, l, alpha) - compiled.energy(law, 1.0, ALPHA0)
            work = result.steps["work"][case, :n]
            np.testing.assert_allclose(work, stored, rtol=0, atol=1e-12)
            assert np.max(np.abs(work)) > 1e-4  # the check is not vacuous
            # The closed cycle of each stage: total work = energy difference = 0,
            # and the per-turn works add up to it.
            first_turn = 0
            for stage in stages:
                steps = cycle_stage_steps(result, case, stage)
                total = work[steps[-1]] - work[steps[0]]
                energy_change = stored[steps[-1]] - stored[steps[0]]
                assert total == pytest.approx(energy_change, abs=1e-12)
                assert abs(total) < 1e-12
                turns = path.programme.stages[stage].turns
                per_turn = result.cycles["work"][case, first_turn : first_turn + turns]
                assert per_turn.sum() == pytest.approx(total, abs=1e-13)
                first_turn += turns


# --- Cundall--Strack: ratcheting and Green's paradox ---------------------------------------------


def test_cundall_strack_from_rest_does_work_gamma_I_squared_k_plus_half(hypoelastic_path):
    # Turn k (k = 0, 1, ...) starts with T_k = k gamma I (from rest), and along
    # the turn T = T_k + gamma J(lambda), J = int_0^lambda l dalpha, so
    # W_k = oint T l dalpha = T_k I + gamma I^2 / 2 = gamma I^2 (k + 1/2)
    # (the normal part oint -N dl vanishes: N = -(l - 1)).  I by quadrature.
    # Engine error ~1e-11 relative (PRECISE_OPTIONS); asserted to 1e-9.
    direction, path = hypoelastic_path
    for gamma, c1, c2 in hypoelastic_cases():
        result, case = path.case("cundall_strack", gamma=gamma, c1=c1, c2=c2)
        I = loop_I((c1, c2), (0.0, 0.0), direction)
        expected = gamma * I**2 * (np.arange(3) + 0.5)
        np.testing.assert_allclose(result.cycles["work"][case], expected, rtol=1e-9)


def test_cundall_strack_tangential_force_drifts_by_gamma_I_per_turn(hypoelastic_path):
    # dT = gamma l dalpha (seed Eq. 13, dimensionless): T_end - T_start = gamma I,
    # the same on every turn.  At the closing state u, hence l, alpha and N, are
    # back, so F_end - F_start = 2 gamma I (sin alpha0, -cos alpha0) (Eq. 4).
    # Tolerance 1e-9 relative, engine error ~1e-12.
    direction, path = hypoelastic_path
    for gamma, c1, c2 in hypoelastic_cases():
        result, case = path.case("cundall_strack", gamma=gamma, c1=c1, c2=c2)
        I = loop_I((c1, c2), (0.0, 0.0), direction)
        assert np.sign(I) == direction  # I = iint dA / l > 0 counterclockwise
        drift = result.cycles["tangential_drift"][case]
        np.testing.assert_allclose(drift, np.full(3, gamma * I), rtol=1e-9)
        gap = 2 * gamma * I * np.array([math.sin(ALPHA0), -math.cos(ALPHA0)])
        np.testing.assert_allclose(
            result.cycles["force_gap"][case], np.tile(gap, (3, 1)), rtol=1e-9
        )


def test_cundall_strack_work_does_not_depend_on_the_direction():
    # I changes sign with the direction, the work gamma I^2 (k + 1/2) does not:
    # running the cycle either way from rest costs the same energy.
    runs = {}
    for direction in (1, -1):
        path = follow(
            SYSTEM,
            ["cundall_strack"],
            [{"cycle": {"center": [0.04, 0.02], "turns": 2, "direction": direction}}],
            {"gamma": 0.8, "alpha0": ALPHA0},
            PRECISE_OPTIONS,
        )
        runs[direction] = path.results[0].cycles
    I = loop_I((0.04, 0.02), (0.0, 0.0), 1)
    assert loop_I((0.04, 0.02), (0.0, 0.0), -1) == pytest.approx(-I, rel=1e-12)
    np.testing.assert_allclose(runs[1]["work"], runs[-1]["work"], rtol=1e-9)
    np.testing.assert_allclose(
        runs[1]["tangential_drift"], -runs[-1]["tangential_drift"], rtol=1e-9
    )
    np.testing.assert_allclose(runs[1]["work"][0], 0.8 * I**2 * np.array([0.5, 1.5]), rtol=1e-9)


# --- weakly hypoelastic: forces return, work does not --------------------------------------------


def test_weakly_hypoelastic_forces_return_after_every_turn(hypoelastic_path):
    # Total form (seed Eq. 27): F = F(u), so F and T are back after a turn.
    # No Newton projection residual above 1e-12 is accepted; asserted to 1e-10.
    _, path = hypoelastic_path
    result = path.results[path.laws.index("weakly_hypoelastic")]
    assert np.all(np.abs(result.cycles["force_gap"]) < 1e-10)
    assert np.all(np.abs(result.cycles["tangential_drift"]) < 1e-10)


def test_weakly_hypoelastic_work_is_the_same_nonzero_value_on_every_turn(hypoelastic_path):
    # The forces return, so every turn is the same turn: W_k = W_0, and
    # W_0 = gamma oint (alpha - alpha0) l dalpha (seed Eq. 9, 27) by quadrature.
    # Engine error ~2e-12 relative (PRECISE_OPTIONS); asserted to 1e-10.
    direction, path = hypoelastic_path
    for gamma, c1, c2 in hypoelastic_cases():
        result, case = path.case("weakly_hypoelastic", gamma=gamma, c1=c1, c2=c2)
        work = result.cycles["work"][case]
        expected = gamma * loop_weakly((c1, c2), (0.0, 0.0), direction)
        assert abs(expected) > 1e-5  # Green's paradox: not zero
        np.testing.assert_allclose(work, np.full(3, work[0]), rtol=1e-10)
        np.testing.assert_allclose(work, np.full(3, expected), rtol=1e-10)


def test_weakly_hypoelastic_work_changes_sign_with_the_direction():
    # W(-1) = -W(+1): the cycle run clockwise returns energy on every turn,
    # for ever (a perpetual-motion cycle).  Both to 1e-10 relative.
    works = {}
    for direction in (1, -1):
        path = follow(
            SYSTEM,
            ["weakly_hypoelastic"],
            [{"cycle": {"center": [0.05, 0.03], "turns": 2, "direction": direction}}],
            {"gamma": 0.5, "alpha0": ALPHA0},
            PRECISE_OPTIONS,
        )
        works[direction] = path.results[0].cycles["work"][0]
    expected = 0.5 * loop_weakly((0.05, 0.03), (0.0, 0.0), 1)
    np.testing.assert_allclose(works[1], [expected, expected], rtol=1e-10)
    np.testing.assert_allclose(works[-1], [-expected, -expected], rtol=1e-10)


# --- a cycle after a preload ----------------------------------------------------------------------


def test_every_preloaded_case_finishes(preloaded_path):
    assert (preloaded_path.status == "finished").all(), preloaded_path.message


def test_a_cycle_after_a_preload_passes_through_the_preloaded_state_and_closes(preloaded_path):
    # The cycle stage starts where the preload ended (the same integrated
    # state, re-evaluated: equal to round-off), every state of the cycle lies on
    # the circle (kinematic control; Newton residual 1e-12 for total forms,
    # integration error ~1e-13 for Cundall--Strack: asserted to 1e-10), and the
    # turned angle ends at 2 pi turns (cycle end located to event_tol 1e-13).
    centre = np.array([0.05, 0.0])
    for result in preloaded_path.results:
        for case in range(result.n_steps.size):
            preload, cycle = cycle_stage_steps(result, case, 0), cycle_stage_steps(result, case, 1)
            u = result.steps["u"][case]
            last, first = preload[-1], cycle[0]
            assert first == last + 1
            for name in ("u", "F", "T", "N", "work", "l", "alpha"):
                np.testing.assert_allclose(
                    result.steps[name][case, first],
                    result.steps[name][case, last],
                    rtol=0,
                    atol=1e-15,
                )
            assert result.steps["F"][case, last] == pytest.approx([0.0, 0.1], abs=1e-12)
            radius = np.hypot(*(u[first] - centre))
            assert radius > 0.05  # the preload moved the state off the origin
            distance = np.hypot(*(u[cycle] - centre).T)
            np.testing.assert_allclose(distance, radius, rtol=0, atol=1e-10)
            np.testing.assert_allclose(u[cycle[-1]], u[first], rtol=0, atol=1e-10)
            assert result.steps["lam"][case, cycle[-1]] == pytest.approx(4 * math.pi, abs=1e-10)


def test_cundall_strack_after_a_preload_does_work_T_start_I_plus_half_gamma_I_squared(
    preloaded_path,
):
    # From a preloaded state with tangential force T_p the turn k starts with
    # T_k = T_p + k gamma I, and W_k = T_k I + gamma I^2 / 2 (the derivation of
    # docs/green-paradox.md for any start).  I by quadrature around the circle
    # through the preloaded state; tolerance as from rest (1e-9 relative).
    centre = np.array([0.05, 0.0])
    result = preloaded_path.results[preloaded_path.laws.index("cundall_strack")]
    for gamma in (0.5, 1.0):
        _, case = preloaded_path.case("cundall_strack", gamma=gamma)
        first = cycle_stage_steps(result, case, 1)[0]
        start = result.steps["u"][case, first]
        t_start = result.steps["T"][case, first]
        assert abs(t_start) > 1e-3  # the preload did load the contact tangentially
        I = loop_I(centre, start, -1)
        t_k = t_start + gamma * I * np.arange(2)
        np.testing.assert_allclose(
            result.cycles["work"][case], t_k * I + gamma * I**2 / 2, rtol=1e-9
        )
        np.testing.assert_allclose(
            result.cycles["tangential_drift"][case], [gamma * I] * 2, rtol=1e-9
        )


def test_after_a_preload_hyperelastic_cycles_do_no_work_and_weakly_hypoelastic_ones_do(
    preloaded_path,
):
    # Tolerances as from rest: 1e-12 absolute (hyperelastic), 1e-10 relative (weakly).
    centre = np.array([0.05, 0.0])
    for law in ("mcnamara", "turco"):
        result = preloaded_path.results[preloaded_path.laws.index(law)]
        assert np.all(np.abs(result.cycles["work"]) < 1e-12)
    result = preloaded_path.results[preloaded_path.laws.index("weakly_hypoelastic")]
    for gamma in (0.5, 1.0):
        _, case = preloaded_path.case("weakly_hypoelastic", gamma=gamma)
        start = result.steps["u"][case, cycle_stage_steps(result, case, 1)[0]]
        expected = gamma * loop_weakly(centre, start, -1)
        np.testing.assert_allclose(result.cycles["work"][case], [expected] * 2, rtol=1e-10)


# --- the Dataset ----------------------------------------------------------------------------------


def test_the_dataset_has_a_cycle_dimension_with_described_variables(study_dataset):
    ds = study_dataset
    assert ds.sizes["cycle"] == 4  # 2 turns + 2 turns
    np.testing.assert_array_equal(ds["cycle"].values, [1, 2, 3, 4])
    np.testing.assert_array_equal(ds["cycle_stage"].values, [0, 0, 1, 1])
    assert ds["cycle_work"].dims == ("law", "radius", "cycle")
    assert ds["cumulative_work"].dims == ("law", "radius", "cycle")
    assert ds["cycle_force_gap"].dims == ("law", "radius", "cycle", "dof")
    assert ds["cycle_T_drift"].dims == ("law", "radius", "cycle")
    for name in (
        "cycle_work",
        "cumulative_work",
        "cycle_force_gap",
        "cycle_T_drift",
        "cycle_stage",
    ):
        attrs = ds[name].attrs
        assert attrs["units"] == "1", name
        assert attrs["long_name"] and attrs["description"], name
    # cumulative_work is the running sum (the same additions: equal to round-off).
    np.testing.assert_allclose(
        ds["cumulative_work"].values,
        np.cumsum(ds["cycle_work"].values, axis=-1),
        rtol=1e-15,
        atol=0,
    )
    # Two turns one way, then two back along the same circle: Cundall--Strack
    # gives back what it took, turn by turn (T is unwound), so the total is 0.
    # Turn works ~1e-5..1e-4 integrated at rtol 1e-12: errors ~1e-14 per turn;
    # asserted to 1e-9 relative and 1e-12 absolute for the total.
    work = ds["cycle_work"].sel(law="cundall_strack").values
    np.testing.assert_allclose(work[:, 2:], -work[:, 1::-1], rtol=1e-9)
    total = ds["cumulative_work"].sel(law="cundall_strack").values[:, -1]
    np.testing.assert_allclose(total, 0, atol=1e-12)


def test_a_programme_without_cycle_stages_has_no_cycle_dimension():
    path = follow(
        SYSTEM,
        ["mcnamara"],
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.02}}],
        {"gamma": 0.5, "alpha0": ALPHA0},
        PathOptions(max_step=0.05),
    )
    ds = path.to_dataset()
    assert "cycle" not in ds.dims
    assert "cycle_stage" not in ds.coords
    for name in ("cycle_work", "cumulative_work", "cycle_force_gap", "cycle_T_drift"):
        assert name not in ds
    with pytest.raises(ValueError, match="no cycle stages"):
        cycle_work_figure(ds)


# --- figures --------------------------------------------------------------------------------------


def lines_with(ax, prefix: str) -> dict[str, object]:
    """Lines of an axes whose gid starts with ``prefix + ':'``, by the rest of the gid."""
    return {
        line.get_gid()[len(prefix) + 1 :]: line
        for line in ax.get_lines()
        if (line.get_gid() or "").startswith(prefix + ":")
    }


def legend_texts(figure: Figure) -> list[str]:
    return [text.get_text() for legend in figure.legends for text in legend.get_texts()]


def test_cycle_work_figure_plots_the_dataset_work(study_dataset, tmp_path):
    figure = cycle_work_figure(study_dataset)
    assert isinstance(figure, Figure)
    figure.savefig(tmp_path / "cycle_work.png")
    assert (tmp_path / "cycle_work.png").stat().st_size > 10_000
    (ax,) = figure.axes
    assert ax.get_yscale() == "log"
    assert "cycle number" in ax.get_xlabel()
    assert "W^*" in ax.get_ylabel() and "k_n(2R)^2" in ax.get_ylabel()
    cases, _ = cycle_cases(study_dataset)
    assert len(cases) == 8
    curves = lines_with(ax, "cycle_work_line")
    positive, negative = (
        lines_with(ax, "cycle_work_positive"),
        lines_with(ax, "cycle_work_negative"),
    )
    assert len(curves) == len(positive) == len(negative) == 8
    for case in cases:
        work = study_dataset["cycle_work"].sel(law=case.law, radius=case.swept["radius"]).values
        cycles = np.arange(1, 5)
        np.testing.assert_array_equal(curves[case.key].get_xdata(), cycles[work != 0])
        np.testing.assert_array_equal(curves[case.key].get_ydata(), np.abs(work[work != 0]))
        np.testing.assert_array_equal(positive[case.key].get_ydata(), work[work > 0])
        np.testing.assert_array_equal(negative[case.key].get_ydata(), -work[work < 0])
        # Sign by marker fill: filled positive, open negative.
        assert negative[case.key].get_markerfacecolor() in ("white", (1.0, 1.0, 1.0, 1.0))
    # Counterclockwise then clockwise: the weakly hypoelastic work flips sign.
    key = next(c.key for c in cases if c.law == "weakly_hypoelastic")
    np.testing.assert_array_equal(positive[key].get_xdata(), [1, 2])
    np.testing.assert_array_equal(negative[key].get_xdata(), [3, 4])
    # The round-off band bounds every hyperelastic value and is said to be one.
    (label,) = [t for t in ax.texts if t.get_gid() == "round_off_label"]
    assert "hyperelastic" in label.get_text() and "round-off" in label.get_text()
    bound = label.get_position()[1]
    hyper = study_dataset["cycle_work"].sel(law=["mcnamara", "turco"]).values
    assert np.all(np.abs(hyper) < bound) and bound <= 1e-12
    stages = [t.get_text() for t in ax.texts if t.get_gid() == "stage_label"]
    assert stages == ["stage 1: 2 turns counterclockwise", "stage 2: 2 turns clockwise"]
    texts = legend_texts(figure)
    for law in ("cundall_strack", "weakly_hypoelastic", "mcnamara", "turco"):
        assert law_display_name(law) in texts
    assert "radius = 0.03" in texts and "radius = 0.06" in texts


def test_cycle_paths_figure_draws_each_circle_once_in_both_planes(study_dataset, tmp_path):
    figure = cycle_paths_figure(study_dataset)
    figure.savefig(tmp_path / "cycle_paths.png")
    ax_u, ax_q = figure.axes
    assert "Delta_1^*" in ax_u.get_xlabel() and "Delta_2^*" in ax_u.get_ylabel()
    assert "alpha" in ax_q.get_xlabel() and "l^*" in ax_q.get_ylabel()
    # Kinematic control: every law follows the same circle, drawn once per radius.
    paths_u, paths_q = lines_with(ax_u, "cycle_path_u"), lines_with(ax_q, "cycle_path_alpha_l")
    assert len(paths_u) == len(paths_q) == 2
    stage = study_dataset["stage"]
    for line_u, line_q, radius in zip(paths_u.values(), paths_q.values(), (0.03, 0.06)):
        x, y = np.asarray(line_u.get_xdata()), np.asarray(line_u.get_ydata())
        # Only cycle-stage states (here every state), on the circle centred (radius, 0).
        np.testing.assert_allclose(np.hypot(x - radius, y), radius, rtol=0, atol=1e-10)
        reference = study_dataset.sel(law="cundall_strack", radius=radius)
        n = int(reference["n_steps"])
        assert np.all(np.isin(stage.sel(law="cundall_strack", radius=radius).values[:n], [0, 1]))
        np.testing.assert_array_equal(x, reference["u"].values[:n, 0])
        np.testing.assert_array_equal(np.asarray(line_q.get_xdata()), reference["alpha"].values[:n])
        np.testing.assert_array_equal(np.asarray(line_q.get_ydata()), reference["l"].values[:n])
    assert {"radius = 0.03", "radius = 0.06"} <= set(legend_texts(figure))


def test_cycle_force_drift_figure_shows_the_ratchet(study_dataset, tmp_path):
    figure = cycle_force_drift_figure(study_dataset)
    figure.savefig(tmp_path / "cycle_force_drift.png")
    axes = figure.axes
    assert len(axes) == 3
    assert [ax.get_ylabel().split("=")[0].strip() for ax in axes] == ["$F_1^*", "$F_2^*", "$T^*"]
    assert all("2R\\,k_n" in ax.get_ylabel() for ax in axes)
    assert "turns" in axes[-1].get_xlabel()
    cases, _ = cycle_cases(study_dataset)
    for ax, name in zip(axes, ("F1", "F2", "T")):
        curves, ends = (
            lines_with(ax, f"force_drift:{name}"),
            lines_with(ax, f"force_drift_ends:{name}"),
        )
        assert len(curves) == len(ends) == 8
        for case in cases:
            values = {"F1": case.F[:, 0], "F2": case.F[:, 1], "T": case.T}[name]
            y = np.asarray(curves[case.key].get_ydata())
            np.testing.assert_array_equal(y[np.isfinite(y)], values)
            # The ends of turns: 0, 1, 2 (stage 1) and 2, 3, 4 (stage 2).
            x_ends = np.asarray(ends[case.key].get_xdata())
            np.testing.assert_allclose(x_ends, [0, 1, 2, 2, 3, 4], atol=1e-9)
    # Cundall--Strack: T at the ends of turns steps by the recorded drift.
    ends = lines_with(axes[2], "force_drift_ends:T")
    for case in (c for c in cases if c.law == "cundall_strack"):
        t_ends = np.asarray(ends[case.key].get_ydata())
        steps = np.diff(t_ends[[0, 1, 2, 4, 5]])  # skip the repeated stage boundary
        drift = study_dataset["cycle_T_drift"].sel(law=case.law, radius=case.swept["radius"]).values
        np.testing.assert_allclose(steps, drift, rtol=0, atol=1e-14)
        assert drift[0] > 0 and drift[2] < 0  # up counterclockwise, back down clockwise


def test_cycle_figures_draw_from_an_archive_and_from_one_law(study_dataset, tmp_path):
    from ncstab.studies import open_study, write_dataset

    archive = write_dataset(study_dataset, tmp_path / "green.nc")
    reread = open_study(archive)
    one_law = study_dataset.sel(law=["cundall_strack"])
    for number, dataset in enumerate((reread, one_law)):
        for function in (cycle_work_figure, cycle_paths_figure, cycle_force_drift_figure):
            figure = function(dataset)
            figure.savefig(tmp_path / f"{function.__name__}_{number}.png")
    # A Figure given is drawn into and returned.
    given = Figure(figsize=(8, 5))
    assert cycle_work_figure(study_dataset, given) is given and len(given.axes) == 1
    # One law: the legend names it once and lists the radii.
    texts = legend_texts(cycle_work_figure(one_law))
    assert texts.count(law_display_name("cundall_strack")) == 1
    assert "radius = 0.03" in texts
