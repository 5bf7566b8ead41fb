"""The dynamic spectrum of M s^2 + C s + K and its indicators (issue 16, numeric layer).

Checked against Ziegler's pendulum in closed form (its matrices derived here with
sympy from the Lagrangian), against the Routh-Hurwitz criterion written out by
hand, against scipy.linalg.eig of the companion matrix, against exact (rational)
sympy determinants and discriminants, and against Orlando's formula.

Units: l = 1, k = 1, m = 1 (P in k/l, time in sqrt(m l^2 / k), b in sqrt(k m l^2)).
"""

from __future__ import annotations

import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import scipy.linalg
import sympy as sp
from scipy.optimize import brentq, linear_sum_assignment

from ncstab.operators import (
    characteristic_polynomial,
    critical_frequency,
    divergence_indicator,
    dynamic_spectrum,
    flutter_discriminant,
    flutter_indicator,
    flutter_onset_indicator,
    frequency_discriminant,
    hurwitz_determinants,
    hurwitz_matrix,
)
from ncstab.operators.onset_cases import interpolated_rows

SQRT2 = math.sqrt(2.0)
#: Ziegler's flutter load (undamped, follower), divergence load (dead), paradox limit.
P_FLUTTER = 3.5 - SQRT2
P_DIVERGENCE = (3.0 - math.sqrt(5.0)) / 2.0
P_PARADOX = 41.0 / 28.0

# --- Ziegler's pendulum from its Lagrangian ---------------------------------------------------


def ziegler_symbolic() -> dict[str, sp.Matrix]:
    """M, C, K_follower, K_dead on the straight state, derived from T, V, R and the load's work.

    Two rigid bars of length 1, angles phi1, phi2 from the vertical; masses 2 at
    the middle joint and 1 at the tip; springs phi1 and (phi2 - phi1); dashpots
    b1 phi1' and b2 (phi2' - phi1'); tip load P, either dead (0, -P) or follower
    (-P along the second bar).  Linearising Lagrange's equations about the rest
    state gives M q'' + C q' + (Hess V - dQ/dq) q = 0.
    """
    q1, q2, v1, v2, P, b1, b2 = sp.symbols("phi1 phi2 v1 v2 P b1 b2")
    q, v = sp.Matrix([q1, q2]), sp.Matrix([v1, v2])
    joint = sp.Matrix([sp.sin(q1), sp.cos(q1)])
    tip = joint + sp.Matrix([sp.sin(q2), sp.cos(q2)])
    speed = [point.jacobian(q) * v for point in (joint, tip)]
    kinetic = sp.Rational(1, 2) * (2 * speed[0].dot(speed[0]) + 1 * speed[1].dot(speed[1]))
    potential = sp.Rational(1, 2) * (q1**2 + (q2 - q1) ** 2)
    rayleigh = sp.Rational(1, 2) * (b1 * v1**2 + b2 * (v2 - v1) ** 2)
    rest = {q1: 0, q2: 0, v1: 0, v2: 0}

    def load_stiffness(force: sp.Matrix) -> sp.Matrix:
        generalized = tip.jacobian(q).T * force  # Q_i = F . d(tip)/d(q_i)
        return -generalized.jacobian(q).subs(rest)

    spring = sp.hessian(potential, q).subs(rest)
    return {
        "M": sp.hessian(kinetic, v).subs(rest),
        "C": sp.hessian(rayleigh, v).subs(rest),
        "K_follower": sp.simplify(
            spring + load_stiffness(-P * sp.Matrix([sp.sin(q2), sp.cos(q2)]))
        ),
        "K_dead": sp.simplify(spring + load_stiffness(sp.Matrix([0, -P]))),
    }


def test_ziegler_matrices_follow_from_the_lagrangian():
    P, b1, b2 = sp.symbols("P b1 b2")
    derived = ziegler_symbolic()
    assert derived["M"] == sp.Matrix([[3, 1], [1, 1]])
    assert derived["C"] == sp.Matrix([[b1 + b2, -b2], [-b2, b2]])
    assert sp.simplify(derived["K_follower"] - sp.Matrix([[2 - P, P - 1], [-1, 1]])) == sp.zeros(
        2, 2
    )
    assert sp.simplify(derived["K_dead"] - sp.Matrix([[2 - P, -1], [-1, 1 - P]])) == sp.zeros(2, 2)


MASS = np.array([[3.0, 1.0], [1.0, 1.0]])


def k_follower(load: np.ndarray | float) -> np.ndarray:
    load = np.asarray(load, dtype=float)[..., None, None]
    return np.array([[2.0, -1.0], [-1.0, 1.0]]) + load * np.array([[-1.0, 1.0], [0.0, 0.0]])


def k_dead(load: np.ndarray | float) -> np.ndarray:
    load = np.asarray(load, dtype=float)[..., None, None]
    return np.array([[2.0, -1.0], [-1.0, 1.0]]) - load * np.eye(2)


