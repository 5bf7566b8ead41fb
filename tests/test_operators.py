"""The tangent operator K (dF = K dDelta) and the stability indicators.

K is checked three ways (STYLE 8): against the seed's hand-derived matrices
(Eq. 38 and 51, written out below), against finite differences of the
equilibrium forces, and for symmetry where a potential exists (Eq. 41).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import assume, given, settings

from ncstab.laws import make_law
from ncstab.operators import contact_forces as law_contact_forces
from ncstab.operators import (
    det_K,
    flutter_discriminant,
    generalized_forces,
    hill_eigenvalue,
    mixed_control_determinant,
    mixed_control_stiffness,
    normalized_second_order_work,
    second_order_work,
    skew_part,
    symmetric_part,
    tangent_operator,
    tangent_operator_at_forces,
)
from ncstab.systems import DiamondChain
from strategies import (
    BASE_LAWS,
    HYPERELASTIC_LAWS,
    TOTAL_FORM_LAWS,
    DiamondState,
    diamond_states,
    tangential_forces,
)

# K is assembled from O(1) trigonometric terms and forces divided by l >= 0.5:
# entries are at most ~20 and carry a few ulp of rounding, so 1e-12 relative to
# the scale 1 + max|K| is a few hundred ulp of margin; any wrong term is O(1e-2).
EXACT_TOL = 1e-12


def _scale(matrix: np.ndarray) -> float:
    return 1.0 + float(np.abs(matrix).max())


def _law(name: str, state: DiamondState):
    return make_law(name, gamma=state.gamma, alpha0=state.alpha0)


# --- the seed's matrices, written by hand ---------------------------------------------


def seed_eq_38(alpha, l, f1, f2, gamma):
    """Seed Eq. (38): dimensionless tangent of the (strongly) hypoelastic model."""
    c, s = math.cos(alpha), math.sin(alpha)
    k11 = 2 * c**2 + 2 * gamma * s**2 - s / l * f2
    k12 = 2 * (1 - gamma) * c * s + c / l * f2
    k21 = 2 * (1 - gamma) * c * s + s / l * f1
    k22 = 2 * s**2 + 2 * gamma * c**2 - c / l * f1
    return np.array([[k11, k12], [k21, k22]])


def seed_eq_51(alpha, l, f1, f2, gamma, alpha0):
    """Seed Eq. (51): dimensionless tangent of the McNamara et al. (2008) model."""
    c, s = math.cos(alpha), math.sin(alpha)
    k11 = (
        2 * c**2
        + 2 * gamma * s**2 / l**2
        - 2 * gamma * (alpha0 - alpha) / l**2 * c * s
        - f2 * s / l
    )
    k12 = (
        2 * c * s
        - 2 * gamma * s * c / l**2
        - 2 * gamma * (alpha0 - alpha) / l**2 * s**2
        + f2 * c / l
    )
    k21 = (
        2 * c * s
        - 2 * gamma * s * c / l**2
        + 2 * gamma * (alpha0 - alpha) / l**2 * c**2
        + f1 * s / l
    )
    k22 = (
        2 * s**2
        + 2 * gamma * c**2 / l**2
        + 2 * gamma * (alpha0 - alpha) / l**2 * c * s
        - f1 * c / l
    )
    return np.array([[k11, k12], [k21, k22]])


@settings(max_examples=100, deadline=None)
@given(state=diamond_states(), tangential=tangential_forces)
def test_cundall_strack_tangent_is_eq_38(state, tangential):
    """State (u, T) with T Cundall--Strack's internal variable; F from Eq. (4)."""
    law = _law("cundall_strack", state)
    system, u, a, l = state.system, state.u, state.alpha, state.length
    normal = 1 - l  # Eq. (14): N = -(l - 1)
    f1 = 2 * normal * math.cos(a) + 2 * tangential * math.sin(a)
    f2 = 2 * normal * math.sin(a) - 2 * tangential * math.cos(a)
    expected = seed_eq_38(a, l, f1, f2, state.gamma)

    stiffness = tangent_operator(system, law, u, tangential=np.array([tangential]))
    assert stiffness.shape == (2, 2)
    np.testing.assert_allclose(stiffness, expected, rtol=0, atol=EXACT_TOL * _scale(expected))
    # Same operator from the current forces (Eq. 38 is written with F1, F2).
    at_forces = tangent_operator_at_forces(system, law, u, np.array([f1, f2]))
    np.testing.assert_allclose(at_forces, expected, rtol=0, atol=EXACT_TOL * _scale(expected))


