"""Classification by the seed's integrability conditions, energies, rate matrices."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sympy as sp
from hypothesis import assume, given, settings

from ncstab.laws import (
    ALPHA,
    ALPHA0,
    DELTA,
    GAMMA,
    MCNAMARA,
    TURCO,
    L,
    LawDefinition,
    N,
    T,
    law_definition,
    make_law,
    no_tension,
)
from ncstab.symbolic import (
    HYPERELASTIC,
    STRONGLY_HYPOELASTIC,
    WEAKLY_HYPOELASTIC,
    classify,
    compile_law,
    derive_law,
    is_identically_zero,
    kinematic_integrability,
)
from strategies import BASE_LAWS, EXPECTED_CLASS, HYPERELASTIC_LAWS, TOTAL_FORM_LAWS, diamond_states

# Central differences with step h = 1e-5.  On the sampled box (l >= 0.5,
# gamma <= 3, |alpha - alpha0| <= 1.3) the largest third derivative is that of
# McNamara's T = gamma (alpha - alpha0) / l, 6 gamma |alpha - alpha0| / l^4 <= 400
# (energies: <= 1 + 4 gamma = 13), so truncation h^2/6 |f'''| <= 7e-9; rounding
# eps |f| / h <= 2e-16 * 10 / 1e-5 = 2e-10.  1e-7 (relative to 1 + |f'|) is 15x
# the worst-case bound and far below any wrong term (O(1e-2) or more).
FD_STEP = 1e-5
FD_TOL = 1e-7
# The no_tension kink delta = 0 must be farther than the stencil reaches
# (|d delta / d(l, alpha)| <= 2, so 2 h = 2e-5); 1e-3 leaves a wide margin.
KINK_MARGIN = 1e-3


def _test_law(name: str, **fields) -> LawDefinition:
    return LawDefinition(
        name=name, title=f"test law {name}", equations="none", normal_overlap=1 - L, **fields
    )


# --- the seed's four laws -------------------------------------------------------------


@pytest.mark.parametrize("name", BASE_LAWS)
@pytest.mark.parametrize("modifier", ["", "+no_tension"])
def test_catalogue_laws_classify_as_in_the_seed(name, modifier):
    """Seed: Cundall--Strack strongly hypoelastic (Eq. 13-15), constant lever arm
    weakly hypoelastic (Eq. 26-27), McNamara and Turco hyperelastic (Eq. 17-19,
    28-29); the no-tension bracket (Eq. 59) keeps the class of its base law."""
    result = classify(law_definition(name + modifier))
    assert result.kind == EXPECTED_CLASS[name]
    assert result.law == name + modifier
    assert (result.energy is not None) == (result.kind == HYPERELASTIC)
    assert len(result.checks) == 3


def test_deciding_conditions_are_the_seeds():
    cundall = classify(law_definition("cundall_strack"))
    assert cundall.deciding_condition.name.startswith("Frobenius")
    assert not cundall.deciding_condition.holds
    # The Frobenius residual of dT = gamma l dalpha is d(gamma l)/dl = gamma (up to sign).
    assert sp.simplify(cundall.deciding_condition.residual**2 - GAMMA**2) == 0
    assert "fails" in cundall.reason

    weakly = classify(law_definition("weakly_hypoelastic"))
    assert weakly.deciding_condition.name.startswith("Eq. (17)")
    assert not weakly.deciding_condition.holds
    assert weakly.checks[0].holds  # total form exists: the rate form is integrable

    for name in ("mcnamara", "turco"):
        result = classify(law_definition(name))
        assert result.deciding_condition.name.startswith("Eq. (17)")
        assert result.deciding_condition.holds
        assert "holds" in result.reason


@pytest.mark.parametrize(
    ("name", "independent"), [("mcnamara", True), ("weakly_hypoelastic", True), ("turco", False)]
)
def test_eq_25_normal_force_independent_of_alpha(name, independent):
    """Seed Eq. (25): N depends on l only for the rotational laws, not for Turco's."""
    assert derive_law(law_definition(name)).normal_independent_of_alpha.holds is independent


def test_kinematic_integrability_fails_eq_8():
    """Seed Eq. (7)-(8): du_t = l dalpha is not exact (dA/dalpha = 0 != dB/dl = 1)."""
    check = kinematic_integrability()
    assert not check.holds
    assert sp.simplify(check.residual) != 0
    assert sp.simplify(check.residual**2 - 1) == 0
    assert "fails" in str(check)


