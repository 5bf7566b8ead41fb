"""The seed's closed forms (ncstab.systems.closed_forms) against their own identities.

Each closed form is checked against an equation of the seed it was not written
from: a root of a quadratic against the quadratic (Eq. 52, 56), an expansion
against finite differences (Eq. 50), two equations that must agree (Eq. 48 and
53; Eq. 66-68).  Tolerances are stated where they are used, with why.
"""

from __future__ import annotations

import numpy as np
import pytest
from numpy.testing import assert_allclose

from ncstab.systems.closed_forms import (
    diamond_displacements,
    mcnamara_branch_length,
    mcnamara_load_rotation,
    mcnamara_turning_alpha,
    pure_shear_blocking_alpha,
    pure_shear_displacement,
    pure_shear_load_rotation,
    pure_shear_max_displacement,
    turco_branch_length,
    turco_load_rotation,
)

ALPHA0 = np.pi / 4
GAMMAS = [0.25, 0.5, 1.0, 2.0]


def eq48(alpha, gamma, alpha0, sign):
    """Seed Eq. (48), written by hand; NaN where the root is imaginary."""
    with np.errstate(invalid="ignore"):
        return (1 + sign * np.sqrt(1 + 4 * gamma * (alpha0 - alpha) / np.tan(alpha))) / np.cos(
            alpha
        )


def eq52_residual(F1, alpha, gamma, alpha0, F2):
    """Left-hand side of seed Eq. (52)."""
    s, c = np.sin(alpha), np.cos(alpha)
    return (
        -(F1**2) * s * c / 2
        + F1 * (s - F2 / 2 + F2 * c**2)
        - F2 * c * (1 - F2 / 2 * s)
        + 2 * gamma * (alpha0 - alpha)
    )


def eq56_residual(F1, alpha, gamma, alpha0):
    """Left-hand side of seed Eq. (56), last term as in Eq. (55) and (57): sin(2 a0 - 2 a)."""
    return (
        -np.sin(2 * alpha) * F1**2 / 4
        + F1 * np.sin(2 * alpha - alpha0)
        + gamma * np.sin(2 * alpha0 - 2 * alpha)
    )


# --- McNamara et al. (2008) ----------------------------------------------------------------


@pytest.mark.parametrize("gamma", GAMMAS)
def test_eq49_vanishes_at_alpha0_with_the_slope_of_eq50(gamma):
    assert mcnamara_load_rotation(ALPHA0, gamma, ALPHA0) == pytest.approx(0.0, abs=1e-15)
    # Central difference: truncation error h^2 |F'''| / 6 ~ 1e-10 and rounding
    # eps / h ~ 1e-11 for h = 1e-5; 1e-8 relative leaves a wide margin.
    h = 1e-5
    slope = (
        mcnamara_load_rotation(ALPHA0 + h, gamma, ALPHA0)
        - mcnamara_load_rotation(ALPHA0 - h, gamma, ALPHA0)
    ) / (2 * h)
    assert slope == pytest.approx(2 * gamma / np.sin(ALPHA0), rel=1e-8)


@pytest.mark.parametrize("branch", [-1, 1])
def test_eq53_with_no_lateral_force_is_eq48(branch):
    alpha = np.linspace(0.3, 1.3, 101)
    gamma = np.array(GAMMAS)[:, None]
    expected = eq48(alpha, gamma, ALPHA0, branch)
    got = mcnamara_load_rotation(alpha, gamma, ALPHA0, F2=0.0, branch=branch)
    assert got.shape == (len(GAMMAS), alpha.size)
    assert np.isfinite(got).sum() > 200
    # Same quantity written two ways (a common factor sin(alpha) cancelled):
    # a few ulps of O(1) to O(10) numbers.
    assert_allclose(got, expected, rtol=1e-13, atol=1e-13, equal_nan=True)