@settings(max_examples=100, deadline=None)
@given(state=diamond_states())
def test_mcnamara_tangent_is_eq_51(state):
    """F1*, F2* are the law's equilibrium forces at u (Eq. 43)."""
    law = _law("mcnamara", state)
    system, u = state.system, state.u
    f1, f2 = generalized_forces(system, law, u)
    expected = seed_eq_51(state.alpha, state.length, f1, f2, state.gamma, state.alpha0)
    stiffness = tangent_operator(system, law, u)
    np.testing.assert_allclose(stiffness, expected, rtol=0, atol=EXACT_TOL * _scale(expected))


def test_cundall_strack_requires_its_internal_variable():
    law = make_law("cundall_strack", gamma=1.0)
    with pytest.raises(ValueError, match="tangential"):
        tangent_operator(DiamondChain(), law, np.zeros(2))
    with pytest.raises(ValueError, match="internal variable"):
        generalized_forces(DiamondChain(), law, np.zeros(2))


@pytest.mark.parametrize("name", ["weakly_hypoelastic", "mcnamara", "turco"])
def test_tangential_argument_is_ignored_for_laws_with_a_total_form(name):
    """T of a law with a total form is the law's, whatever the caller passes."""
    state = DiamondState(alpha0=0.7, gamma=1.3, length=0.85, alpha=0.95)
    law = _law(name, state)
    expected = tangent_operator(state.system, law, state.u)
    np.testing.assert_array_equal(
        tangent_operator(state.system, law, state.u, tangential=np.array([0.4])), expected
    )


# --- finite differences ---------------------------------------------------------------

# Central differences of F(Delta) with h = 1e-5.  Third derivatives of F are
# bounded by ~500 on the sampled box (terms like gamma |alpha - alpha0| / l^4
# with l >= 0.5, gamma <= 3), so truncation h^2/6 |F'''| <= 1e-8; rounding
# eps |F| / h ~ 2e-16 * 10 / 1e-5 = 2e-10.  1e-7 relative to 1 + max|K| is
# 10x that worst-case bound (the worst error measured over 20000 random states
# is 1.2e-9, the median 5e-11) and far below any wrong term.
FD_STEP = 1e-5
FD_TOL = 1e-7
# Keep the no_tension kink delta = 0 out of the stencil: delta moves by at most
# |d delta / dDelta| h <= 3 h = 3e-5, so 1e-3 is far enough.
KINK_MARGIN = 1e-3


@pytest.mark.parametrize("name", TOTAL_FORM_LAWS)
@settings(max_examples=40, deadline=None)
@given(state=diamond_states())
def test_tangent_is_the_derivative_of_the_equilibrium_forces(name, state):
    assume(abs(state.overlap(name)) > KINK_MARGIN)
    law = _law(name, state)
    system, u = state.system, state.u
    columns = []
    for j in range(2):
        step = np.zeros(2)
        step[j] = FD_STEP
        columns.append(
            (generalized_forces(system, law, u + step) - generalized_forces(system, law, u - step))
            / (2 * FD_STEP)
        )
    finite_difference = np.column_stack(columns)
    stiffness = tangent_operator(system, law, u)
    np.testing.assert_allclose(
        stiffness, finite_difference, rtol=0, atol=FD_TOL * _scale(stiffness)
    )


# --- symmetry (seed Eq. 41) -----------------------------------------------------------


@pytest.mark.parametrize("name", HYPERELASTIC_LAWS)
@settings(max_examples=60, deadline=None)
@given(state=diamond_states())
def test_hyperelastic_tangent_is_symmetric_at_equilibrium_eq_41(name, state):
    assume(abs(state.overlap(name)) > KINK_MARGIN)  # K is not defined on the kink
    stiffness = tangent_operator(state.system, _law(name, state), state.u)
    np.testing.assert_allclose(stiffness, stiffness.T, rtol=0, atol=EXACT_TOL * _scale(stiffness))
    np.testing.assert_allclose(
        skew_part(stiffness), 0.0, rtol=0, atol=EXACT_TOL * _scale(stiffness)
    )


