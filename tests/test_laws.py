"""The law catalogue, parameter validation and the numeric forms of each law.

Every expected value is the seed's equation written by hand in the
dimensionless variables of Eq. (37): l = l*/(2R), N and T in units of 2R k_n.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings

from ncstab.laws import LAWS, MODIFIERS, law_definition, law_names, make_law, no_tension
from ncstab.symbolic import compile_law, derive_law
from strategies import BASE_LAWS, DEM_LAWS, NO_TENSION_LAWS, DiamondState, diamond_states, tangential_forces

# Values of order 1-10 computed through a handful of floating-point operations
# differ from the hand-written formula by a few ulp: 1e-13 leaves two orders of
# magnitude of margin and still catches any wrong term (which is O(1e-2) or more).
VALUE_TOL = 1e-13


def _compiled(name: str, state: DiamondState):
    law = make_law(name, gamma=state.gamma, alpha0=state.alpha0)
    return law, compile_law(law.definition)


# --- catalogue ------------------------------------------------------------------------


def test_catalogue_lists_the_seed_laws_the_dem_rules_their_modified_variants_and_the_spring_laws():
    assert law_names() == list(BASE_LAWS) + list(DEM_LAWS) + ["linear_spring"]
    assert set(LAWS) == set(BASE_LAWS) | set(DEM_LAWS)
    dem_no_tension = [f"{name}+no_tension" for name in DEM_LAWS]
    assert law_names(with_modifiers=True) == (
        list(BASE_LAWS) + list(DEM_LAWS) + list(NO_TENSION_LAWS) + dem_no_tension + ["linear_spring"]
    )
    assert set(MODIFIERS) == {"no_tension"}
    assert law_definition("linear_spring").kind == "spring"


@pytest.mark.parametrize("name", BASE_LAWS)
def test_no_tension_modifier_marks_the_definition_and_is_idempotent(name):
    base = law_definition(name)
    modified = law_definition(f"{name}+no_tension")
    assert not base.no_tension
    assert modified.no_tension
    assert modified.name == f"{name}+no_tension"
    assert no_tension(modified) is modified
    # Only the normal overlap changes: the law's own expressions are untouched.
    assert modified.normal_force == base.normal_force
    assert modified.tangential_force == base.tangential_force
    assert modified.tangential_rate == base.tangential_rate


def test_make_law_defaults_alpha0_to_pi_over_4_and_keeps_array_parameters():
    law = make_law("mcnamara", gamma=[0.5, 2.0])
    assert law.name == "mcnamara"
    assert float(law.parameters["alpha0"]) == pytest.approx(math.pi / 4, abs=0)
    np.testing.assert_array_equal(law.parameters["gamma"], [0.5, 2.0])
    assert law.parameter_values()[0] is law.parameters["gamma"]


def test_compile_law_and_derive_law_are_cached():
    definition = law_definition("turco+no_tension")
    assert compile_law(definition) is compile_law(definition)
    assert derive_law(definition) is derive_law(definition)
    # The registry hands back equal definitions, so the cache is hit by name too.
    assert compile_law(law_definition("turco+no_tension")) is compile_law(definition)


# --- validation -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("parameters", "field"),
    [
        ({"gamma": -1.0}, "gamma"),
        ({"gamma": math.nan}, "gamma"),
        ({"gamma": math.inf}, "gamma"),
        ({"gamma": 1.0, "alpha0": 0.0}, "alpha0"),
        ({"gamma": 1.0, "alpha0": math.pi / 2}, "alpha0"),
        ({"gamma": 1.0, "alpha0": 2.0}, "alpha0"),
        ({"gamma": 1.0, "alpha0": np.array([0.3, 0.7, 1.8, 1.0])}, "alpha0"),
        ({"gamma": np.array([[0.5], [-0.1]])}, "gamma"),
        ({"gamma": "stiff"}, "gamma"),
    ],
)
def test_bad_parameter_values_raise_naming_the_parameter(parameters, field):
    with pytest.raises(ValueError, match=rf"parameter '{field}'") as info:
        make_law("mcnamara", **parameters)
    # The message also says what is allowed.
    assert "allowed" in str(info.value) or "must be" in str(info.value)


def test_array_parameter_error_shows_the_offending_entry():
    with pytest.raises(ValueError, match=r"alpha0.*= 1\.8 "):
        make_law("turco", gamma=1.0, alpha0=np.array([0.3, 0.7, 1.8, 1.0]))


def test_unknown_law_lists_the_catalogue_and_suggests_the_close_name():
    with pytest.raises(ValueError, match="unknown law 'mcnamra'") as info:
        make_law("mcnamra", gamma=1.0)
    message = str(info.value)
    assert "did you mean 'mcnamara'" in message
    assert "catalogue" in message
    for name in BASE_LAWS:
        assert name in message


def test_unknown_modifier_names_it_and_suggests_the_close_name():
    with pytest.raises(ValueError, match="unknown law modifier 'no_tenson'") as info:
        law_definition("turco+no_tenson")
    assert "did you mean 'no_tension'" in str(info.value)


@pytest.mark.parametrize("name", ["", "   ", None])
def test_empty_law_name_is_rejected(name):
    with pytest.raises(ValueError, match="law name"):
        law_definition(name)


def test_unknown_parameter_name_is_named_with_the_laws_parameters():
    with pytest.raises(ValueError, match="no parameter.*'gama'") as info:
        make_law("mcnamara", gama=1.0)
    assert "gamma, alpha0" in str(info.value)


def test_missing_parameter_without_default_is_named():
    with pytest.raises(ValueError, match="needs parameter 'gamma'"):
        make_law("weakly_hypoelastic", alpha0=0.5)


# --- the laws, seed equations written by hand -----------------------------------------


@settings(max_examples=40, deadline=None)
@given(state=diamond_states(), normal=tangential_forces, tangential=tangential_forces)
def test_cundall_strack_rate_matrix_is_eq_13(state, normal, tangential):
    """Seed Eq. (13) dimensionless: dN = -dl, dT = gamma l dalpha, whatever (N, T)."""
    law, compiled = _compiled("cundall_strack", state)
    rate = compiled.rate_matrix(law, state.length, state.alpha, normal, tangential)
    expected = np.array([[-1.0, 0.0], [0.0, state.gamma * state.length]])
    assert rate.shape == (2, 2)
    np.testing.assert_allclose(rate, expected, rtol=0, atol=VALUE_TOL)
    np.testing.assert_allclose(
        compiled.normal_force(law, state.length, state.alpha),
        1 - state.length,
        rtol=0,
        atol=VALUE_TOL,
    )


def test_cundall_strack_has_no_total_tangential_force_and_no_energy():
    law = make_law("cundall_strack", gamma=1.0)
    compiled = compile_law(law.definition)
    assert compiled.tangential_function is None
    with pytest.raises(ValueError, match="internal variable"):
        compiled.tangential_force(law, 1.0, 0.5)
    with pytest.raises(ValueError, match="no potential"):
        compiled.energy(law, 1.0, 0.5)
    assert law.internal_variables == ("T",)
    assert not law.has_total_form


@settings(max_examples=40, deadline=None)
@given(state=diamond_states())
def test_weakly_hypoelastic_forces_are_eq_27(state):
    """Seed Eq. (27) dimensionless: N = -(l - 1), T = gamma (alpha - alpha0)."""
    law, compiled = _compiled("weakly_hypoelastic", state)
    l, a = state.length, state.alpha
    np.testing.assert_allclose(compiled.normal_force(law, l, a), -(l - 1), rtol=0, atol=VALUE_TOL)
    np.testing.assert_allclose(
        compiled.tangential_force(law, l, a),
        state.gamma * (a - state.alpha0),
        rtol=0,
        atol=VALUE_TOL,
    )
    with pytest.raises(ValueError, match="no potential"):
        compiled.energy(law, l, a)


@settings(max_examples=40, deadline=None)
@given(state=diamond_states())
def test_mcnamara_forces_are_eq_18(state):
    """Seed Eq. (18) dimensionless: N = -(l - 1), l T = gamma (alpha - alpha0)."""
    law, compiled = _compiled("mcnamara", state)
    l, a = state.length, state.alpha
    np.testing.assert_allclose(compiled.normal_force(law, l, a), -(l - 1), rtol=0, atol=VALUE_TOL)
    np.testing.assert_allclose(
        l * compiled.tangential_force(law, l, a),
        state.gamma * (a - state.alpha0),
        rtol=0,
        atol=VALUE_TOL,
    )


@settings(max_examples=40, deadline=None)
@given(state=diamond_states())
def test_turco_forces_are_eq_28(state):
    """Seed Eq. (28) dimensionless: N = -(l - cos(a - a0)),
    l T = sin(a - a0)(l - cos(a - a0)) + gamma sin(a - a0) cos(a - a0)."""
    law, compiled = _compiled("turco", state)
    l, a, g = state.length, state.alpha, state.gamma
    s, c = np.sin(a - state.alpha0), np.cos(a - state.alpha0)
    np.testing.assert_allclose(compiled.normal_force(law, l, a), -(l - c), rtol=0, atol=VALUE_TOL)
    np.testing.assert_allclose(
        l * compiled.tangential_force(law, l, a), s * (l - c) + g * s * c, rtol=0, atol=VALUE_TOL
    )


@pytest.mark.parametrize("name", ["cundall_strack", "weakly_hypoelastic", "mcnamara"])
@settings(max_examples=30, deadline=None)
@given(state=diamond_states())
def test_no_tension_normal_force_is_the_macaulay_bracket_eq_59(name, state):
    """Seed Eq. (59): N = <1 - l> = max(1 - l, 0) for the rotational-spring laws."""
    modified, compiled = _compiled(f"{name}+no_tension", state)
    base, base_compiled = _compiled(name, state)
    l, a = state.length, state.alpha
    np.testing.assert_allclose(
        compiled.normal_force(modified, l, a), max(1 - l, 0.0), rtol=0, atol=VALUE_TOL
    )
    if base_compiled.tangential_function is not None:
        # The tangential force of these laws carries no normal spring: unchanged.
        np.testing.assert_allclose(
            compiled.tangential_force(modified, l, a),
            base_compiled.tangential_force(base, l, a),
            rtol=0,
            atol=VALUE_TOL,
        )


@settings(max_examples=40, deadline=None)
@given(state=diamond_states())
def test_turco_no_tension_drops_the_normal_spring_when_the_contact_opens(state):
    """Eq. (28) with <cos(a - a0) - l>: for l > cos(a - a0) the contact is open,
    N = 0 and l T = gamma sin(a - a0) cos(a - a0) (only the shear spring)."""
    law, compiled = _compiled("turco+no_tension", state)
    l, a, g = state.length, state.alpha, state.gamma
    s, c = np.sin(a - state.alpha0), np.cos(a - state.alpha0)
    overlap = max(c - l, 0.0)
    np.testing.assert_allclose(compiled.normal_force(law, l, a), overlap, rtol=0, atol=VALUE_TOL)
    np.testing.assert_allclose(
        l * compiled.tangential_force(law, l, a), -s * overlap + g * s * c, rtol=0, atol=VALUE_TOL
    )


def test_turco_no_tension_on_both_sides_of_the_kink():
    """Two fixed states, one closed and one open, against Eq. (28) by hand."""
    gamma, alpha0, alpha = 0.5, math.pi / 4, math.pi / 4 + 0.2
    law = make_law("turco+no_tension", gamma=gamma, alpha0=alpha0)
    plain = make_law("turco", gamma=gamma, alpha0=alpha0)
    compiled, plain_compiled = compile_law(law.definition), compile_law(plain.definition)
    s, c = math.sin(0.2), math.cos(0.2)
    closed, opened = 0.9 * c, 1.1 * c
    # Closed: identical to Turco.
    assert compiled.tangential_force(law, closed, alpha) == pytest.approx(
        plain_compiled.tangential_force(plain, closed, alpha), abs=VALUE_TOL
    )
    # Open: no normal force, shear spring only, and different from plain Turco.
    assert compiled.normal_force(law, opened, alpha) == 0.0
    assert opened * compiled.tangential_force(law, opened, alpha) == pytest.approx(
        gamma * s * c, abs=VALUE_TOL
    )
    assert opened * plain_compiled.tangential_force(plain, opened, alpha) == pytest.approx(
        s * (opened - c) + gamma * s * c, abs=VALUE_TOL
    )


def test_law_functions_broadcast_over_parameter_sweeps():
    """One Law stands for a sweep: gamma (3, 1) against states (4,) gives (3, 4)."""
    gamma = np.array([[0.0], [0.5], [2.0]])
    law = make_law("mcnamara", gamma=gamma, alpha0=0.6)
    compiled = compile_law(law.definition)
    l = np.linspace(0.8, 1.2, 4)
    a = np.linspace(0.3, 0.9, 4)
    tangential = compiled.tangential_force(law, l, a)
    assert tangential.shape == (3, 4)
    np.testing.assert_allclose(tangential, gamma * (a - 0.6) / l, rtol=0, atol=VALUE_TOL)
    # Constant entries of the rate matrix (dN/dl = -1) are broadcast like the others.
    rate = compiled.rate_matrix(law, l, a, 0.0, 0.0)
    assert rate.shape == (3, 4, 2, 2)
    np.testing.assert_array_equal(rate[..., 0, 0], -np.ones((3, 4)))