@pytest.mark.parametrize("F2", [-0.5, 0.0, 0.3, 0.75])
@pytest.mark.parametrize("branch", [-1, 1])
def test_eq53_solves_the_quadratic_eq52(F2, branch):
    alpha = np.linspace(0.1, 1.45, 200)
    gamma = np.array(GAMMAS)[:, None]
    F1 = mcnamara_load_rotation(alpha, gamma, ALPHA0, F2=F2, branch=branch)
    finite = np.isfinite(F1)
    assert finite.sum() > 100
    # Restricted to |F1*| <= 20, where the terms of Eq. (52) are O(100) at
    # most: rounding stays below 1e-12.
    keep = finite & (np.abs(F1) <= 20)
    residual = eq52_residual(F1, alpha, gamma, ALPHA0, F2)[keep]
    assert np.max(np.abs(residual)) < 1e-12


def test_eq53_is_nan_where_the_discriminant_is_negative():
    # gamma = 2, F2 = 0: the discriminant 1 + 4 gamma (a0 - a)/tan(a) is
    # negative just beyond the turning alpha.
    turning = float(mcnamara_turning_alpha(2.0, ALPHA0))
    assert np.isnan(mcnamara_load_rotation(turning + 0.05, 2.0, ALPHA0))
    assert np.isnan(mcnamara_load_rotation(turning + 0.05, 2.0, ALPHA0, branch=1))
    assert np.isfinite(mcnamara_load_rotation(turning - 0.05, 2.0, ALPHA0))
    with pytest.raises(ValueError, match="branch"):
        mcnamara_load_rotation(0.8, 2.0, ALPHA0, branch=0)


@pytest.mark.parametrize("gamma", [1.6, 2.0, 5.0])
def test_at_the_turning_alpha_the_branches_meet_and_l_is_one_half(gamma):
    turning = float(mcnamara_turning_alpha(gamma, ALPHA0))
    assert ALPHA0 < turning < np.pi / 2
    assert np.tan(turning) == pytest.approx(4 * gamma * (turning - ALPHA0), rel=1e-13)
    # At the double root F1* = 1/cos(alpha), whence l* = 1 - F1* cos(alpha)/2 = 1/2.
    # The discriminant is zero only to rounding (brentq to a few ulps of alpha,
    # and sqrt amplifies: sqrt(1e-16) = 1e-8), so F1* is taken as the mean of
    # the two branches, which equals b/(s c) exactly.
    lower = mcnamara_load_rotation(turning - 1e-9, gamma, ALPHA0, branch=-1)
    upper = mcnamara_load_rotation(turning - 1e-9, gamma, ALPHA0, branch=1)
    F1 = (lower + upper) / 2
    assert upper - lower < 1e-3
    assert F1 == pytest.approx(1 / np.cos(turning - 1e-9), rel=1e-13)
    assert mcnamara_branch_length(turning, 1 / np.cos(turning), 0.0) == pytest.approx(
        0.5, abs=1e-15
    )


def test_turning_alpha_is_nan_without_a_maximum_and_broadcasts():
    # Seed Fig. 8: alpha has a maximum only for the larger gamma (about 1.55 at alpha0 = pi/4).
    turning = mcnamara_turning_alpha(np.array([0.25, 1.5, 2.0]), ALPHA0)
    assert turning.shape == (3,)
    assert np.isnan(turning[0]) and np.isnan(turning[1]) and np.isfinite(turning[2])
    assert np.isnan(mcnamara_turning_alpha(0.0, ALPHA0))


def test_displacements_invert_the_kinematics_eq1():
    alpha = np.linspace(0.2, 1.4, 7)
    length = np.linspace(0.6, 1.1, 7)
    D1, D2 = diamond_displacements(alpha, length, ALPHA0)
    # Eq. (1): tan(alpha) and l recovered from the displacements.
    x, y = np.cos(ALPHA0) - D1, np.sin(ALPHA0) - D2
    assert_allclose(np.arctan2(y, x), alpha, rtol=0, atol=1e-15)
    assert_allclose(np.hypot(x, y), length, rtol=0, atol=1e-15)
    assert diamond_displacements(ALPHA0, 1.0, ALPHA0) == pytest.approx((0.0, 0.0), abs=1e-16)