@settings(max_examples=60, deadline=None)
@given(state=diamond_states(), tangential=tangential_forces)
def test_cundall_strack_asymmetry_is_2_t_over_l(state, tangential):
    """From Eq. (38) with Eq. (4): K21 - K12 = (F1 sin a - F2 cos a)/l = 2 T / l."""
    stiffness = tangent_operator(
        state.system, _law("cundall_strack", state), state.u, np.array([tangential])
    )
    assert stiffness[1, 0] - stiffness[0, 1] == pytest.approx(
        2 * tangential / state.length, abs=EXACT_TOL * _scale(stiffness)
    )


def test_weakly_hypoelastic_tangent_is_not_symmetric():
    """Eq. (27) violates Eq. (17): -dN/dalpha = 0 but d(l T)/dl = T, so the
    asymmetry is that of Eq. (38), K21 - K12 = 2 T / l with T = gamma (a - a0)."""
    alpha0, alpha, length, gamma = math.pi / 4, math.pi / 4 + 0.3, 0.9, 1.0
    system = DiamondChain(alpha0=alpha0)
    u = system.displacements(np.array([[length, alpha]]))
    stiffness = tangent_operator(
        system, make_law("weakly_hypoelastic", gamma=gamma, alpha0=alpha0), u
    )
    asymmetry = stiffness[1, 0] - stiffness[0, 1]
    assert asymmetry > 0.5  # clearly not symmetric: 2 * 0.3 / 0.9 = 0.667
    assert asymmetry == pytest.approx(2 * gamma * 0.3 / length, abs=EXACT_TOL * _scale(stiffness))


@settings(max_examples=60, deadline=None)
@given(state=diamond_states(), tangential=tangential_forces)
def test_mcnamara_symmetry_needs_equilibrium(state, tangential):
    """Eq. (41) holds *due to* Eq. (42): with forces F that the law does not carry
    at u, K12 - K21 = 2 (T_law - T) / l, with T the contact force of F."""
    law = _law("mcnamara", state)
    system, u, a, l = state.system, state.u, state.alpha, state.length
    normal = 1 - l
    forces = np.array(
        [
            2 * normal * math.cos(a) + 2 * tangential * math.sin(a),
            2 * normal * math.sin(a) - 2 * tangential * math.cos(a),
        ]
    )
    stiffness = tangent_operator_at_forces(system, law, u, forces)
    law_tangential = state.gamma * (a - state.alpha0) / l
    assert stiffness[0, 1] - stiffness[1, 0] == pytest.approx(
        2 * (law_tangential - tangential) / l, abs=EXACT_TOL * _scale(stiffness)
    )
    # At the law's own forces, the operator at forces is the tangent operator.
    own = tangent_operator_at_forces(system, law, u, generalized_forces(system, law, u))
    np.testing.assert_allclose(
        own, tangent_operator(system, law, u), rtol=0, atol=EXACT_TOL * _scale(own)
    )


@pytest.mark.parametrize("name", ["mcnamara", "turco", "weakly_hypoelastic"])
def test_law_contact_forces_are_recovered_from_equilibrium(name):
    state = DiamondState(alpha0=0.7, gamma=1.3, length=0.85, alpha=0.95)
    law = _law(name, state)
    normal, tangential = law_contact_forces(state.system, law, state.u)
    forces = generalized_forces(state.system, law, state.u)
    recovered = state.system.contact_forces(state.q, forces)
    np.testing.assert_allclose(recovered[0], normal, rtol=0, atol=EXACT_TOL)
    np.testing.assert_allclose(recovered[1], tangential, rtol=0, atol=EXACT_TOL)


# --- the unloaded reference state -----------------------------------------------------