def damping(b1: float, b2: float) -> np.ndarray:
    return np.array([[b1 + b2, -b2], [-b2, b2]])


def undamped_follower_roots(load: float) -> np.ndarray:
    """s = +-sqrt(mu) for the roots mu of 2 mu^2 + (7 - 2P) mu + 1 (det(M mu + K_follower))."""
    mu = np.roots([2.0, 7.0 - 2.0 * load, 1.0]).astype(complex)
    root = np.sqrt(mu)
    return np.concatenate([root, -root])


def assert_same_roots(actual: np.ndarray, expected: np.ndarray, tol: float) -> None:
    """The two root sets agree to tol * max|expected|, matched one to one."""
    distance = np.abs(actual[:, None] - expected[None, :])
    rows, cols = linear_sum_assignment(distance)
    error = distance[rows, cols].max()
    assert error <= tol * np.abs(expected).max(), (actual, expected, error)


# --- undamped follower load: flutter at 7/2 - sqrt 2 -----------------------------------------


def test_undamped_follower_flutter_load_and_frequency():
    # The discriminant is (7 - 2P)^2 - 8, exact to rounding (~1e-15) with a slope
    # -4 (7 - 2P) = -8 sqrt 2 at the root: the root is exact to ~1e-16, and
    # 1e-10 (the demand) holds with a wide margin; a wrong M or K moves it
    # by O(1).
    onset = brentq(
        lambda p: float(frequency_discriminant(MASS, k_follower(p))),
        1.5,
        3.0,
        xtol=1e-15,
        rtol=1e-15,
    )
    assert abs(onset - P_FLUTTER) <= 1e-10
    loads = np.linspace(0.0, 4.0, 41)
    np.testing.assert_allclose(
        frequency_discriminant(MASS, k_follower(loads)),
        (7 - 2 * loads) ** 2 - 8,
        rtol=0,
        atol=1e-12,
    )
    assert np.all(flutter_onset_indicator(MASS, None, k_follower(loads[loads < P_FLUTTER])) > 0)
    assert np.all(flutter_onset_indicator(MASS, None, k_follower(loads[loads > P_FLUTTER])) < 0)
    # At the coalescence mu = -(7 - 2P)/4 = -sqrt(2)/2 twice: omega = 2^(-1/4).  The
    # mean of the two mu is a trace (well conditioned), so 1e-10 although each
    # mu of a double root carries a sqrt(eps) error.
    assert abs(float(critical_frequency(MASS, None, k_follower(onset))) - 2**-0.25) <= 1e-10
    # The discriminant of K alone (which ignores M) fires at P = 1: (P - 1)(P - 5).
    np.testing.assert_allclose(
        flutter_discriminant(k_follower(loads)), (loads - 1) * (loads - 5), atol=1e-12
    )


@pytest.mark.parametrize("load", [0.0, 1.0, 2.0, P_FLUTTER - 1e-3])
def test_undamped_follower_below_flutter_has_an_imaginary_spectrum(load):
    spectrum = dynamic_spectrum(MASS, None, k_follower(load))
    # Every root is imaginary: Re s is rounding only.  Near the onset the two
    # frequencies are 1.6e-2 apart, so the eigenvalue error eps |A| / gap ~ 1e-14.
    assert np.abs(spectrum.real).max() <= 1e-12
    assert abs(float(flutter_indicator(MASS, None, k_follower(load)))) <= 1e-12
    assert_same_roots(spectrum, undamped_follower_roots(load), 1e-10)


@pytest.mark.parametrize("load", [P_FLUTTER + 1e-3, 3.0, 5.0])
def test_undamped_follower_above_flutter_has_a_growing_pair(load):
    expected = undamped_follower_roots(load)
    growth = float(flutter_indicator(MASS, None, k_follower(load)))
    assert growth > 1e-3
    assert abs(growth - expected.real.max()) <= 1e-10  # simple roots: eps |A| / gap
    assert_same_roots(dynamic_spectrum(MASS, None, k_follower(load)), expected, 1e-10)


def test_follower_load_never_diverges():
    loads = np.linspace(0.0, 10.0, 101)
    # det K_follower = (2 - P) + (P - 1) = 1: rounding of a sum of O(10) terms.
    np.testing.assert_allclose(
        divergence_indicator(MASS, None, k_follower(loads)), 1.0, rtol=0, atol=1e-13
    )


# --- dead load: divergence at (3 - sqrt 5)/2, no flutter ---------------------------------------


