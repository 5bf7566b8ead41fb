"""DEM codes' shear updates on the diamond: each rule's class and its small-step limit.

Each code's update (``ncstab.laws.dem_updates``, transcribed from its source,
docs/dem-codes.md) is replayed along a smooth kinematic path of one contact
with n steps; its tangential force must tend, as n grows, to the seed law the
rule reduces to, integrated here independently (quadrature or scipy), at the
order the update's construction gives: first order for a linearised rotation
or a projection, second order for an exact rotation.  The laws the catalogue
ships for the rules that differ from the seed's are then followed on the
diamond against the seed laws they reduce to.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad, solve_ivp

from ncstab.laws import ALPHA, ALPHA0, GAMMA, L, N, T, law_definition
from ncstab.laws.dem_updates import RULES, replay
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.symbolic import classify

A0 = math.pi / 4
GAMMA_VALUE = 0.7

#: The rule -> (the law it reduces to as the step shrinks, the order of the update's error).
LIMITS = {
    "liggghts_history": ("cundall_strack", 1),
    "lammps_hooke_history": ("cundall_strack", 1),
    "lammps_granular_linear_history": ("cundall_strack", 2),
    "yade_avoid_ratcheting": ("weakly_hypoelastic", 1),
    "yade_plain": ("cundall_strack", 1),
    "mercurydpm_sliding_friction": ("cundall_strack", 1),
    "kratos_rotate_old_contact_forces": ("cundall_strack", 2),
    "esys_friction": ("esys", 1),
    "chrono_one_step": ("no tangential spring", 1),
}
#: The class of each limit, from the seed: Cundall-Strack's Eq. (8)/(13) strongly
#: hypoelastic, Eq. (26) weakly hypoelastic, T = 0 derives from W = (l - 1)^2 / 2.
EXPECTED_CLASS = {
    "cundall_strack": "strongly hypoelastic",
    "weakly_hypoelastic": "weakly hypoelastic",
    "dem_yade_avoid_ratcheting": "weakly hypoelastic",
    "dem_chrono_one_step": "hyperelastic",
}


def test_every_rule_has_a_limit():
    assert set(RULES) == set(LIMITS)


# --- one contact along a smooth path ---------------------------------------------------------


def length(s):
    return 1.0 - 0.05 * np.sin(np.pi * s)


def orientation(s):
    return A0 + 0.4 * s + 0.1 * np.sin(2 * np.pi * s)


def length_rate(s):
    return -0.05 * np.pi * np.cos(np.pi * s)


def orientation_rate(s):
    return 0.4 + 0.2 * np.pi * np.cos(2 * np.pi * s)


def branch(n: int) -> np.ndarray:
    s = np.linspace(0.0, 1.0, n + 1)
    return np.stack([length(s) * np.cos(orientation(s)), length(s) * np.sin(orientation(s))], axis=-1)


def limit(name: str) -> tuple[float, float]:
    """(T, N_s) at the end of the path for the continuous rule, computed independently."""
    if name == "cundall_strack":  # dT = gamma l dalpha (seed Eq. 13)
        value = quad(lambda s: length(s) * orientation_rate(s), 0, 1, epsabs=0, epsrel=1e-13)[0]
        return GAMMA_VALUE * value, 0.0
    if name == "weakly_hypoelastic":  # T = gamma (alpha - alpha0) (Eq. 26-27)
        return GAMMA_VALUE * (orientation(1.0) - A0), 0.0
    if name == "no tangential spring":
        return 0.0, 0.0
    # ESyS: a force G = N_s n - T t kept in the global frame, dG = -gamma l dalpha t:
    # with dn = t dalpha and dt = -n dalpha, dT = (gamma l + N_s) dalpha, dN_s = -T dalpha.
    solution = solve_ivp(
        lambda s, y: [(GAMMA_VALUE * length(s) + y[1]) * orientation_rate(s), -y[0] * orientation_rate(s)],
        (0.0, 1.0), [0.0, 0.0], method="DOP853", rtol=1e-13, atol=1e-15,
    )
    return float(solution.y[0, -1]), float(solution.y[1, -1])


@pytest.mark.parametrize("rule", sorted(LIMITS))
def test_each_rule_tends_to_its_limit_at_its_order(rule):
    # Errors at n = 250, 1000, 4000 steps: the error divides by 4^order per
    # 4 times more steps (observed orders within 0.1 of 1 or 2), and at n = 4000
    # it is below 5e-3 / 4000^(order - 1) relative to the tangential force reached.
    name, order = LIMITS[rule]
    tangential, extra = limit(name)
    scale = max(abs(tangential), GAMMA_VALUE * 0.1)
    errors = []
    for n in (250, 1000, 4000):
        t_values, n_values = replay(rule, branch(n), GAMMA_VALUE)
        errors.append(max(abs(t_values[-1] - tangential), abs(n_values[-1] - extra)) / scale)
    observed = [math.log(errors[k] / errors[k + 1], 4) for k in range(2)]
    assert all(abs(o - order) < 0.1 for o in observed), (rule, errors, observed)
    assert errors[-1] < 5e-3 / 4000 ** (order - 1), (rule, errors)


def test_the_codes_of_one_limit_differ_by_their_discrete_update_only():
    # At n = 100 the Cundall-Strack family spreads over ~1e-3 relative; at n = 10^4
    # it agrees to ~1e-5 (first order) -- the same law, different updates.
    finals = {n: {rule: replay(rule, branch(n), GAMMA_VALUE)[0][-1] for rule, (name, _) in LIMITS.items()
                  if name == "cundall_strack"} for n in (100, 10_000)}
    spread = {n: max(values.values()) - min(values.values()) for n, values in finals.items()}
    reference = limit("cundall_strack")[0]
    assert spread[100] > 5e-4 * reference
    assert spread[10_000] < 5e-5 * reference


def test_esys_does_not_reduce_to_cundall_strack():
    # Its force is not turned with the contact: the limit differs from Eq. (13) by
    # far more than the discretisation error, and a normal part appears.
    esys, esys_normal = limit("esys")
    cundall_strack, _ = limit("cundall_strack")
    assert abs(esys - cundall_strack) > 1e-2 * cundall_strack
    assert abs(esys_normal) > 1e-2 * cundall_strack
    t_values, n_values = replay("esys_friction", branch(4000), GAMMA_VALUE)
    assert abs(t_values[-1] - esys) < 1e-2 * abs(esys - cundall_strack)


def test_yades_fix_removes_the_ratchet_over_a_closed_cycle():
    # Around a closed kinematic cycle Cundall-Strack's T drifts by gamma oint l dalpha
    # (the ratchet the flag's name refers to); with avoidGranularRatcheting T comes
    # back (T = gamma (alpha - alpha0)), to O(1/n).
    s = np.linspace(0.0, 1.0, 4001)
    angle = 2 * np.pi * s
    d1, d2 = 0.05 - 0.05 * np.cos(angle), 0.05 * np.sin(angle)  # circle through u = 0
    x, y = math.cos(A0) - d1, math.sin(A0) - d2
    b = np.stack([x, y], axis=-1)
    drift = GAMMA_VALUE * np.sum(0.5 * (np.hypot(x[1:], y[1:]) + np.hypot(x[:-1], y[:-1]))
                                 * np.diff(np.unwrap(np.arctan2(y, x))))
    assert abs(drift) > 1e-3
    assert replay("kratos_rotate_old_contact_forces", b, GAMMA_VALUE)[0][-1] == pytest.approx(drift, rel=1e-5)
    assert abs(replay("yade_avoid_ratcheting", b, GAMMA_VALUE)[0][-1]) < 1e-3 * abs(drift)
    assert replay("yade_plain", b, GAMMA_VALUE)[0][-1] == pytest.approx(drift, rel=1e-3)


# --- classes ----------------------------------------------------------------------------------


@pytest.mark.parametrize("name", sorted(EXPECTED_CLASS))
def test_the_laws_of_the_rules_have_the_seeds_classes(name):
    assert classify(law_definition(name)).kind == EXPECTED_CLASS[name]


def test_yades_rule_is_eq26_in_rate_form():
    # dT = gamma dalpha: integrable (Frobenius holds), but D12 - D21 = -C_Na - (T + l C_Tl) = -T
    # for every initial state: weakly hypoelastic (docs/laws.md: rate laws are classified
    # for every initial state).
    result = classify(law_definition("dem_yade_avoid_ratcheting"))
    assert result.checks[0].holds
    assert sp.simplify(result.deciding_condition.residual + T) == 0


def test_chronos_rule_is_the_seed_laws_at_gamma_zero():
    result = classify(law_definition("dem_chrono_one_step"))
    assert sp.simplify(sp.diff(result.energy, L) + (1 - L)) == 0 and sp.diff(result.energy, ALPHA) == 0


def test_esys_rate_law_fails_frobenius_like_cundall_strack():
    # In (N, T) with N = 1 - l + N_s: dN = -dl - T dalpha, dT = (gamma l + N + l - 1) dalpha.
    # Frobenius (docs/laws.md) on the T row: D_alpha A_T - D_l B_T with A_T = 0 and
    # D_l B_T = dB_T/dl + A_N dB_T/dN = (gamma + 1) - 1 = gamma: residual -gamma, not 0.
    a = {N: sp.Integer(-1), T: sp.Integer(0)}
    b = {N: -T, T: GAMMA * L + N + L - 1}
    for force, expected in ((N, 0), (T, -GAMMA)):
        d_alpha_a = sp.diff(a[force], ALPHA) + sum(b[y] * sp.diff(a[force], y) for y in (N, T))
        d_l_b = sp.diff(b[force], L) + sum(a[y] * sp.diff(b[force], y) for y in (N, T))
        assert sp.simplify(d_alpha_a - d_l_b - expected) == 0
    assert ALPHA0 not in b[T].free_symbols


# --- the shipped laws on the diamond ------------------------------------------------------------

SYSTEM = SystemSpec(secondary_contacts="ignore")
OPTIONS = PathOptions(rtol=1e-12, atol=1e-14)


def test_yades_law_follows_the_weakly_hypoelastic_path():
    # YADE's default integrates dT = gamma dalpha from T = 0, i.e. T = gamma (alpha - alpha0)
    # exactly: the two laws reach the same state at the end of each stage (a located
    # target) to the engine's accuracy: measured <= 4e-13, asserted 1e-9.
    programme = [{"hold": {"F1": 0.0}, "drive": {"F2": 0.1}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.3}}]
    path = follow(SYSTEM, ["weakly_hypoelastic", "dem_yade_avoid_ratcheting"], programme,
                  {"gamma": [0.5, 2.0], "alpha0": A0}, OPTIONS)
    assert (path.status == "finished").all()
    weakly, yade = path.results
    for case in range(2):
        ends = []
        for result in (weakly, yade):
            stages = result.steps["stage"][case, : int(result.n_steps[case])]
            ends.append(list(np.flatnonzero(np.diff(stages) != 0)) + [len(stages) - 1])  # last state of each stage
        assert len(ends[0]) == len(ends[1]) == 2
        for k_weakly, k_yade in zip(*ends):
            for field in ("u", "F", "T"):
                np.testing.assert_allclose(yade.steps[field][case, k_yade], weakly.steps[field][case, k_weakly],
                                           rtol=0, atol=1e-9)


def test_chronos_law_follows_mcnamaras_path_at_gamma_zero():
    # Displacement-driven (T = 0 leaves F2 held singular at the start: det K = 4 gamma):
    # identical expressions N = 1 - l, T = 0, so identical paths (asserted 1e-12).
    programme = [{"hold": {"D2": 0.0}, "drive": {"D1": 0.05}}, {"hold": {"D1": "current"}, "drive": {"D2": 0.02}}]
    chrono = follow(SYSTEM, ["dem_chrono_one_step"], programme, {"gamma": 0.5, "alpha0": A0}, OPTIONS)
    seed = follow(SYSTEM, ["mcnamara"], programme, {"gamma": 0.0, "alpha0": A0}, OPTIONS)
    a, b = chrono.results[0], seed.results[0]
    np.testing.assert_array_equal(a.n_steps, b.n_steps)
    for field in ("u", "F", "N", "T"):
        np.testing.assert_allclose(np.nan_to_num(a.steps[field]), np.nan_to_num(b.steps[field]), rtol=0, atol=1e-12)


def test_a_code_replayed_on_the_diamonds_kinematics_gives_the_engines_tangential_force():
    # D2 held at 0 and D1 driven to 0.1: the kinematics are Eq. (1) alone; LIGGGHTS'
    # update with 20000 steps must give ncstab's Cundall-Strack T at the end to its
    # first-order error (~3e-6 here; asserted 2e-5 relative).
    path = follow(SYSTEM, ["cundall_strack"], [{"hold": {"D2": 0.0}, "drive": {"D1": 0.1}}],
                  {"gamma": GAMMA_VALUE, "alpha0": A0}, OPTIONS)
    result = path.results[0]
    final = float(result.steps["T"][0, int(result.n_steps[0]) - 1])
    d1 = np.linspace(0.0, 0.1, 20_001)
    b = np.stack([math.cos(A0) - d1, np.full_like(d1, math.sin(A0))], axis=-1)
    replayed = replay("liggghts_history", b, GAMMA_VALUE)[0][-1]
    assert final > 1e-3
    assert replayed == pytest.approx(final, rel=2e-5)