@pytest.mark.parametrize("name", BASE_LAWS)
@pytest.mark.parametrize("gamma", [0.0, 0.25, 0.5, 1.0, 2.0])
def test_reference_state_at_pi_over_4(name, gamma):
    """At alpha0 = pi/4 and zero load every law gives K = [[1+g, 1-g], [1-g, 1+g]]:
    det K = 4 gamma and, with F2 held and Delta1 driven, dF1/dDelta1 =
    det K / K22 = 4 gamma / (1 + gamma) (seed Eq. 35; the common initial slope
    of Figs. 6-7 and 13)."""
    system = DiamondChain(alpha0=math.pi / 4)
    law = make_law(name, gamma=gamma, alpha0=math.pi / 4)
    stiffness = tangent_operator(system, law, np.zeros(2), tangential=np.zeros(1))
    np.testing.assert_allclose(
        stiffness, [[1 + gamma, 1 - gamma], [1 - gamma, 1 + gamma]], rtol=0, atol=EXACT_TOL
    )
    assert det_K(stiffness) == pytest.approx(4 * gamma, abs=EXACT_TOL)
    slope = mixed_control_stiffness(stiffness, [1])
    assert slope == pytest.approx(4 * gamma / (1 + gamma), abs=EXACT_TOL)
    assert slope == pytest.approx(det_K(stiffness) / stiffness[1, 1], abs=EXACT_TOL)
    assert mixed_control_determinant(stiffness, [1]) == pytest.approx(1 + gamma, abs=EXACT_TOL)


@pytest.mark.parametrize("name", ["mcnamara+no_tension", "turco+no_tension"])
def test_no_tension_contact_touching_at_rest_is_closed(name):
    """At u = 0 the overlap is exactly 0: a contact that touches is closed, so
    the tangent is the closed one, [[1+g, 1-g], [1-g, 1+g]] at alpha0 = pi/4, and
    the mixed-control slope is 4 g/(1 + g) as for the law without the bracket.
    The Macaulay bracket is a Piecewise closed at delta = 0 (docs/laws.md)."""
    gamma = 0.7
    system = DiamondChain(alpha0=math.pi / 4)
    stiffness = tangent_operator(
        system, make_law(name, gamma=gamma, alpha0=math.pi / 4), np.zeros(2)
    )
    closed = np.array([[1 + gamma, 1 - gamma], [1 - gamma, 1 + gamma]])
    np.testing.assert_allclose(stiffness, closed, rtol=0, atol=EXACT_TOL)
    assert mixed_control_stiffness(stiffness, [1]) == pytest.approx(4 * gamma / (1 + gamma), abs=EXACT_TOL)


# --- indicators -----------------------------------------------------------------------


def _random_stiffness(rng: np.random.Generator, shape: tuple[int, ...]) -> np.ndarray:
    return rng.normal(size=shape)


def test_indicators_on_batches_equal_the_loop(rng):
    stiffness = _random_stiffness(rng, (7, 5, 2, 2))
    direction = rng.normal(size=(7, 5, 2))
    batched = {
        "det": det_K(stiffness),
        "hill": hill_eigenvalue(stiffness),
        "flutter": flutter_discriminant(stiffness),
        "work": second_order_work(stiffness, direction),
        "normalized_work": normalized_second_order_work(stiffness, direction),
        "mixed_det_1": mixed_control_determinant(stiffness, [1]),
        "mixed_det_0": mixed_control_determinant(stiffness, [0]),
        "mixed_det_all": mixed_control_determinant(stiffness, [0, 1]),
        "mixed_det_mask": mixed_control_determinant(stiffness, np.array([False, True])),
        "mixed_det_none": mixed_control_determinant(stiffness, []),
        "mixed_1": mixed_control_stiffness(stiffness, [1]),
        "mixed_0": mixed_control_stiffness(stiffness, [0]),
        "sym": symmetric_part(stiffness),
        "skew": skew_part(stiffness),
    }
    for key, value in batched.items():
        expected_shape = (7, 5, 2, 2) if key in ("sym", "skew") else (7, 5)
        assert value.shape == expected_shape, key
    for i in range(7):
        for j in range(5):
            k, du = stiffness[i, j], direction[i, j]
            single = {
                "det": k[0, 0] * k[1, 1] - k[0, 1] * k[1, 0],
                "hill": np.linalg.eigvalsh((k + k.T) / 2)[0],
                "flutter": np.trace(k) ** 2 - 4 * np.linalg.det(k),
                "work": du @ k @ du,
                "normalized_work": du @ k @ du / (du @ du),
                "mixed_det_1": k[1, 1],
                "mixed_det_0": k[0, 0],
                "mixed_det_all": np.linalg.det(k),
                "mixed_det_mask": k[1, 1],
                "mixed_det_none": 1.0,
                "mixed_1": np.linalg.det(k) / k[1, 1],
                "mixed_0": np.linalg.det(k) / k[0, 0],
                "sym": (k + k.T) / 2,
                "skew": (k - k.T) / 2,
            }
            for key, value in single.items():
                # O(1) random entries: the batched closed forms and numpy's LU /
                # eigvalsh differ by rounding only; the mixed stiffness divides by
                # a pivot that can be small, so its tolerance is relative.
                np.testing.assert_allclose(
                    batched[key][i, j], value, rtol=1e-10, atol=1e-12, err_msg=key
                )
    # (K + K^T)/2 + (K - K^T)/2 = K up to one rounding of O(1) entries (~1 ulp).
    np.testing.assert_allclose(
        symmetric_part(stiffness) + skew_part(stiffness), stiffness, rtol=0, atol=1e-15
    )