def test_mcnamara_state_is_in_equilibrium_eq43():
    # Forces from the closed form, l* from Eq. (46): then N* = -(l* - 1) and
    # l* T* = gamma (alpha - alpha0) (Eq. 43 in units of 2R k_n) reproduce F
    # through the equilibrium Eq. (4).
    alpha = np.linspace(0.5, 1.1, 13)
    gamma, F2 = 0.5, 0.3
    F1 = mcnamara_load_rotation(alpha, gamma, ALPHA0, F2=F2)
    length = mcnamara_branch_length(alpha, F1, F2)
    N, T = -(length - 1), gamma * (alpha - ALPHA0) / length
    assert_allclose(2 * N * np.cos(alpha) + 2 * T * np.sin(alpha), F1, rtol=0, atol=1e-13)
    assert_allclose(2 * N * np.sin(alpha) - 2 * T * np.cos(alpha), F2, rtol=0, atol=1e-13)


# --- Turco et al. (2019) -------------------------------------------------------------------


@pytest.mark.parametrize("branch", [-1, 1])
def test_eq57_solves_the_quadratic_eq56(branch):
    alpha = np.linspace(0.1, 1.45, 200)
    gamma = np.array(GAMMAS)[:, None]
    F1 = turco_load_rotation(alpha, gamma, ALPHA0, branch=branch)
    keep = np.isfinite(F1) & (np.abs(F1) <= 20)
    assert keep.sum() > 100
    # Terms O(100) at most for |F1*| <= 20: rounding below 1e-12.
    assert np.max(np.abs(eq56_residual(F1, alpha, gamma, ALPHA0)[keep])) < 1e-12


@pytest.mark.parametrize("gamma", GAMMAS)
def test_eq58_starts_unloaded_with_the_slope_of_eq50(gamma):
    # Seed: "Eq. (50) is valid for both hyperelastic models".
    assert turco_load_rotation(ALPHA0, gamma, ALPHA0) == pytest.approx(0.0, abs=1e-15)
    h = 1e-5
    slope = (
        turco_load_rotation(ALPHA0 + h, gamma, ALPHA0)
        - turco_load_rotation(ALPHA0 - h, gamma, ALPHA0)
    ) / (2 * h)
    assert slope == pytest.approx(2 * gamma / np.sin(ALPHA0), rel=1e-8)


def test_turco_state_is_in_equilibrium_eq54():
    # Eq. (54) in units of 2R k_n: N* = -(l* - cos(a - a0)),
    # l* T* = sin(a - a0) (l* - cos(a - a0)) + gamma sin(a - a0) cos(a - a0).
    alpha = np.linspace(0.5, 1.1, 13)
    gamma = 0.5
    F1 = turco_load_rotation(alpha, gamma, ALPHA0)
    length = turco_branch_length(alpha, F1, 0.0, ALPHA0)
    d = alpha - ALPHA0
    N = -(length - np.cos(d))
    T = (np.sin(d) * (length - np.cos(d)) + gamma * np.sin(d) * np.cos(d)) / length
    assert_allclose(2 * N * np.cos(alpha) + 2 * T * np.sin(alpha), F1, rtol=0, atol=1e-13)
    assert_allclose(2 * N * np.sin(alpha) - 2 * T * np.cos(alpha), 0.0, rtol=0, atol=1e-13)


# --- pure-shear limit ----------------------------------------------------------------------


@pytest.mark.parametrize("alpha0", [0.3, np.pi / 4, 1.0])
def test_rotational_blocking_at_pi_over_3_eq66_67(alpha0):
    blocking = pure_shear_blocking_alpha(alpha0, "rotational")
    assert blocking == pytest.approx(np.pi / 3, abs=0)
    D1 = pure_shear_displacement(blocking, alpha0, "rotational")
    assert D1 == pytest.approx(np.cos(alpha0) - 0.5, abs=1e-15)
    assert pure_shear_max_displacement(alpha0) == pytest.approx(np.cos(alpha0) - 0.5, abs=0)


def test_blocking_displacement_for_alpha0_pi_over_4_eq67():
    expected = (np.sqrt(2) - 1) / 2
    assert pure_shear_displacement(np.pi / 3, np.pi / 4, "rotational") == pytest.approx(
        expected, abs=1e-15
    )
    assert pure_shear_max_displacement(np.pi / 4) == pytest.approx(expected, abs=1e-15)


