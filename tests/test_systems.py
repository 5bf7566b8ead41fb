"""The diamond chain: kinematics (seed Eq. 1-3, 10-11), statics (Eq. 4), geometry (Eq. 66-67)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ncstab.systems import SYSTEMS, DiamondChain, DiscreteSystem
from ncstab.systems.granular import symmetric_diamond
from strategies import DiamondState, diamond_states

# Round trips and hand-written closed forms go through a few trigonometric
# evaluations of O(1) numbers: they agree to a few ulp, so 1e-12 is generous and
# still far below any real error (a wrong sign or factor is O(1e-2) or more).
EXACT_TOL = 1e-12
# Central differences with h = 1e-6 of q(u) (for J) and of J(u) (for H): the
# third derivatives of J are fourth derivatives of q, bounded by ~24 / l^4 <= 400
# for l >= 0.5, so truncation h^2/6 * 400 ~ 7e-11; rounding eps |J| / h ~
# 2e-16 * 2 / 1e-6 = 4e-10.  1e-8 is 20x that bound and far below any wrong entry.
FD_STEP = 1e-6
FD_TOL = 1e-8

displacements = st.tuples(st.floats(-0.4, 0.4), st.floats(-0.4, 0.4))


def _central_difference(function, u: np.ndarray, h: float) -> np.ndarray:
    """d function / du, derivative index last: shape function(u).shape + (2,)."""
    columns = []
    for j in range(2):
        step = np.zeros(2)
        step[j] = h
        columns.append((function(u + step) - function(u - step)) / (2 * h))
    return np.stack(columns, axis=-1)


def test_diamond_chain_implements_the_protocol():
    system = DiamondChain()
    assert isinstance(system, DiscreteSystem)
    assert SYSTEMS["diamond"].build() == symmetric_diamond()
    assert system.n_dof == 2 and system.n_contacts == 1
    np.testing.assert_array_equal(system.contact_weights, [2.0])
    np.testing.assert_array_equal(system.mass_matrix(), np.eye(2))
    assert DiamondChain(alpha0=np.array([0.5, 0.7])).mass_matrix().shape == (2, 2, 2)


@pytest.mark.parametrize("alpha0", [0.0, -0.1, 3.0, math.pi / 2, math.nan, np.array([0.5, 2.0])])
def test_bad_alpha0_is_rejected_naming_it(alpha0):
    with pytest.raises(ValueError, match="parameter 'alpha0'"):
        DiamondChain(alpha0=alpha0)


@settings(max_examples=50, deadline=None)
@given(alpha0=st.floats(0.2, 1.35), u=displacements)
def test_kinematics_round_trip_u_q_u(alpha0, u):
    """Eq. (1) then Eq. (3): Delta -> (l, alpha) -> Delta is the identity."""
    system = DiamondChain(alpha0=alpha0)
    u = np.array(u)
    q = system.contact_variables(u)
    assert q.shape == (1, 2)
    np.testing.assert_allclose(system.displacements(q), u, rtol=0, atol=EXACT_TOL)


@settings(max_examples=50, deadline=None)
@given(state=diamond_states())
def test_kinematics_round_trip_q_u_q_and_eq_1(state: DiamondState):
    """(l, alpha) -> Delta -> (l, alpha), and Eq. (1) written by hand."""
    system, u = state.system, state.u
    np.testing.assert_allclose(system.contact_variables(u), state.q, rtol=0, atol=EXACT_TOL)
    vertical = math.cos(state.alpha0) - u[0]
    horizontal = math.sin(state.alpha0) - u[1]
    assert math.tan(state.alpha) == pytest.approx(horizontal / vertical, rel=EXACT_TOL)
    assert state.length == pytest.approx(math.hypot(vertical, horizontal), abs=EXACT_TOL)


@settings(max_examples=50, deadline=None)
@given(alpha0=st.floats(0.2, 1.35), length=st.floats(0.2, 2.0), alpha=st.floats(-3.1, 3.1))
def test_kinematics_round_trip_in_every_quadrant(alpha0, length, alpha):
    """Eq. (1) must pick the quadrant of alpha from the signs of both
    components (tan alpha alone loses it): the round trip holds for any alpha
    in (-pi, pi), not only in the first quadrant."""
    system = DiamondChain(alpha0=alpha0)
    q = np.array([[length, alpha]])
    np.testing.assert_allclose(
        system.contact_variables(system.displacements(q)), q, rtol=0, atol=EXACT_TOL
    )


def test_reference_configuration_is_l_1_alpha_alpha0():
    system = DiamondChain(alpha0=0.6)
    np.testing.assert_allclose(
        system.contact_variables(np.zeros(2)), [[1.0, 0.6]], rtol=0, atol=EXACT_TOL
    )


@settings(max_examples=50, deadline=None)
@given(state=diamond_states())
def test_contact_jacobian_is_the_derivative_of_the_kinematics(state):
    """J = d(l, alpha)/dDelta, seed Eq. (10)-(11)."""
    system, u = state.system, state.u
    jacobian = system.contact_jacobian(system.contact_variables(u))
    assert jacobian.shape == (1, 2, 2)
    finite_difference = _central_difference(system.contact_variables, u, FD_STEP)
    np.testing.assert_allclose(jacobian, finite_difference, rtol=0, atol=FD_TOL)
    # Eq. (10)-(11) by hand: dl = -cos dD1 - sin dD2, l dalpha = sin dD1 - cos dD2.
    c, s, l = math.cos(state.alpha), math.sin(state.alpha), state.length
    np.testing.assert_allclose(jacobian[0], [[-c, -s], [s / l, -c / l]], rtol=0, atol=EXACT_TOL)


@settings(max_examples=50, deadline=None)
@given(state=diamond_states())
def test_contact_hessian_is_the_derivative_of_the_jacobian(state):
    system, u = state.system, state.u
    hessian = system.contact_hessian(system.contact_variables(u))
    assert hessian.shape == (1, 2, 2, 2)
    finite_difference = _central_difference(
        lambda v: system.contact_jacobian(system.contact_variables(v)), u, FD_STEP
    )
    np.testing.assert_allclose(hessian, finite_difference, rtol=0, atol=FD_TOL)
    np.testing.assert_array_equal(hessian, np.swapaxes(hessian, -1, -2))


@settings(max_examples=50, deadline=None)
@given(state=diamond_states(), normal=st.floats(-1, 1), tangential=st.floats(-1, 1))
def test_generalized_forces_are_eq_4_and_contact_forces_invert_them(state, normal, tangential):
    """Seed Eq. (4): F1 = 2N cos a + 2T sin a, F2 = 2N sin a - 2T cos a."""
    system, q, a = state.system, state.q, state.alpha
    forces = system.generalized_forces(q, np.array([normal]), np.array([tangential]))
    expected = [
        2 * normal * math.cos(a) + 2 * tangential * math.sin(a),
        2 * normal * math.sin(a) - 2 * tangential * math.cos(a),
    ]
    assert forces.shape == (2,)
    np.testing.assert_allclose(forces, expected, rtol=0, atol=EXACT_TOL)
    recovered_normal, recovered_tangential = system.contact_forces(q, forces)
    assert recovered_normal.shape == recovered_tangential.shape == (1,)
    np.testing.assert_allclose(recovered_normal, [normal], rtol=0, atol=EXACT_TOL)
    np.testing.assert_allclose(recovered_tangential, [tangential], rtol=0, atol=EXACT_TOL)


@settings(max_examples=50, deadline=None)
@given(state=diamond_states())
def test_secondary_gaps_are_the_distances_to_the_second_neighbours(state):
    """Top-bottom centres are 2 l cos(alpha) apart, left-right 2 l sin(alpha)
    (units of 2R), so the gaps are 2 l cos(alpha) - 1 and 2 l sin(alpha) - 1."""
    gaps = state.system.secondary_gaps(state.q)
    expected = [
        2 * state.length * math.cos(state.alpha) - 1,
        2 * state.length * math.sin(state.alpha) - 1,
    ]
    np.testing.assert_allclose(gaps, expected, rtol=0, atol=EXACT_TOL)
    assert state.system.secondary_gap_names() == ("top_bottom", "left_right")


def test_blocking_contact_at_alpha_pi_over_3_eq_66_67():
    """Seed Eq. (66)-(67): with l = 1 the top and bottom grains touch at
    alpha_max = pi/3, i.e. at Delta_1* = cos(alpha0) - 1/2 = (sqrt 2 - 1)/2 for
    alpha0 = pi/4."""
    system = DiamondChain(alpha0=math.pi / 4)
    q = np.array([[1.0, math.pi / 3]])
    assert system.secondary_gaps(q)[0] == pytest.approx(0.0, abs=EXACT_TOL)
    assert system.secondary_gaps(np.array([[1.0, math.pi / 3 - 0.01]]))[0] > 0  # not yet
    assert system.displacements(q)[0] == pytest.approx((math.sqrt(2) - 1) / 2, abs=EXACT_TOL)
    # Left and right grains are far apart there: 2 sin(pi/3) - 1 = sqrt(3) - 1.
    assert system.secondary_gaps(q)[1] == pytest.approx(math.sqrt(3) - 1, abs=EXACT_TOL)


def test_kinematics_broadcast_over_alpha0_and_states():
    alpha0 = np.array([[0.4], [0.8], [1.2]])
    system = DiamondChain(alpha0=alpha0)
    rng = np.random.default_rng(3)
    u = rng.uniform(-0.3, 0.3, size=(3, 4, 2))
    q = system.contact_variables(u)
    assert q.shape == (3, 4, 1, 2)
    assert system.contact_jacobian(q).shape == (3, 4, 1, 2, 2)
    assert system.contact_hessian(q).shape == (3, 4, 1, 2, 2, 2)
    assert system.secondary_gaps(q).shape == (3, 4, 2)
    for i in range(3):
        single = DiamondChain(alpha0=float(alpha0[i, 0]))
        for j in range(4):
            np.testing.assert_allclose(
                q[i, j], single.contact_variables(u[i, j]), rtol=0, atol=EXACT_TOL
            )
    np.testing.assert_allclose(system.displacements(q), u, rtol=0, atol=EXACT_TOL)