def test_is_identically_zero_both_ways():
    assert is_identically_zero(sp.sin(ALPHA) ** 2 + sp.cos(ALPHA) ** 2 - 1)[0]
    assert not is_identically_zero(GAMMA * (ALPHA - ALPHA0))[0]
    # Non-smooth: Max(d, 0) - d vanishes only for d >= 0, so not identically.
    assert not is_identically_zero(sp.Max(1 - L, 0) - (1 - L))[0]
    assert is_identically_zero(sp.Max(1 - L, 0) - (1 - L + sp.Abs(1 - L)) / 2)[0]


# --- made-up laws: the classification is computed, not declared -----------------------


def test_non_integrable_rate_law_is_strongly_hypoelastic():
    definition = _test_law(
        "test_rate_l_squared", normal_force=DELTA, tangential_rate=(sp.Integer(0), GAMMA * L**2)
    )
    result = classify(definition)
    assert result.kind == STRONGLY_HYPOELASTIC
    assert result.energy is None
    # D_alpha(0) - D_l(gamma l^2) = -2 gamma l
    assert sp.simplify(result.deciding_condition.residual + 2 * GAMMA * L) == 0


def test_total_forms_without_potential_are_weakly_hypoelastic():
    definition = _test_law(
        "test_coupled_normal",
        normal_force=DELTA + GAMMA * (ALPHA - ALPHA0),
        tangential_force=sp.Integer(0),
    )
    result = classify(definition)
    assert result.kind == WEAKLY_HYPOELASTIC
    assert result.energy is None
    assert not result.deciding_condition.holds


def test_wrong_declared_energy_is_rejected():
    wrong = dataclasses.replace(
        MCNAMARA,
        name="test_mcnamara_wrong_energy",
        energy=DELTA**2 / 2 + GAMMA * (ALPHA - ALPHA0) ** 2,
    )
    with pytest.raises(ValueError, match="declared energy does not generate"):
        classify(wrong)


def test_energy_declared_on_a_law_without_potential_is_rejected():
    declared = _test_law(
        "test_weakly_with_energy",
        normal_force=DELTA,
        tangential_force=GAMMA * (ALPHA - ALPHA0),
        energy=DELTA**2 / 2 + GAMMA * (ALPHA - ALPHA0) ** 2 / 2,
    )
    with pytest.raises(ValueError, match="energy"):
        classify(declared)


def test_law_without_any_tangential_form_is_rejected():
    with pytest.raises(ValueError, match="tangential"):
        _test_law("test_incomplete", normal_force=DELTA)


@pytest.mark.parametrize("base", [MCNAMARA, TURCO, no_tension(MCNAMARA)], ids=lambda d: d.name)
def test_potential_is_integrated_when_none_is_declared(base):
    """Eq. (17) holds, no energy declared: the classification integrates one,
    and it matches the seed's Eq. (19)/(29) up to a constant."""
    definition = dataclasses.replace(base, name=f"test_{base.name}_no_energy", energy=None)
    result = classify(definition)
    assert result.kind == HYPERELASTIC
    assert result.energy is not None
    difference = result.energy - base.energy_total
    # Same gradient as the declared energy: the difference is constant.
    for symbol in (L, ALPHA):
        assert is_identically_zero(sp.diff(difference, symbol))[0]


@pytest.mark.parametrize(
    ("rate", "kind"),
    [
        # Seed Eq. (15): dT = gamma (1 - N) dalpha, Cundall--Strack with K_T(N, T).
        ((sp.Integer(0), GAMMA * (1 - N)), STRONGLY_HYPOELASTIC),
        # Seed Eq. (21): d(l T) = gamma dalpha, i.e. dT = (gamma dalpha - T dl) / l.
        ((-T / L, GAMMA / L), HYPERELASTIC),
    ],
    ids=["eq_15", "eq_21"],
)
def test_rate_laws_with_force_dependent_coefficients(rate, kind):
    """The Frobenius condition uses total derivatives along the rate system
    (D_l = d/dl + A_j d/dy_j, D_alpha = d/dalpha + B_j d/dy_j): with
    coefficients depending on (N, T) the force terms decide the class."""
    definition = _test_law(
        f"test_rate_{kind.replace(' ', '_')}", normal_force=DELTA, tangential_rate=rate
    )
    result = classify(definition)
    assert result.kind == kind
    assert result.checks[0].holds is (kind != STRONGLY_HYPOELASTIC)