@pytest.mark.parametrize("alpha0", [0.3, np.pi / 4, 1.0])
def test_translational_blocking_eq68(alpha0):
    blocking = float(pure_shear_blocking_alpha(alpha0, "translational"))
    assert alpha0 < blocking < np.pi / 2
    assert np.cos(blocking) * np.cos(blocking - alpha0) == pytest.approx(0.5, abs=1e-15)
    # The same displacement limit as the rotational model (Eq. 68).
    D1 = pure_shear_displacement(blocking, alpha0, "translational")
    assert D1 == pytest.approx(np.cos(alpha0) - 0.5, abs=1e-15)


def test_blocking_is_nan_when_the_grains_touch_at_rest():
    assert np.isnan(pure_shear_blocking_alpha(np.pi / 3, "rotational"))
    assert np.all(np.isnan(pure_shear_blocking_alpha([1.2, 0.0], "translational")))


def test_pure_shear_first_branch_eq62_eq65():
    alpha = np.linspace(ALPHA0, np.pi / 3, 50)
    # Eq. (66): F2hat = 0 on the rotational model.
    assert_allclose(
        pure_shear_load_rotation(alpha, ALPHA0),
        2 * (alpha - ALPHA0) / np.sin(alpha),
        rtol=0,
        atol=1e-15,
    )
    # Both start unloaded and, to first order, coincide (same initial slope 2/sin a0).
    for model in ("rotational", "translational"):
        assert pure_shear_load_rotation(ALPHA0, ALPHA0, model=model) == pytest.approx(
            0.0, abs=1e-15
        )
        h = 1e-6
        slope = (
            pure_shear_load_rotation(ALPHA0 + h, ALPHA0, model=model)
            - pure_shear_load_rotation(ALPHA0 - h, ALPHA0, model=model)
        ) / (2 * h)
        assert slope == pytest.approx(2 / np.sin(ALPHA0), rel=1e-7)
    # Eq. (61) and (64) from the forces: F1 sin a - F2 cos a = 2 (a - a0) on the
    # rotational model, F1 sin(2a - a0) - F2 cos(2a - a0) = sin(2a - 2a0) on the other.
    F2hat = 0.4
    rot = pure_shear_load_rotation(alpha, ALPHA0, F2hat, "rotational")
    assert_allclose(
        rot * np.sin(alpha) - F2hat * np.cos(alpha), 2 * (alpha - ALPHA0), rtol=0, atol=1e-15
    )
    tra = pure_shear_load_rotation(alpha, ALPHA0, F2hat, "translational")
    assert_allclose(
        tra * np.sin(2 * alpha - ALPHA0) - F2hat * np.cos(2 * alpha - ALPHA0),
        np.sin(2 * alpha - 2 * ALPHA0),
        rtol=0,
        atol=1e-15,
    )
    with pytest.raises(ValueError, match="model"):
        pure_shear_displacement(alpha, ALPHA0, "elastic")


@pytest.mark.parametrize("k", [0.1, 0.3, 0.5563, 0.9])
def test_the_elastica_deflection_is_that_of_the_integrated_elastica(k):
    # theta'' = -sin(theta) (lambda = 1) from a pinned end (theta = theta_0 = 2 asin k, no moment)
    # to midspan (theta = 0), integrated at rtol 1e-12: there s = L / 2 and y is the deflection,
    # at P / P_cr = (L / pi)^2; elastica_deflection gives y / L from that ratio alone (1e-9: the
    # integration's tolerance times the inversion's conditioning, 1 / k^2: k >= 0.1)
    from scipy.integrate import solve_ivp

    from ncstab.systems.closed_forms import elastica_deflection

    def midspan(s, x):
        return x[0]
    midspan.terminal, midspan.direction = True, -1
    solution = solve_ivp(lambda s, x: [x[1], -np.sin(x[0]), np.sin(x[0])], (0.0, 20.0),
                         [2 * np.arcsin(k), 0.0, 0.0], rtol=1e-12, atol=1e-14, events=midspan, method="DOP853")
    half, deflection = solution.t_events[0][0], solution.y_events[0][0][2]
    ratio = (2 * half / np.pi) ** 2
    assert elastica_deflection(ratio) == pytest.approx(deflection / (2 * half), rel=1e-9)


def test_the_elastica_is_straight_up_to_the_critical_load():
    from ncstab.systems.closed_forms import elastica_deflection

    assert elastica_deflection(1.0) == 0.0
    with pytest.raises(ValueError, match="P / P_cr >= 1"):
        elastica_deflection(0.9)
