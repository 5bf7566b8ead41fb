"""Over steps across simple bifurcation points (:mod:`ncstab.paths.over_steps`): the
trigger, the arclength of an over step and its interpolant, checked against exact
properties, on the compiled loop's own functions (``next_over_length``,
``next_degenerate_length``, ``richardson_arc``, ``over_coefficients`` of
:mod:`ncstab.paths.loop_step_limits`, called through small numba functions: the loop
compiles them without Python wrappers).  The paths through such points are tested in
tests/test_bifurcations.py (Turco, gamma = 2, F2* = 0, against its closed form) and
tests/test_paths_engine.py."""

from __future__ import annotations

import numpy as np
import pytest

numba = pytest.importorskip("numba")

from ncstab.paths import loop_numerics
from ncstab.paths.compiled import _POWER
from ncstab.paths.over_steps import OVER_MARGIN

LOOP = loop_numerics  # the compiled loop imports these
_next_over_length = LOOP.next_over_length
_next_degenerate_length = LOOP.next_degenerate_length
_richardson_arc = LOOP.richardson_arc
_over_coefficients = LOOP.over_coefficients
_dense_value = LOOP.dense_value


@numba.njit
def _over_lengths(before, after, reach, newton_tol):
    out = np.empty(before.size)
    for i in range(before.size):
        out[i] = _next_over_length(before[i], after[i], reach[i], newton_tol)
    return out


@numba.njit
def _degenerate_lengths(before, after, reach):
    out = np.empty(before.size)
    for i in range(before.size):
        out[i] = _next_degenerate_length(before[i], after[i], reach[i])
    return out


@numba.njit
def _arc(whole, halves):
    return _richardson_arc(whole, halves)


@numba.njit
def _interpolant_at(y0, rate, length, arc, fraction, power):
    coefficients = np.empty((power, y0.size))
    _over_coefficients(length, arc, rate, y0.size, coefficients)
    out = np.empty(y0.size)
    _dense_value(y0, coefficients, fraction, out)
    return out


def test_the_next_over_step_reaches_as_far_past_the_extrapolated_zero_as_the_path_is_before_it():
    """The branch test falling linearly from b0 to b1 over a step h has its zero at
    d = h b1 / (b0 - b1) ahead; the over step is 2 d, tried only within over_distance
    (1e-4 at newton_tol = 1e-12) and only where the test falls toward zero."""
    assert OVER_MARGIN * np.sqrt(1e-12) == pytest.approx(1e-4, rel=1e-15)
    h = np.array([1e-3, 1e-3, 1e-3, 1e-3, 1e-3, 0.0])
    before = np.array([1.0, 1.0, 0.5, 1.0, np.nan, 1.0])
    after = np.array([0.05, 0.5, 0.6, 0.0, 0.1, 0.5])
    lengths = _over_lengths(before, after, h, 1e-12)
    d = 1e-3 * 0.05 / 0.95  # 5.26e-5 ahead: within 1e-4
    np.testing.assert_allclose(lengths[0], 2 * d, rtol=1e-15)
    # 1e-3 ahead (too far), rising, exactly zero (no extrapolation), unknown, no length
    np.testing.assert_array_equal(lengths[1:], 0.0)


@pytest.mark.parametrize("distance", [3e-6, 2.6e-5, 3.7e-4])
def test_the_degenerate_over_step_reaches_as_far_past_a_quadratic_zero_as_the_path_is_before_it(distance):
    """A branch test of size k d^2 (a degenerate point, d its distance ahead; k = 23 as on
    the unreduced diamond at Turco's point) seen at d + h and d: sqrt of it extrapolates to
    the zero exactly, so the degenerate over step is 2 d (to rounding, 1e-12 relative);
    the linear extrapolation of next_over_length falls short of it (d^2 / (2 d + h))."""
    k, h = 23.0, 2e-3
    before, after = np.array([k * (distance + h) ** 2]), np.array([k * distance**2])
    np.testing.assert_allclose(_degenerate_lengths(before, after, np.array([h])), 2 * distance, rtol=1e-12)
    linear = h * after / (before - after)
    np.testing.assert_allclose(linear, distance**2 / (2 * distance + h), rtol=1e-12)
    assert linear[0] < 0.5 * distance
    # rising, zero, unknown, no length: none
    lengths = _degenerate_lengths(np.array([1.0, 1.0, np.nan, 1.0]), np.array([2.0, 0.0, 0.5, 0.5]),
                                  np.array([h, h, h, 0.0]))
    np.testing.assert_array_equal(lengths, 0.0)


@pytest.mark.parametrize("angle", [1e-2, 5e-2, 1e-1])
def test_the_arclength_of_an_over_step_is_exact_to_fifth_order_on_a_circle(angle):
    """Three points of a circle of radius R at 0, angle/2, angle: the chords of one and two
    pieces extrapolated give R angle - R angle^5 / 7680 + O(angle^7) (the series of
    2 R sin(angle/2) and 4 R sin(angle/4) written out); the points in 5 dimensions
    (u, F, lambda), the circle in a tilted plane."""
    radius = 3.0
    e1 = np.array([1.0, 2.0, 0.0, -1.0, 0.5])
    e1 /= np.linalg.norm(e1)
    e2 = np.array([0.0, 1.0, 1.0, 2.0, 0.0])
    e2 -= (e2 @ e1) * e1
    e2 /= np.linalg.norm(e2)
    start, middle, end = (radius * (np.cos(t) * e1 + np.sin(t) * e2) for t in (0.0, angle / 2, angle))
    whole = np.sqrt(np.sum((end - start) ** 2))
    halves = np.sqrt(np.sum((middle - start) ** 2)) + np.sqrt(np.sum((end - middle) ** 2))
    arc = _arc(whole, halves)
    expected = radius * angle - radius * angle**5 / 7680
    assert abs(arc - expected) <= 1e-3 * radius * angle**5 / 7680 + 1e-15


def test_the_over_interpolant_is_the_predictor_at_sigma_of_f():
    """The dense output of the over step's interpolant at fraction f is y0 + sigma(f) dy/ds with
    sigma(f) = L f + (arc - L) f (1 - f): at f = 1 the predictor's end y0 + L dy/ds, and
    the arclength term arc f to second order (rounding: 1e-15 relative)."""
    rng = np.random.default_rng(1)
    y0, rate = rng.normal(size=(3, 4)), rng.normal(size=(3, 4))
    length = np.array([1e-4, 2e-4, 5e-5])
    arc = length * (1 + np.array([1e-3, -2e-3, 5e-4]))
    power = _POWER  # the rows of DOP853's dense output (scipy's INTERPOLATOR_POWER)
    for f in (0.0, 0.25, 0.5, 0.9, 1.0):
        sigma = length * f + (arc - length) * f * (1 - f)
        for k in range(3):
            value = _interpolant_at(y0[k], rate[k], length[k], arc[k], f, power)
            np.testing.assert_allclose(value, y0[k] + sigma[k] * rate[k], rtol=0, atol=1e-15)
