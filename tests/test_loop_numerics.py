"""The compiled loop's model-free numerics (ncstab.paths.loop_numerics) against scipy's DOP853.

The loop must take scipy's DOP853 steps: the same tableau sums, error norm and
dense output (its starting step: tests/test_initial_step.py).  Each function is
compared with scipy's own code on random data, compiled and as plain Python (the
same text, :mod:`ncstab.plain_python`).  Tolerances: the dense output follows
scipy's Horner form operation for operation (bit for bit); the stage sums skip
the tableau's zero weights and sum in stage order where numpy's ``dot`` may block
its sum, and the error norm takes its norms in another order: a few roundings of
O(1) numbers, so 1e-13 relative (a wrong weight or term is O(1e-3) or more).
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest
from scipy.integrate._ivp import rk

from ncstab.paths import loop_numerics
from ncstab.plain_python import plain_file

TOL = 1e-13
SIZES = (1, 4, 9)


@pytest.fixture(params=["compiled", "plain"])
def numerics(request):
    if request.param == "compiled":
        return loop_numerics
    return plain_file("ncstab.paths.loop_numerics", importlib.util.find_spec("ncstab.paths.loop_numerics").origin)


def _stages(rng: np.random.Generator, m: int) -> np.ndarray:
    return rng.standard_normal((rk.DOP853.n_stages + 4, m))


@pytest.mark.parametrize("m", SIZES)
def test_the_stage_sums_are_the_tableau_rows_times_the_stages(numerics, m):
    rng = np.random.default_rng(m)
    stages = _stages(rng, m)
    out = np.empty(m)
    for s in range(1, rk.DOP853.n_stages):  # each stage's state: A[s] . K (scipy's rk_step)
        numerics.combine(numerics.A[s], numerics.A_TERMS[s], numerics.A_COUNT[s], stages, out, m)
        np.testing.assert_allclose(out, rk.DOP853.A[s, :s] @ stages[:s], rtol=TOL, atol=TOL)
    numerics.combine(numerics.B, numerics.B_TERMS, numerics.B_COUNT, stages, out, m)
    np.testing.assert_allclose(out, rk.DOP853.B @ stages[: rk.DOP853.n_stages], rtol=TOL, atol=TOL)


@pytest.mark.parametrize("m", SIZES)
def test_the_error_norm_is_scipys(numerics, m):
    rng = np.random.default_rng(10 + m)
    stages = _stages(rng, m)
    y0, y1 = rng.standard_normal(m), rng.standard_normal(m)
    rtol, atol, h = 1e-6, 1e-9, 0.03
    scale = atol + np.maximum(np.abs(y0), np.abs(y1)) * rtol
    expected = rk.DOP853._estimate_error_norm(rk.DOP853, stages[: rk.DOP853.n_stages + 1], h, scale)
    work = np.empty((3, m))
    assert numerics.error_norm(y0, y1, h, rtol, atol, stages, work, m) == pytest.approx(expected, rel=TOL)


def test_the_error_norm_is_infinite_where_the_step_is_not_finite(numerics):
    stages = _stages(np.random.default_rng(1), 3)
    y1 = np.array([0.0, np.nan, 1.0])
    assert numerics.error_norm(np.zeros(3), y1, 0.1, 1e-6, 1e-9, stages, np.empty((3, 3)), 3) == np.inf


@pytest.mark.parametrize("m", SIZES)
def test_the_dense_output_is_scipys_bit_for_bit(numerics, m):
    rng = np.random.default_rng(20 + m)
    coefficients = rng.standard_normal((rk.DOP853.D.shape[0] + 3, m))
    y0 = rng.standard_normal(m)
    scipy_output = rk.Dop853DenseOutput(0.0, 0.5, y0, coefficients)
    out = np.empty(m)
    for fraction in (0.0, 0.125, 0.5, 0.9, 1.0):
        numerics.dense_value(y0, coefficients, fraction, out)
        np.testing.assert_array_equal(out, scipy_output(np.float64(0.5 * fraction)))


def test_pieces_signs_and_the_first_column(numerics):
    assert numerics.piece_count(0.01, 0.02, 50) == 1
    assert numerics.piece_count(0.05, 0.02, 50) == 3  # ceil(2.5)
    assert numerics.piece_count(10.0, 0.02, 50) == 50  # at most max_pieces
    assert [numerics.sign(x) for x in (2.0, -0.5, 0.0)] == [1.0, -1.0, 0.0]
    assert np.isnan(numerics.sign(np.nan))
    sigma = np.array([0.3, np.inf, 0.1, 0.2])
    assert numerics.first_column(np.array([0, 3, -1]), sigma) == 3
    assert numerics.first_column(np.array([2, 0]), sigma) == 2
    assert numerics.first_column(np.array([-1, -1]), sigma) == -1


@pytest.mark.parametrize("theta", [0.1, 0.2, 0.4])
def test_the_richardson_arc_of_a_circle_errs_by_theta5_over_7680(numerics, theta):
    # chords of a unit circle's arc of angle theta: 2 sin(theta/2) whole, 4 sin(theta/4) its
    # halves; (4 halves - whole)/3 = theta - theta^5/7680 + O(theta^7) (Taylor series), so
    # the error over theta^5 is 1/7680 to O(theta^2) (at most 1.2 % here)
    arc = numerics.richardson_arc(2 * np.sin(theta / 2), 4 * np.sin(theta / 4))
    assert (theta - arc) / theta**5 == pytest.approx(1 / 7680, rel=0.012)


def test_the_over_step_is_twice_the_distance_to_a_linear_zero(numerics):
    # a branch test falling linearly, size(s) = 1 - 5 s (zero at s = 0.2); a step from s0 to s1
    newton_tol = 1e-12
    margin = loop_numerics.OVER_MARGIN * np.sqrt(newton_tol)

    def over(s0, s1):
        return numerics.next_over_length(1 - 5 * s0, 1 - 5 * s1, s1 - s0, newton_tol)

    assert over(0.1, 0.19) == 0.0  # 0.01 ahead: beyond the margin, none
    near = 0.2 - 0.5 * margin  # half the margin ahead: tried, twice that long
    assert over(0.1, near) == pytest.approx(margin, rel=1e-6)
    assert over(near, 0.1) == 0.0  # rising: none
    # the degenerate step: sqrt(size) falls linearly, size = (1 - 5 s)^2: twice 0.01 ahead
    length = numerics.next_degenerate_length((1 - 5 * 0.1) ** 2, (1 - 5 * 0.19) ** 2, 0.09)
    assert length == pytest.approx(2 * 0.01, rel=1e-12)


def test_the_over_step_interpolant_ends_at_the_predictor(numerics):
    rate, length, arc = np.array([0.6, -0.8]), 0.3, 0.31
    coefficients = np.full((7, 2), np.nan)
    numerics.over_coefficients(length, arc, rate, 2, coefficients)
    y0, out = np.array([1.0, 2.0]), np.empty(2)
    numerics.dense_value(y0, coefficients, 1.0, out)
    np.testing.assert_allclose(out, y0 + length * rate, rtol=1e-15)
    numerics.dense_value(y0, coefficients, 0.5, out)  # sigma(1/2) = L/2 + (arc - L)/4
    np.testing.assert_allclose(out, y0 + (length / 2 + (arc - length) / 4) * rate, rtol=1e-15)