def test_dead_load_diverges_and_never_flutters():
    loads = np.linspace(0.0, 4.0, 81)
    np.testing.assert_allclose(
        divergence_indicator(MASS, None, k_dead(loads)), loads**2 - 3 * loads + 1, atol=1e-13
    )
    root = brentq(
        lambda p: float(divergence_indicator(MASS, None, k_dead(p))),
        0.0,
        1.0,
        xtol=1e-15,
        rtol=1e-15,
    )
    assert abs(root - P_DIVERGENCE) <= 1e-12  # simple root of a quadratic, slope -sqrt 5
    # Discriminant of 2 mu^2 + (7 - 4P) mu + P^2 - 3P + 1: 8 P^2 - 32 P + 41 > 0 for every P
    # (M and K symmetric: every mu is real).
    discriminant = frequency_discriminant(MASS, k_dead(loads))
    np.testing.assert_allclose(discriminant, 8 * loads**2 - 32 * loads + 41, rtol=1e-14)
    assert np.all(discriminant > 0)
    # Past the divergence load a real root is positive: s^2 = mu, the positive root.
    beyond = 1.0
    mu = np.roots([2.0, 7.0 - 4.0 * beyond, beyond**2 - 3 * beyond + 1]).real.max()
    assert mu > 0
    assert abs(float(flutter_indicator(MASS, None, k_dead(beyond))) - math.sqrt(mu)) <= 1e-12
    assert abs(float(flutter_indicator(MASS, None, k_dead(0.2)))) <= 1e-12
    # At the divergence load a root is at s = 0 (double, as C = 0: error ~ sqrt(eps)).
    assert np.abs(dynamic_spectrum(MASS, None, k_dead(P_DIVERGENCE))).min() <= 1e-7


# --- equal dashpots: Routh-Hurwitz by hand, the destabilization paradox ------------------------


def hand_quartic(load: float, b: float) -> list[float]:
    """det(M s^2 + C s + K_follower) for b1 = b2 = b, expanded by hand:

    (3s^2 + 2bs + 2 - P)(s^2 + bs + 1) - (s^2 - bs + P - 1)(s^2 - bs - 1)
    = 2 s^4 + 7b s^3 + (7 + b^2 - 2P) s^2 + 2b s + 1.
    """
    return [2.0, 7.0 * b, 7.0 + b * b - 2.0 * load, 2.0 * b, 1.0]


def routh_hurwitz_critical_load(b: float) -> float:
    """Root in P of Delta_3 = a1 a2 a3 - a0 a3^2 - a1^2 a4 for the hand quartic (sympy, exact)."""
    P, s = sp.symbols("P s")
    bb = sp.nsimplify(b)
    a0, a1, a2, a3, a4 = 2, 7 * bb, 7 + bb**2 - 2 * P, 2 * bb, 1
    # The hand quartic is the determinant of the derived matrices.
    derived = ziegler_symbolic()
    matrix = (
        derived["M"] * s**2 + derived["C"].subs({"b1": bb, "b2": bb}) * s + derived["K_follower"]
    )
    assert sp.expand(matrix.det() - (a0 * s**4 + a1 * s**3 + a2 * s**2 + a3 * s + a4)) == 0
    (critical,) = sp.solve(sp.Eq(a1 * a2 * a3 - a0 * a3**2 - a1**2 * a4, 0), P)
    # Below it the other Hurwitz conditions hold: Delta_1 = a1 > 0, Delta_2 > 0, a4 > 0.
    assert (a1 * a2 - a0 * a3).subs(P, critical) > 0
    return float(critical)


@pytest.mark.parametrize("b", [1.0, 0.1, 0.01, 0.001])
def test_equal_dashpots_critical_load_is_the_routh_hurwitz_root(b):
    expected = routh_hurwitz_critical_load(b)
    c = damping(b, b)
    np.testing.assert_allclose(
        characteristic_polynomial(MASS, c, k_follower(1.3)),
        hand_quartic(1.3, b),
        rtol=1e-15,
        atol=1e-15,
    )
    # Delta_3 is b^2 (41 + 14 b^2 - 28 P) / 8 after dividing by a0^3: its terms carry
    # rounding ~ eps b^2 and its slope is 3.5 b^2, so the root is good to ~1e-15;
    # 1e-9 is the demand.
    onset = brentq(
        lambda p: float(flutter_onset_indicator(MASS, c, k_follower(p))),
        1.0,
        2.0,
        xtol=1e-15,
        rtol=1e-15,
    )
    assert abs(onset - expected) <= 1e-9
    # The spectrum agrees: a pair crosses Re s = 0 there (growth rate slope ~ b, so
    # a step of 1e-4 gives |max Re s| >> rounding 1e-15).
    assert float(flutter_indicator(MASS, c, k_follower(onset - 1e-4))) < 0
    assert float(flutter_indicator(MASS, c, k_follower(onset + 1e-4))) > 0
    # omega^2 = a3 / a1 = 2/7 at the onset (the pair +-i omega solves both the even and
    # the odd part of the quartic); eigenvalues are simple there: 1e-9.
    assert abs(float(critical_frequency(MASS, c, k_follower(onset))) - math.sqrt(2.0 / 7.0)) <= 1e-9


