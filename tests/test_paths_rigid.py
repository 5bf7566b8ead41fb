"""Pure-shear limit (rigid normal contacts): seed Eq. (60)-(68), Figs. 14-15.

Forces are in units of 2R k_t (Eq. 62).  The first branch has closed forms
(Eq. 62 for the rotational-spring laws, Eq. 65 for Turco's translational
springs); the second contact blocks the chain at alpha_max (Eq. 66-68).
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from ncstab.laws import law_definition
from ncstab.paths import PathOptions, SystemSpec, follow
from ncstab.symbolic.rigid import rigid_limit

ALPHA0 = math.pi / 4
# The constrained path is integrated and projected at rtol 1e-10 / Newton 1e-12;
# closed forms are compared to 1e-10 (a few hundred steps of error-controlled
# integration of O(1) quantities).
PATH_TOL = 1e-10
# Event location brackets the arclength to options.event_tol = 1e-10; alpha and
# Delta_1 move at most O(1) per unit arclength, so 1e-9 is a safe margin.
EVENT_TOL = 1e-9


def _pure_shear(laws, target=1.0, alpha0=ALPHA0, secondary="activate", **options):
    return follow(
        SystemSpec(normal="rigid", secondary_contacts=secondary),
        laws,
        [{"hold": {"F2": 0.0}, "drive": {"F1": target}}],
        {"alpha0": alpha0},
        PathOptions(**options) if options else None,
    )


def _case(path, law):
    result, k = path.case(law)
    n = result.n_steps[k]
    return {key: value[k, :n] for key, value in result.steps.items()}, result, k


def test_rigid_limit_is_derived_from_the_laws():
    """Eq. (60), (63): lbar = 1 (rotational laws), cos(alpha - alpha0) (Turco)."""
    import sympy as sp

    from ncstab.laws import ALPHA
    from ncstab.laws import ALPHA0 as A0

    assert rigid_limit(law_definition("mcnamara")).length == 1
    assert sp.simplify(rigid_limit(law_definition("turco")).length - sp.cos(ALPHA - A0)) == 0
    assert sp.simplify(rigid_limit(law_definition("mcnamara")).tangential - (ALPHA - A0)) == 0
    assert rigid_limit(law_definition("cundall_strack")).tangential_rate == 1
    with pytest.raises(ValueError, match="no_tension"):
        rigid_limit(law_definition("mcnamara+no_tension"))


@pytest.mark.parametrize("law", ["mcnamara", "cundall_strack", "weakly_hypoelastic"])
def test_rotational_laws_follow_eq62_then_block_at_pi_over_3(law):
    path = _pure_shear([law])
    steps, result, k = _case(path, law)
    assert result.status[k] == "finished"
    alpha, f1, d1 = steps["alpha"], steps["F"][:, 0], steps["u"][:, 0]
    np.testing.assert_allclose(steps["F"][:, 1], 0.0, atol=PATH_TOL)  # F2 held at 0
    np.testing.assert_allclose(steps["l"], 1.0, atol=1e-14)  # rigid normal: l = 2R exactly
    free = alpha < math.pi / 3 - 1e-9
    # Eq. (62) with F2hat = 0: F1hat = 2 (alpha - alpha0) / sin(alpha); Eq. (61): D1 = cos a0 - cos a.
    np.testing.assert_allclose(f1[free], 2 * (alpha[free] - ALPHA0) / np.sin(alpha[free]), atol=PATH_TOL)
    np.testing.assert_allclose(d1, np.cos(ALPHA0) - np.cos(alpha), atol=PATH_TOL)
    # Blocking: the second contact (top-bottom) at alpha_max = pi/3, Eq. (66).
    event = result.events["secondary_contact"]
    assert event["found"][k]
    assert event["alpha"][k] == pytest.approx(math.pi / 3, abs=EVENT_TOL)
    assert event["u"][k, 0] == pytest.approx(math.cos(ALPHA0) - 0.5, abs=EVENT_TOL)  # Eq. (67)
    assert event["u"][k, 0] == pytest.approx((math.sqrt(2) - 1) / 2, abs=EVENT_TOL)
    assert event["F"][k, 0] == pytest.approx(2 * (math.pi / 3 - ALPHA0) / math.sin(math.pi / 3), abs=EVENT_TOL)
    # Second branch: vertical, alpha = alpha_max while F1 keeps increasing to its target.
    blocked = f1 > event["F"][k, 0] + 1e-9
    assert blocked.sum() >= 2
    np.testing.assert_allclose(alpha[blocked], math.pi / 3, atol=EVENT_TOL)
    np.testing.assert_allclose(d1[blocked], math.cos(ALPHA0) - 0.5, atol=EVENT_TOL)
    assert np.all(np.diff(f1[blocked]) > 0)
    assert f1[-1] == pytest.approx(1.0, abs=1e-10)
    assert d1.max() <= math.cos(ALPHA0) - 0.5 + EVENT_TOL  # displacement-limited (blocking)


def test_turco_follows_eq65_and_blocks_where_cos_a_cos_a_minus_a0_is_half():
    path = _pure_shear(["turco"])
    steps, result, k = _case(path, "turco")
    assert result.status[k] == "finished"
    alpha_max = brentq(lambda a: math.cos(a) * math.cos(a - ALPHA0) - 0.5, ALPHA0, math.pi / 2, xtol=1e-15)
    alpha, f1, d1 = steps["alpha"], steps["F"][:, 0], steps["u"][:, 0]
    free = alpha < alpha_max - 1e-9
    # Eq. (65) with F2hat = 0 and Eq. (64): D1 = cos a0 - cos a cos(a - a0); Eq. (63): l = cos(a - a0).
    expected = np.sin(2 * alpha[free] - 2 * ALPHA0) / np.sin(2 * alpha[free] - ALPHA0)
    np.testing.assert_allclose(f1[free], expected, atol=PATH_TOL)
    np.testing.assert_allclose(steps["l"], np.cos(alpha - ALPHA0), atol=1e-13)
    np.testing.assert_allclose(d1, np.cos(ALPHA0) - np.cos(alpha) * np.cos(alpha - ALPHA0), atol=PATH_TOL)
    event = result.events["secondary_contact"]
    assert event["alpha"][k] == pytest.approx(alpha_max, abs=EVENT_TOL)
    # Eq. (68): the same displacement limit as the rotational model.
    assert event["u"][k, 0] == pytest.approx(math.cos(ALPHA0) - 0.5, abs=EVENT_TOL)
    assert alpha.max() == pytest.approx(alpha_max, abs=EVENT_TOL)


def test_blocking_is_a_loss_of_controllability_under_displacement_control():
    """Driving Delta_1 past Delta_1max is impossible: with the chain blocked the
    control determinant vanishes; with 'stop' the case stops at the contact."""
    path = follow(
        SystemSpec(normal="rigid", secondary_contacts="stop"),
        ["mcnamara"],
        [{"hold": {"F2": 0.0}, "drive": {"D1": 0.3}}],
        {"alpha0": ALPHA0},
    )
    steps, result, k = _case(path, "mcnamara")
    assert result.status[k] == "stopped:secondary_contact"
    assert steps["u"][-1, 0] == pytest.approx(math.cos(ALPHA0) - 0.5, abs=EVENT_TOL)


def test_rigid_mode_rejects_gamma_and_kappa():
    with pytest.raises(ValueError, match="gamma"):
        follow(SystemSpec(normal="rigid"), ["mcnamara"], [{"hold": {"F2": 0.0}, "drive": {"F1": 0.1}}],
               {"gamma": 0.5})


def test_rigid_dataset_is_labelled_in_units_of_2r_kt():
    ds = _pure_shear(["mcnamara", "turco"], target=0.8).to_dataset()
    assert ds.attrs["force_unit"] == "2R k_t"
    assert "2R k_t" in ds["F"].attrs["description"]
    # K is undefined on the constraint: NaN, never a silent number.
    n = int(ds["n_steps"].isel(law=0))
    assert np.all(np.isnan(ds["det_K"].isel(law=0).values[:n]))


@pytest.mark.parametrize("secondary", ["activate", "stop"])
def test_the_pure_shear_limit_follows_the_closed_forms_at_either_alpha0_blocked_or_stopped(secondary):
    """The closed forms above, for a rotational, a rate and a translational law in one
    batch at two alpha0 (pi/4 and pi/5), the second contact blocking the chain
    (activate) or stopping the case (stop): the first branch Eq. (62) / (65), the
    contact at alpha_max with Delta_1 = cos(alpha0) - 1/2 (Eq. 66-68), the end at the
    target F1 = 1 on the blocked branch or at the contact; and the work, recorded as
    1/2 int F1 dDelta_1 (the diamond's work_factor, per contact, seed Eq. 5), in closed
    form along the first branch and constant on the blocked one (Delta_1 fixed, F2 = 0):
    (alpha - alpha0)^2 / 2 for the rotational laws (Eq. 61-62: dDelta_1 = sin(alpha)
    dalpha), sin^2(alpha - alpha0) / 2 for Turco's (Eq. 64-65: dDelta_1 = sin(2 alpha
    - alpha0) dalpha).  Tolerances: PATH_TOL on the path, EVENT_TOL at the contact."""
    laws = ["mcnamara", "cundall_strack", "turco"]
    alpha0s = [ALPHA0, math.pi / 5]
    path = follow(
        SystemSpec(normal="rigid", secondary_contacts=secondary), laws,
        [{"hold": {"F2": 0.0}, "drive": {"F1": 1.0}}], {"alpha0": alpha0s},
    )
    for law in laws:
        for alpha0 in alpha0s:
            result, k = path.case(law, alpha0=alpha0)
            n = result.n_steps[k]
            steps = {key: value[k, :n] for key, value in result.steps.items()}
            alpha, f1, d1 = steps["alpha"], steps["F"][:, 0], steps["u"][:, 0]
            if law == "turco":
                alpha_max = brentq(lambda a, a0=alpha0: math.cos(a) * math.cos(a - a0) - 0.5, alpha0, math.pi / 2, xtol=1e-15)
                expected_f1 = np.sin(2 * alpha - 2 * alpha0) / np.sin(2 * alpha - alpha0)
                expected_d1 = np.cos(alpha0) - np.cos(alpha) * np.cos(alpha - alpha0)
                expected_work = np.sin(np.minimum(alpha, alpha_max) - alpha0) ** 2 / 2
            else:
                alpha_max = math.pi / 3
                expected_f1 = 2 * (alpha - alpha0) / np.sin(alpha)
                expected_d1 = np.cos(alpha0) - np.cos(alpha)
                expected_work = (np.minimum(alpha, alpha_max) - alpha0) ** 2 / 2
            free = alpha < alpha_max - 1e-9
            assert free.sum() >= 10, (law, alpha0)
            np.testing.assert_allclose(steps["F"][:, 1], 0.0, atol=PATH_TOL)
            np.testing.assert_allclose(f1[free], expected_f1[free], atol=PATH_TOL, err_msg=law)
            np.testing.assert_allclose(d1, expected_d1, atol=PATH_TOL, err_msg=law)
            np.testing.assert_allclose(steps["work"], expected_work, atol=PATH_TOL, err_msg=law)
            event = result.events["secondary_contact"]
            assert event["found"][k]
            assert event["alpha"][k] == pytest.approx(alpha_max, abs=EVENT_TOL)
            assert event["u"][k, 0] == pytest.approx(math.cos(alpha0) - 0.5, abs=EVENT_TOL)
            assert alpha.max() == pytest.approx(alpha_max, abs=EVENT_TOL)
            if secondary == "activate":
                assert result.status[k] == "finished"
                assert f1[-1] == pytest.approx(1.0, abs=PATH_TOL) and (~free).sum() >= 2
                np.testing.assert_allclose(d1[~free], math.cos(alpha0) - 0.5, atol=EVENT_TOL)
            else:
                assert result.status[k] == "stopped:secondary_contact"
                assert alpha[-1] == pytest.approx(alpha_max, abs=EVENT_TOL)  # the contact state, stored last
                assert d1[-1] == pytest.approx(math.cos(alpha0) - 0.5, abs=EVENT_TOL)
