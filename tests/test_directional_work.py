"""Directional second-order work and the unstable cone (issue 6, operator level)."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from ncstab.operators import hill_eigenvalue
from ncstab.operators.directional_work import (
    directional_second_order_work,
    second_order_work_form,
    unstable_cone,
)

# Entries of K in [-5, 5]: d2W values are O(10); the closed forms are exact up to
# a few roundings, so 1e-12 absolute is the tolerance with margin.
TOL = 1e-12
matrices = arrays(np.float64, (2, 2), elements=st.floats(-5, 5, allow_nan=False, allow_subnormal=False))


@settings(max_examples=300, deadline=None)
@given(matrices)
def test_form_reproduces_the_quadratic_form(stiffness):
    theta = np.linspace(0, 2 * np.pi, 37)
    direct = np.einsum("ti,ij,tj->t", np.stack([np.cos(theta), np.sin(theta)], -1), stiffness,
                       np.stack([np.cos(theta), np.sin(theta)], -1))
    np.testing.assert_allclose(directional_second_order_work(stiffness, theta), direct, rtol=0, atol=TOL)


@settings(max_examples=300, deadline=None)
@given(matrices)
def test_minimum_over_directions_is_the_hill_eigenvalue(stiffness):
    """min_theta d2W = smallest eigenvalue of K_sym, including non-symmetric K."""
    mean, radius, phi = second_order_work_form(stiffness)
    assert mean - radius == pytest.approx(hill_eigenvalue(stiffness), abs=TOL)
    # attained at theta = phi + pi/2 (exactly), and no sampled direction is lower
    at_minimum = directional_second_order_work(stiffness, np.array([phi + np.pi / 2]))[0]
    assert at_minimum == pytest.approx(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0], abs=TOL)
    samples = directional_second_order_work(stiffness, np.linspace(0, np.pi, 2001))
    assert samples.min() >= at_minimum - TOL


@settings(max_examples=300, deadline=None)
@given(matrices)
def test_cone_bounds_are_exact_roots_and_width_matches_sampling(stiffness):
    width, lower, upper = unstable_cone(stiffness)
    if np.isfinite(lower):
        roots = directional_second_order_work(stiffness, np.array([lower, upper]))
        np.testing.assert_allclose(roots, 0.0, rtol=0, atol=TOL)
        middle = directional_second_order_work(stiffness, np.array([0.5 * (lower + upper)]))[0]
        assert middle < 0  # the cone is where d2W < 0
        assert width == pytest.approx(2 * (upper - lower), abs=TOL)
    # Width against dense sampling of the circle (resolution 2 pi / 20000 per edge, 4 edges).
    theta = np.linspace(0, 2 * np.pi, 20000, endpoint=False)
    sampled = (directional_second_order_work(stiffness, theta) < 0).mean() * 2 * np.pi
    assert width == pytest.approx(sampled, abs=4 * 2 * np.pi / 20000 + 1e-12)


def test_a_denormal_skew_part_makes_no_cone_and_no_overflow_warning():
    """Found by hypothesis on a fresh database: K = 2 I with K01 = 2.2e-308 (the
    smallest normal double) gave -mean / radius an overflow warning."""
    stiffness = np.array([[2.0, 2.2250738585072014e-308], [0.0, 2.0]])
    width, lower, upper = unstable_cone(stiffness)  # (warnings are errors in the suite)
    assert width == 0.0 and np.isnan(lower) and np.isnan(upper)
    assert unstable_cone(-stiffness)[0] == pytest.approx(2 * np.pi)


def test_cone_limits_and_batch_shapes():
    stable = np.eye(2)
    unstable = -np.eye(2)
    assert unstable_cone(stable)[0] == 0.0
    assert unstable_cone(unstable)[0] == pytest.approx(2 * np.pi)
    assert np.isnan(unstable_cone(stable)[1]) and np.isnan(unstable_cone(unstable)[1])
    # A pure skew operator does no second-order work in any direction: no cone.
    assert unstable_cone(np.array([[0.0, 1.0], [-1.0, 0.0]]))[0] == 0.0

    rng = np.random.default_rng(3)
    batch = rng.normal(size=(7, 5, 2, 2))
    theta = np.linspace(0, np.pi, 9)
    maps = directional_second_order_work(batch, theta)
    assert maps.shape == (7, 5, 9)
    width, lower, upper = unstable_cone(batch)
    assert width.shape == lower.shape == upper.shape == (7, 5)
    for index in np.ndindex(7, 5):
        np.testing.assert_allclose(maps[index], directional_second_order_work(batch[index], theta), atol=0)
        np.testing.assert_allclose(width[index], unstable_cone(batch[index])[0], atol=0)
    with pytest.raises(ValueError, match="2x2"):
        unstable_cone(np.eye(3))


def test_path_dataset_directional_map_and_cone():
    """to_dataset(directions=M): d2W_dir is e.K e with the stored K, the cone is
    empty exactly while hill > 0, and its bounds are roots along the path."""
    from ncstab.paths import SystemSpec, follow

    path = follow(
        SystemSpec(secondary_contacts="ignore"),
        ["weakly_hypoelastic"],
        [{"hold": {"F1": 0.0}, "drive": {"F2": 0.75}}, {"hold": {"F2": "current"}, "drive": {"D1": 0.6}}],
        {"gamma": 0.5},
    )
    ds = path.to_dataset(directions=36).isel(law=0)
    n = int(ds.n_steps)
    K = ds.K.values[:n]
    theta = ds.theta.values
    e = np.stack([np.cos(theta), np.sin(theta)], -1)
    expected = np.einsum("ti,sij,tj->st", e, K, e)
    np.testing.assert_allclose(ds.d2W_dir.values[:n], expected, rtol=0, atol=TOL)
    hill = ds.hill.values[:n]
    width = ds.cone_width.values[:n]
    assert np.all(width[hill > 1e-12] == 0) and np.all(width[hill < -1e-12] > 0)
    assert (hill < 0).any()  # this path loses Hill's condition (s ~ 2.32)
    has_cone = np.isfinite(ds.cone_lower.values[:n])
    for bound in ("cone_lower", "cone_upper"):
        b = ds[bound].values[:n][has_cone]
        roots = np.einsum("si,sij,sj->s", np.stack([np.cos(b), np.sin(b)], -1), K[has_cone],
                          np.stack([np.cos(b), np.sin(b)], -1))
        np.testing.assert_allclose(roots, 0.0, rtol=0, atol=TOL)
    assert ds.d2W_dir.attrs["units"] == "1" and ds.theta.attrs["units"] == "rad"


def test_a_path_padding_state_has_no_cone():
    """Past a case's last state K is NaN: the cone is unknown (NaN), not empty (0)."""
    width, lower, upper = unstable_cone(np.full((3, 2, 2), np.nan))
    assert np.isnan(width).all() and np.isnan(lower).all() and np.isnan(upper).all()