def test_normalized_second_order_work_is_bounded_by_the_hill_eigenvalue(rng):
    stiffness = _random_stiffness(rng, (200, 2, 2))
    direction = rng.normal(size=(200, 2))
    normalized = normalized_second_order_work(stiffness, direction)
    eigenvalues = np.linalg.eigvalsh(symmetric_part(stiffness))
    # Rayleigh quotient bounds, up to rounding of O(1) numbers.
    assert np.all(normalized >= eigenvalues[:, 0] - 1e-12)
    assert np.all(normalized <= eigenvalues[:, 1] + 1e-12)
    # Homogeneous of degree 0 in the direction, of degree 2 for the raw work;
    # scaling by 3 changes only the rounding of a 2-term sum: 1e-13 relative is
    # ~500 ulp, except for near-cancelling sums, which O(1) random data avoid.
    np.testing.assert_allclose(
        normalized_second_order_work(stiffness, 3 * direction), normalized, rtol=1e-13
    )
    np.testing.assert_allclose(
        second_order_work(stiffness, 3 * direction),
        9 * second_order_work(stiffness, direction),
        rtol=1e-13,
    )


@pytest.mark.parametrize("n", [2, 3])
def test_hill_eigenvalue_is_the_smallest_eigenvalue_of_the_symmetric_part(rng, n):
    stiffness = _random_stiffness(rng, (500, n, n)) * rng.uniform(0.1, 10, size=(500, 1, 1))
    expected = np.linalg.eigvalsh(symmetric_part(stiffness))[:, 0]
    # Closed form (n = 2) vs LAPACK: both backward stable, error ~ eps * |K|.
    np.testing.assert_allclose(
        hill_eigenvalue(stiffness), expected, rtol=0, atol=1e-12 * (1 + np.abs(stiffness).max())
    )


@pytest.mark.parametrize("n", [2, 3])
def test_flutter_discriminant_is_negative_exactly_for_complex_eigenvalues(rng, n):
    stiffness = _random_stiffness(rng, (2000, n, n))
    discriminant = flutter_discriminant(stiffness)
    eigenvalues = np.linalg.eigvals(stiffness)
    complex_pair = np.abs(eigenvalues.imag).max(axis=-1) > 1e-9
    # Leave out the near-degenerate matrices where the sign is decided by rounding.
    clear = np.abs(discriminant) > 1e-6
    assert clear.sum() > 1900
    assert complex_pair[clear].any() and (~complex_pair[clear]).any()  # both cases occur
    np.testing.assert_array_equal((discriminant < 0)[clear], complex_pair[clear])
    # Value: prod_{i<j} (lambda_i - lambda_j)^2.  The eigenvalues from LAPACK
    # carry errors ~ eps |K| / gap; squared differences of near-equal eigenvalues
    # lose more, hence a loose 1e-8 relative (any wrong formula is off by O(1)).
    expected = np.ones(len(stiffness), dtype=complex)
    for i in range(n):
        for j in range(i + 1, n):
            expected *= (eigenvalues[:, i] - eigenvalues[:, j]) ** 2
    np.testing.assert_allclose(discriminant, expected.real, rtol=1e-8, atol=1e-10)