def test_rate_form_eq_22_is_hyperelastic_only_on_one_leaf():
    """Seed Eq. (22), dT = gamma (l dalpha - (alpha - alpha0) dl) / l^2, integrates to
    T = gamma (alpha - alpha0) / l + C for any initial state: then d(l T)/dl = C,
    so Eq. (17) holds only on the leaf C = 0 (T = 0 at alpha = alpha0).  A rate law
    is classified for every initial state, hence weakly hypoelastic -- unlike
    Eq. (21), d(l T) = gamma dalpha, whose every leaf is hyperelastic (above), and
    unlike the total form Eq. (18), which fixes C = 0."""
    definition = _test_law(
        "test_mcnamara_rate_form_eq_22",
        normal_force=DELTA,
        tangential_rate=(GAMMA * (ALPHA0 - ALPHA) / L**2, GAMMA / L),
    )
    result = classify(definition)
    assert result.checks[0].holds  # integrable: a total form exists on each leaf
    assert result.kind == WEAKLY_HYPOELASTIC
    # The Eq. (17) residual vanishes exactly on the leaf T = gamma (alpha - alpha0) / l.
    residual = result.deciding_condition.residual
    assert sp.simplify(residual.subs(T, GAMMA * (ALPHA - ALPHA0) / L)) == 0
    assert sp.simplify(residual) != 0


# --- numeric checks of what the symbolic layer produced -------------------------------


@pytest.mark.parametrize("name", HYPERELASTIC_LAWS)
@settings(max_examples=30, deadline=None)
@given(state=diamond_states())
def test_energy_generates_the_forces(name, state):
    """Seed Eq. (16): dW = -N dl + l T dalpha, so dW/dl = -N and dW/dalpha = l T.

    Checked on the compiled energy and on the expression ``classify`` returns.
    """
    assume(abs(state.overlap(name)) > KINK_MARGIN)
    law = make_law(name, gamma=state.gamma, alpha0=state.alpha0)
    compiled = compile_law(law.definition)
    symbolic_energy = sp.lambdify(
        (L, ALPHA, GAMMA, ALPHA0), classify(law.definition).energy, "numpy"
    )
    l, a, h = state.length, state.alpha, FD_STEP

    for energy in (
        lambda ll, aa: compiled.energy(law, ll, aa),
        lambda ll, aa: symbolic_energy(ll, aa, state.gamma, state.alpha0),
    ):
        dw_dl = (energy(l + h, a) - energy(l - h, a)) / (2 * h)
        dw_da = (energy(l, a + h) - energy(l, a - h)) / (2 * h)
        normal = compiled.normal_force(law, l, a)
        moment = l * compiled.tangential_force(law, l, a)
        assert abs(dw_dl + normal) <= FD_TOL * (1 + abs(normal))
        assert abs(dw_da - moment) <= FD_TOL * (1 + abs(moment))


@pytest.mark.parametrize("name", TOTAL_FORM_LAWS)
@settings(max_examples=30, deadline=None)
@given(state=diamond_states())
def test_rate_matrix_is_the_derivative_of_the_total_forms(name, state):
    """C = d(N, T)/d(l, alpha) for laws with a total form (seed Eq. 21-22 vs 18)."""
    assume(abs(state.overlap(name)) > KINK_MARGIN)
    law = make_law(name, gamma=state.gamma, alpha0=state.alpha0)
    compiled = compile_law(law.definition)
    l, a, h = state.length, state.alpha, FD_STEP

    def forces(ll, aa):
        return np.array(
            [compiled.normal_force(law, ll, aa), compiled.tangential_force(law, ll, aa)]
        )

    finite_difference = np.column_stack(
        [
            (forces(l + h, a) - forces(l - h, a)) / (2 * h),
            (forces(l, a + h) - forces(l, a - h)) / (2 * h),
        ]
    )
    normal, tangential = forces(l, a)
    rate = compiled.rate_matrix(law, l, a, normal, tangential)
    np.testing.assert_allclose(
        rate, finite_difference, rtol=0, atol=FD_TOL * (1 + np.abs(rate).max())
    )