def test_vanishing_equal_damping_gives_ziegler_paradox():
    c = damping(1e-5, 1e-5)
    onset = brentq(
        lambda p: float(flutter_onset_indicator(MASS, c, k_follower(p))),
        1.0,
        2.0,
        xtol=1e-15,
        rtol=1e-15,
    )
    assert abs(onset - P_PARADOX) <= 1e-4  # the exact limit is 41/28 + b^2/2 = 41/28 + 5e-11
    assert onset < P_FLUTTER - 0.6  # far below the undamped flutter load


# --- generic systems: the spectrum against scipy, batches, the polynomial --------------------


def random_systems(
    rng: np.random.Generator, batch: int, n: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Well-conditioned M (SPD, eigenvalues in [1, ~4]), random C and K (O(1) entries)."""
    a = rng.normal(size=(batch, n, n))
    mass = a @ np.swapaxes(a, -1, -2) / n + np.eye(n)
    return mass, rng.normal(size=(batch, n, n)), rng.normal(size=(batch, n, n)) + 2 * np.eye(n)


def companion(mass: np.ndarray, damping_: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    n = mass.shape[-1]
    inverse = scipy.linalg.inv(mass)
    return np.block([[np.zeros((n, n)), np.eye(n)], [-inverse @ stiffness, -inverse @ damping_]])


@pytest.mark.parametrize("n", [1, 2, 3, 4, 6])
def test_spectrum_matches_scipy_eig_of_the_companion_matrix(rng, n):
    mass, damp, stiffness = random_systems(rng, 40, n)
    spectrum = dynamic_spectrum(mass, damp, stiffness)
    assert spectrum.shape == (40, 2 * n) and spectrum.dtype == complex
    for case in range(40):
        # Both are QR iterations on the same matrix formed with different roundings
        # (solve vs inv): they differ by eps |A| kappa, kappa ~ 1-100 for these
        # matrices: 1e-12 relative to the spectral radius.
        assert_same_roots(
            spectrum[case],
            scipy.linalg.eig(companion(mass[case], damp[case], stiffness[case]), right=False),
            1e-12,
        )
        # And the pencil [[0, I], [-K, -C]] - s diag(I, M), with no inverse at all (QZ).
        pencil_a = np.block([[np.zeros((n, n)), np.eye(n)], [-stiffness[case], -damp[case]]])
        pencil_b = scipy.linalg.block_diag(np.eye(n), mass[case])
        assert_same_roots(spectrum[case], scipy.linalg.eig(pencil_a, pencil_b, right=False), 1e-12)
    # Sorted by imaginary part, then real part.
    order = np.lexsort((spectrum.real, spectrum.imag), axis=-1)
    np.testing.assert_array_equal(order, np.broadcast_to(np.arange(2 * n), order.shape))


def test_undamped_growth_of_two_dofs_is_the_companion_spectrum_in_every_regime(rng):
    """The real closed form of max Re s (n = 2, C = 0) against scipy's eigenvalues of the
    companion matrix, on 400 random systems covering the four regimes (real or complex
    eigenvalues of M^-1 K, positive or negative trace).  Compared as growth^2 =
    (|mu| + Re mu) / 2, a Lipschitz function of the eigenvalues mu (the square root
    amplifies their rounding near mu = 0), to 1e-12 of the spectral radius."""
    mass, _, _ = random_systems(rng, 400, 2)
    stiffness = rng.normal(size=(400, 2, 2)) * rng.choice([0.1, 1.0, 10.0], size=(400, 1, 1))
    growth = flutter_indicator(mass, None, stiffness)
    product = np.linalg.solve(mass, stiffness)
    half_trace = 0.5 * np.trace(product, axis1=-2, axis2=-1)
    discriminant = half_trace**2 - np.linalg.det(product)
    for real in (True, False):
        for positive in (True, False):
            assert np.sum(((discriminant >= 0) == real) & ((half_trace > 0) == positive)) >= 20
    for case in range(400):
        roots = scipy.linalg.eig(companion(mass[case], np.zeros((2, 2)), stiffness[case]), right=False)
        expected = roots.real.max()
        scale = np.abs(roots).max() ** 2
        assert abs(growth[case] ** 2 - expected**2) <= 1e-12 * scale, (case, growth[case], expected)


def test_undamped_growth_near_a_zero_eigenvalue_keeps_its_digits():
    """K = diag(1, -1e-14), M = I: mu = -1 and 1e-14, so max Re s = 1e-7 exactly to rounding.
    Subtracting two numbers near 1 (tr/2 - r) leaves three digits (9.996e-8)."""
    growth = float(flutter_indicator(np.eye(2), None, np.diag([1.0, -1e-14])))
    assert growth == pytest.approx(1e-7, rel=1e-12)
    rotated = float(flutter_indicator(np.eye(2), None, np.diag([-1e-14, 1.0])))
    assert rotated == pytest.approx(1e-7, rel=1e-12)


@pytest.mark.parametrize("n", [2, 3])
def test_spectrum_is_batch_independent(rng, n):
    mass, damp, stiffness = random_systems(rng, 30, n)
    batch = dynamic_spectrum(mass, damp, stiffness)
    alone = np.stack([dynamic_spectrum(mass[i], damp[i], stiffness[i]) for i in range(30)])
    np.testing.assert_array_equal(batch, alone)  # bit for bit
    np.testing.assert_array_equal(
        dynamic_spectrum(
            mass.reshape(5, 6, n, n), damp.reshape(5, 6, n, n), stiffness.reshape(5, 6, n, n)
        ),
        batch.reshape(5, 6, 2 * n),
    )
    shared = dynamic_spectrum(mass[0], None, stiffness)  # one M for the batch
    np.testing.assert_array_equal(shared[7], dynamic_spectrum(mass[0], None, stiffness[7]))
    for function in (flutter_indicator, flutter_onset_indicator, critical_frequency):
        np.testing.assert_array_equal(
            function(mass, damp, stiffness),
            np.stack([function(mass[i], damp[i], stiffness[i]) for i in range(30)]),
        )


def test_an_empty_batch_gives_empty_indicators(rng):
    """No case (a stage that no case enters, as when a preload of 0 is reached at once):
    every indicator has the batch's shape, (0,), not a scalar NaN (which crashed the
    event table of a general model with inertia: tests/test_models.py)."""
    mass, damp, stiffness = random_systems(rng, 3, 3)
    for function in (flutter_indicator, flutter_onset_indicator, critical_frequency):
        assert function(mass[:0], None, stiffness[:0]).shape == (0,), function.__name__
        assert function(mass[0], None, stiffness[:0]).shape == (0,), function.__name__
        assert function(mass[:0], damp[:0], stiffness[:0]).shape == (0,), function.__name__


def test_a_singular_or_non_finite_case_gives_nan_and_spares_the_others(rng):
    mass, damp, stiffness = random_systems(rng, 6, 3)
    clean = dynamic_spectrum(mass, damp, stiffness)
    mass[1] = np.outer([1.0, 2.0, 3.0], [1.0, 0.0, 1.0])  # rank 1
    stiffness[4, 0, 2] = np.nan
    spectrum = dynamic_spectrum(mass, damp, stiffness)
    assert np.isnan(spectrum[[1, 4]]).all()
    np.testing.assert_array_equal(spectrum[[0, 2, 3, 5]], clean[[0, 2, 3, 5]])
    for function in (flutter_indicator, flutter_onset_indicator, critical_frequency):
        values = function(mass, damp, stiffness)
        assert np.isnan(values[[1, 4]]).all() and np.isfinite(values[[0, 2, 3, 5]]).all()
    assert np.isnan(frequency_discriminant(mass, stiffness)[[1, 4]]).all()
    # The functions that need no M^-1: NaN only where an input is not finite.
    assert np.isnan(divergence_indicator(mass, damp, stiffness)[4])
    assert np.isfinite(np.delete(divergence_indicator(mass, damp, stiffness), 4)).all()
    coefficients = characteristic_polynomial(mass, damp, stiffness)
    assert np.isnan(coefficients[4]).all() and np.isfinite(np.delete(coefficients, 4, axis=0)).all()
    assert np.isnan(hurwitz_determinants(coefficients)[4]).all()


def test_shape_errors_name_the_matrix():
    with pytest.raises(ValueError, match=r"K must have shape \(\.\.\., n, n\)"):
        dynamic_spectrum(np.eye(2), None, np.ones(2))
    with pytest.raises(ValueError, match=r"must all be n x n: got M \(2, 2\), C \(3, 3\)"):
        flutter_indicator(np.eye(2), np.eye(3), np.eye(2))
    with pytest.raises(ValueError, match="do not broadcast"):
        characteristic_polynomial(np.ones((4, 2, 2)), None, np.ones((3, 2, 2)))
    with pytest.raises(ValueError, match=r"N >= 1"):
        hurwitz_determinants(np.ones(1))


@pytest.mark.parametrize("n", [3, 4])
def test_characteristic_polynomial_roots_are_the_spectrum(rng, n):
    mass, damp, stiffness = random_systems(rng, 40, n)
    coefficients = characteristic_polynomial(mass, damp, stiffness)
    spectrum = dynamic_spectrum(mass, damp, stiffness)
    for case in range(40):
        # numpy.roots is the eigenvalues of the polynomial's companion matrix: its
        # error is eps kappa_j |s| with the root condition numbers kappa_j of a
        # degree-8 polynomial (up to ~1e2 here) amplified by the coefficient errors
        # (~1e-13 relative): 1e-9 relative to the spectral radius.
        assert_same_roots(np.roots(coefficients[case]), spectrum[case], 1e-9)


@pytest.mark.parametrize("n", [3, 4])
def test_characteristic_polynomial_against_exact_rational_determinant(rng, n):
    mass, damp, stiffness = random_systems(rng, 3, n)
    coefficients = characteristic_polynomial(mass, damp, stiffness)
    s = sp.symbols("s")
    for case in range(3):
        exact_matrices = [
            sp.Matrix(n, n, [sp.Rational(float(x)) for x in a[case].ravel()])
            for a in (mass, damp, stiffness)
        ]
        pencil = exact_matrices[0] * s**2 + exact_matrices[1] * s + exact_matrices[2]
        exact = np.array(
            [float(c) for c in sp.Poly(pencil.det(method="berkowitz"), s).all_coeffs()]
        )
        # Interpolation on a circle of radius r: absolute error ~ N eps max|p(z)| / r^j,
        # a few eps of the largest term; the coefficients of these O(1) systems lie
        # within a factor ~1e2 of it: 1e-11 relative is a margin of ~100.
        np.testing.assert_allclose(coefficients[case], exact, rtol=1e-11)


@pytest.mark.parametrize("n", [1, 2])
def test_interpolation_agrees_with_the_closed_forms(rng, n):
    mass, damp, stiffness = random_systems(rng, 200, n)
    closed = characteristic_polynomial(mass, damp, stiffness)
    # Both exact to a few eps of the largest term (O(10) here): 1e-13 absolute.
    np.testing.assert_allclose(
        interpolated_rows(mass, damp, stiffness),
        closed,
        rtol=0,
        atol=1e-13 * np.abs(closed).max(),
    )


def test_characteristic_polynomial_is_scale_equivariant(rng):
    # det(M s^2 + g C s + g^2 K) = g^(2n) p(s / g): a_j (degree j) -> g^(2n - j) a_j.  The
    # radius follows g, so the relative error stays at the eps level: 1e-12.
    mass, damp, stiffness = random_systems(rng, 20, 4)
    g = 1e3
    scaled = characteristic_polynomial(mass, g * damp, g**2 * stiffness)
    expected = characteristic_polynomial(mass, damp, stiffness) * g ** np.arange(9)
    np.testing.assert_allclose(scaled, expected, rtol=1e-12, atol=0)


# --- Hurwitz determinants and Orlando's formula ---------------------------------------------


def test_hurwitz_determinants_of_a_quadratic_and_a_quartic(rng):
    a = rng.normal(size=(500, 3))
    # Each minor is a handful of products of O(1) numbers: LU agrees with the literal
    # formula to a few eps of the terms' size: 1e-13 absolute.
    np.testing.assert_allclose(
        hurwitz_determinants(a), np.stack([a[:, 1], a[:, 1] * a[:, 2]], -1), atol=1e-13
    )
    a0, a1, a2, a3, a4 = rng.normal(size=(5, 500))
    quartic = np.stack([a0, a1, a2, a3, a4], -1)
    np.testing.assert_array_equal(
        hurwitz_matrix(quartic)[7],
        [
            [a1[7], a3[7], 0, 0],
            [a0[7], a2[7], a4[7], 0],
            [0, a1[7], a3[7], 0],
            [0, a0[7], a2[7], a4[7]],
        ],
    )
    delta3 = a1 * a2 * a3 - a0 * a3**2 - a1**2 * a4
    expected = np.stack([a1, a1 * a2 - a0 * a3, delta3, a4 * delta3], -1)
    np.testing.assert_allclose(hurwitz_determinants(quartic), expected, atol=1e-13)


@pytest.mark.parametrize("degree", [3, 4, 6, 8])
def test_routh_hurwitz_and_orlando_on_polynomials_with_known_roots(rng, degree):
    # Roots in conjugate pairs (and one real root for odd degree), real parts both signs.
    cases = 300
    pairs = degree // 2
    pair_roots = rng.uniform(-1, 0.3, size=(cases, pairs)) + 1j * rng.uniform(
        0.2, 2, size=(cases, pairs)
    )
    roots = np.concatenate(
        [pair_roots, pair_roots.conj()]
        + ([rng.uniform(-1, 0.3, size=(cases, 1))] if degree % 2 else []),
        -1,
    )
    leading = rng.uniform(0.5, 2, size=cases)
    coefficients = leading[:, None] * np.stack([np.poly(r) for r in roots]).real
    deltas = hurwitz_determinants(coefficients)
    stable = roots.real.max(-1) < 0
    assert stable.any() and (~stable).any()
    np.testing.assert_array_equal((deltas > 0).all(-1), stable)
    # Orlando: Delta_{N-1} = (-1)^(N(N-1)/2) a0^(N-1) prod_{i<j} (s_i + s_j).  Products of
    # O(1) numbers, rounded LU vs rounded product: 1e-11 relative to the size of the terms.
    i, j = np.triu_indices(degree, 1)
    orlando = (
        (-1) ** (degree * (degree - 1) // 2)
        * leading ** (degree - 1)
        * np.prod(roots[:, i] + roots[:, j], -1).real
    )
    scale = leading ** (degree - 1) * np.prod(np.abs(roots[:, i]) + np.abs(roots[:, j]), -1)
    np.testing.assert_array_less(np.abs(deltas[:, -2] - orlando), 1e-11 * scale)


@pytest.mark.parametrize("n", [2, 3])
def test_flutter_onset_indicator_is_orlandos_product_of_the_spectrum(rng, n):
    # Independent of the polynomial route: the monic Delta_{2n-1} from the roots alone.
    mass, damp, stiffness = random_systems(rng, 200, n)
    roots = dynamic_spectrum(mass, damp, stiffness)
    i, j = np.triu_indices(2 * n, 1)
    degree = 2 * n
    orlando = (-1) ** (degree * (degree - 1) // 2) * np.prod(roots[:, i] + roots[:, j], -1).real
    scale = np.prod(np.abs(roots[:, i]) + np.abs(roots[:, j]), -1)
    # Both sides carry eps-relative errors on terms of size `scale`: 1e-11 of it.
    np.testing.assert_array_less(
        np.abs(flutter_onset_indicator(mass, damp, stiffness) - orlando), 1e-11 * scale
    )


def test_undamped_cases_of_a_damped_batch_use_the_frequency_discriminant():
    loads = np.array([1.0, 2.5, 1.0, 2.5])
    c = np.stack([damping(0.1, 0.1), damping(0.1, 0.1), np.zeros((2, 2)), np.zeros((2, 2))])
    onset = flutter_onset_indicator(MASS, c, k_follower(loads))
    np.testing.assert_array_equal(onset[2:], frequency_discriminant(MASS, k_follower(loads[2:])))
    np.testing.assert_array_equal(
        onset[2:], flutter_onset_indicator(MASS, None, k_follower(loads[2:]))
    )
    np.testing.assert_allclose(onset[:2], 0.01 * (41 + 14 * 0.01 - 28 * loads[:2]) / 8, rtol=1e-12)
    # Critical frequency: 2^(-1/4) only at the undamped onset; elsewhere the closest pair.
    assert (
        abs(float(critical_frequency(MASS, np.zeros((2, 2)), k_follower(P_FLUTTER))) - 2**-0.25)
        <= 1e-10
    )


# --- the frequency discriminant -------------------------------------------------------------


@pytest.mark.parametrize("n", [2, 3])
def test_frequency_discriminant_reduces_to_the_k_discriminant_when_m_is_scalar(rng, n):
    stiffness = rng.normal(size=(500, n, n))
    m = rng.uniform(0.5, 2.0, size=(500, 1, 1))
    value = frequency_discriminant(m * np.eye(n), stiffness)
    k_discriminant = flutter_discriminant(stiffness)
    # disc det(m I mu + K) = m^(n(n-1)) disc K (a positive factor: the same sign);
    # both from closed forms (n = 2) or the same eigenvalues (n = 3): 1e-10 relative
    # to the terms (near-coalescent eigenvalues lose digits in the differences).
    np.testing.assert_allclose(
        value, m[:, 0, 0] ** (n * (n - 1)) * k_discriminant, rtol=1e-10, atol=1e-10
    )
    clear = np.abs(k_discriminant) > 1e-8
    np.testing.assert_array_equal(np.sign(value[clear]), np.sign(k_discriminant[clear]))


def test_frequency_discriminant_against_sympy_for_three_dofs(rng):
    mass, _, stiffness = random_systems(rng, 4, 3)
    value = frequency_discriminant(mass, stiffness)
    mu = sp.symbols("mu")
    for case in range(4):
        exact_m, exact_k = (
            sp.Matrix(3, 3, [sp.Rational(float(x)) for x in a[case].ravel()])
            for a in (mass, stiffness)
        )
        exact = float(sp.discriminant((exact_m * mu + exact_k).det(method="berkowitz"), mu))
        # det(M)^4 prod (lambda_i - lambda_j)^2 from backward-stable eigenvalues: an
        # absolute error of a few eps of its terms; 1e-9 relative here.
        assert abs(value[case] - exact) <= 1e-9 * abs(exact)


def test_one_degree_of_freedom_oscillator():
    # m s^2 + c s + k: s = (-c +- sqrt(c^2 - 4mk)) / 2m; no frequency coalescence (1).
    m, c, k = 2.0, 0.4, 8.0
    expected = np.roots([m, c, k])
    assert_same_roots(dynamic_spectrum([[m]], [[c]], [[k]]), expected, 1e-15)
    np.testing.assert_array_equal(characteristic_polynomial([[m]], [[c]], [[k]]), [m, c, k])
    assert float(flutter_onset_indicator([[m]], [[c]], [[k]])) == pytest.approx(c / m, rel=1e-15)
    assert float(frequency_discriminant([[m]], [[k]])) == 1.0
    assert float(critical_frequency([[m]], None, [[k]])) == pytest.approx(2.0, rel=1e-15)
    assert float(critical_frequency([[m]], [[c]], [[k]])) == pytest.approx(
        abs(expected.imag).max(), rel=1e-14
    )


# --- docs/dynamic-stability.md stays true -----------------------------------------------------


def test_the_documented_example_runs_and_prints_what_the_page_shows(tmp_path):
    text = (Path(__file__).parent.parent / "docs" / "dynamic-stability.md").read_text(
        encoding="utf-8"
    )
    match = re.search(r"```python\n(.*?)```\n\nprints\n\n```\n(.*?)```", text, re.DOTALL)
    assert match, "docs/dynamic-stability.md: no example followed by its output"
    code, shown = match.groups()
    done = subprocess.run(
        [sys.executable, "-c", code],
        check=False,
        capture_output=True,
        text=True,
        cwd=tmp_path,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    assert done.stdout == shown


def test_a_graded_mass_is_regular_and_dependent_columns_are_not():
    # Column scaling leaves |det M| / prod |M_j| unchanged: diag(1, 1e-8) is a regular
    # mass (a light dof gives a fast mode, s = +-1e4 i) ...
    spectrum = dynamic_spectrum(np.diag([1.0, 1e-8]), None, np.eye(2))
    assert_same_roots(spectrum, np.array([1j, -1j, 1e4j, -1e4j]), 1e-12)
    # ... while columns dependent to rounding (ratio 2e-16 <= 2 eps) are singular,
    # and a ratio of 5e-13 is not (its spectrum is finite, if ill-conditioned).
    mass = np.array([[[1.0, 1.0], [1.0, 1.0 + 4e-16]], [[1.0, 1.0], [1.0, 1.0 + 1e-12]]])
    spectrum = dynamic_spectrum(mass, None, np.eye(2))
    assert np.isnan(spectrum[0]).all() and np.isfinite(spectrum[1]).all()


def test_solve_mass_with_the_identity_equals_lapack_bit_for_bit():
    """M = I everywhere (a system without inertia given) skips the solve: the result must
    be LAPACK's M^-1 K to the bit, with the non-finite cases masked the same way."""
    from ncstab.operators.dynamic_matrices import solve_mass

    rng = np.random.default_rng(7)
    stiffness = rng.normal(size=(500, 3, 3))
    stiffness[3, 0, 0] = np.nan
    stiffness[8, 2, 1] = np.inf
    identity = np.broadcast_to(np.eye(3), stiffness.shape)
    product, valid = solve_mass(identity, stiffness)
    finite = np.isfinite(stiffness).all(axis=(-2, -1))
    lapack = np.linalg.solve(np.where(finite[:, None, None], identity, np.eye(3)),
                             np.where(finite[:, None, None], stiffness, 0.0))
    np.testing.assert_array_equal(valid, finite)
    np.testing.assert_array_equal(product, np.where(finite[:, None, None], lapack, 0.0))
    # A mass that is not the identity still goes through the solve.
    mass = identity * 2.0
    product, _ = solve_mass(mass, stiffness)
    np.testing.assert_allclose(product[finite], stiffness[finite] / 2.0, rtol=1e-15)


def test_each_case_s_growth_rate_is_its_own_whatever_the_batch(rng):
    """flutter_indicator gives an undamped case the same value, bit for bit, alone or
    in a batch with damped cases (each case by its own kind: the Dataset computes it
    in blocks of cases, a chunked run in chunks)."""
    n, size = 2, 12
    mass = np.eye(n) + 0.1 * rng.normal(size=(size, n, n))
    mass = mass @ np.swapaxes(mass, -1, -2)
    stiffness = rng.normal(size=(size, n, n))
    damping = 0.2 * rng.normal(size=(size, n, n))
    damping[::3] = 0.0  # undamped cases among damped ones
    batch = flutter_indicator(mass, damping, stiffness)
    alone = np.array([flutter_indicator(mass[k], damping[k], stiffness[k]) for k in range(size)])
    np.testing.assert_array_equal(batch, alone)
    undamped = flutter_indicator(mass[::3], None, stiffness[::3])
    np.testing.assert_array_equal(batch[::3], undamped)
    spectrum = dynamic_spectrum(mass, damping, stiffness).real.max(axis=-1)
    np.testing.assert_allclose(batch, spectrum, rtol=0, atol=1e-12)  # the same roots, either way