def test_three_by_three_det_and_batch_shapes(rng):
    stiffness = _random_stiffness(rng, (7, 5, 3, 3))
    # Same LU / closed form on O(1) entries: rounding only, so 1e-12 (relative
    # and absolute) is ~1000 ulp; the stiffness quotient divides by a block
    # determinant that may be small, hence 1e-10 relative for it.
    np.testing.assert_allclose(det_K(stiffness), np.linalg.det(stiffness), rtol=1e-12, atol=1e-12)
    assert hill_eigenvalue(stiffness).shape == (7, 5)
    assert flutter_discriminant(stiffness).shape == (7, 5)
    # Mixed control on three dofs: K_SS is the 2x2 block of the held forces.
    block = mixed_control_determinant(stiffness, [0, 2])
    np.testing.assert_allclose(
        block, np.linalg.det(stiffness[..., [0, 2], :][..., :, [0, 2]]), rtol=1e-12, atol=1e-12
    )
    np.testing.assert_allclose(
        mixed_control_determinant(stiffness, [0, 1, 2]),
        np.linalg.det(stiffness),
        rtol=1e-12,
        atol=1e-12,
    )
    np.testing.assert_allclose(
        mixed_control_stiffness(stiffness, [0, 2]),
        np.linalg.det(stiffness) / block,
        rtol=1e-10,
        atol=1e-12,
    )


def test_mixed_control_stiffness_is_the_schur_complement(rng):
    """With F2 held (dF2 = 0) the response to dDelta1 is dF1 = (K11 - K12 K21/K22) dDelta1,
    seed Eq. (35): solve the mixed problem directly and compare."""
    stiffness = _random_stiffness(rng, (50, 2, 2))
    stiffness[:, 1, 1] = np.sign(stiffness[:, 1, 1]) * (
        0.5 + np.abs(stiffness[:, 1, 1])
    )  # K22 away from 0
    response = []
    for k in stiffness:
        d_delta2 = -k[1, 0] / k[1, 1]  # dF2 = K21 + K22 dDelta2 = 0 for dDelta1 = 1
        response.append(k[0, 0] + k[0, 1] * d_delta2)
    # Two algebraically equal expressions on O(1) entries with |K22| >= 0.5:
    # they differ by rounding only (a few ulp), 1e-12 is ample.
    np.testing.assert_allclose(
        mixed_control_stiffness(stiffness, [1]), response, rtol=1e-12, atol=1e-12
    )


def test_force_controlled_selection_is_validated():
    stiffness = np.eye(2)
    with pytest.raises(ValueError, match="out of range"):
        mixed_control_determinant(stiffness, [2])
    with pytest.raises(ValueError, match="length 2"):
        mixed_control_determinant(stiffness, np.array([True, False, True]))


@pytest.mark.parametrize("name", ["cundall_strack", "mcnamara", "turco", "turco+no_tension"])
def test_tangent_operator_broadcasts_over_parameter_sweeps(rng, name):
    """gamma (7, 1) and alpha0 (7, 1) against states (7, 5): K is (7, 5, 2, 2)
    and equals the per-case computation (bitwise up to rounding)."""
    gamma = rng.uniform(0, 3, size=(7, 1))
    alpha0 = rng.uniform(0.2, 1.35, size=(7, 1))
    length = rng.uniform(0.6, 1.4, size=(7, 5))
    alpha = rng.uniform(0.1, 1.45, size=(7, 5))
    tangential = rng.uniform(-1, 1, size=(7, 5, 1))
    system = DiamondChain(alpha0=alpha0)
    u = system.displacements(np.stack([length, alpha], axis=-1)[..., None, :])
    assert u.shape == (7, 5, 2)
    law = make_law(name, gamma=gamma, alpha0=alpha0)
    stiffness = tangent_operator(system, law, u, tangential=tangential)
    assert stiffness.shape == (7, 5, 2, 2)
    for i in range(7):
        single_system = DiamondChain(alpha0=float(alpha0[i, 0]))
        single_law = make_law(name, gamma=float(gamma[i, 0]), alpha0=float(alpha0[i, 0]))
        for j in range(5):
            single = tangent_operator(
                single_system, single_law, u[i, j], tangential=tangential[i, j]
            )
            # Same arithmetic on broadcast arrays: agreement to rounding.
            np.testing.assert_allclose(
                stiffness[i, j], single, rtol=0, atol=EXACT_TOL * _scale(single)
            )


def test_law_and_system_must_share_alpha0():
    """alpha0 is one quantity (seed Eq. 1 and 18): two values are refused, naming it."""
    with pytest.raises(ValueError, match="alpha0"):
        tangent_operator(DiamondChain(alpha0=0.7), make_law("mcnamara", gamma=1.0, alpha0=0.8), np.zeros(2))
