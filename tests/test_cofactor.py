"""The cofactor vector (adj(M) g', det M) from one QR decomposition (ncstab.paths.cofactor).

Against exact rational arithmetic (sympy's adjugate and determinant of integer
matrices, regular and singular), and its defining property A c = 0 with
A = [M | -g'].  Tolerances: Householder QR is backward stable, so c is exact
to a few units of rounding of |M|^(n-1) |g'| (entries below 10 here, n <= 6);
1e-12 relative to the largest entry is that with room.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from ncstab.paths.cofactor import cofactor_vectors

RELATIVE = 1e-12


def _exact(matrix: np.ndarray, rate: np.ndarray) -> np.ndarray:
    exact = sp.Matrix(matrix.astype(int).tolist())
    return np.array([float(x) for x in exact.adjugate() * sp.Matrix(rate.astype(int).tolist())] + [float(exact.det())])


def _integer_cases(n: int, rank: int, count: int, seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    left = rng.integers(-3, 4, size=(count, n, rank))
    right = rng.integers(-3, 4, size=(count, rank, n))
    return (left @ right).astype(float), rng.integers(-5, 6, size=(count, n)).astype(float)


@pytest.mark.parametrize("n, deficiency", [(n, d) for n in range(1, 7) for d in range(3) if d < n])
def test_the_cofactor_vector_is_the_exact_adjugate_times_the_rate_and_the_determinant(n, deficiency):
    """Integer matrices of rank n, n - 1 and n - 2: against sympy's exact adj(M) g' and
    det M.  Rank n - 1 is a turning point (det M = 0, adj(M) g' not 0); rank n - 2 a
    larger null space, where c vanishes."""
    matrices, rates = _integer_cases(n, n - deficiency, 12, seed=10 * n + deficiency)
    dv, det = cofactor_vectors(matrices, rates)
    computed = np.column_stack([dv, det])
    for case in range(len(rates)):
        expected = _exact(matrices[case], rates[case])
        scale = max(1.0, np.abs(matrices[case]).max()) ** (n - 1) * max(1.0, np.abs(rates[case]).max())
        np.testing.assert_allclose(computed[case], expected, rtol=0, atol=RELATIVE * scale)
        if deficiency == 2:
            assert np.all(expected == 0)


def test_the_cofactor_vector_spans_the_null_space_of_m_minus_g():
    """A c = M adj(M) g' - det(M) g' = 0 for random real matrices (to rounding of |M| |c|)."""
    rng = np.random.default_rng(4)
    for n in (3, 5, 7):
        matrices, rates = rng.normal(size=(50, n, n)), rng.normal(size=(50, n))
        dv, det = cofactor_vectors(matrices, rates)
        residual = np.einsum("bij,bj->bi", matrices, dv) - det[:, None] * rates
        size = np.abs(matrices).max() * np.abs(np.column_stack([dv, det])).max(axis=1)
        assert np.all(np.abs(residual).max(axis=1) <= 1e-13 * size)
        np.testing.assert_allclose(det, np.linalg.det(matrices), rtol=1e-12, atol=1e-12)


def test_a_case_has_the_same_cofactor_vector_alone_and_in_a_batch():
    rng = np.random.default_rng(5)
    matrices, rates = rng.normal(size=(9, 6, 6)), rng.normal(size=(9, 6))
    dv, det = cofactor_vectors(matrices, rates)
    for b in (0, 4, 8):
        alone_dv, alone_det = cofactor_vectors(matrices[b : b + 1], rates[b : b + 1])
        np.testing.assert_array_equal(alone_dv[0], dv[b])
        assert alone_det[0] == det[b]


def test_nan_entries_give_nan_and_an_empty_batch_gives_empty_arrays():
    matrix = np.eye(3)[None].copy()
    matrix[0, 1, 2] = np.nan
    dv, det = cofactor_vectors(matrix, np.ones((1, 3)))
    assert np.isnan(det[0]) and np.isnan(dv).all()
    dv, det = cofactor_vectors(np.zeros((0, 4, 4)), np.zeros((0, 4)))
    assert dv.shape == (0, 4) and det.shape == (0,)


@pytest.mark.parametrize("n", [2, 3, 5, 7])
def test_the_minimum_norm_step_solves_the_constraint_with_the_least_norm(n):
    """x = (dv, dlambda) from the QR decomposition: A x = -r with A = [M | -g'] (to
    rounding of |A| |x|), and x lies in the row space of A (x = A^T w: orthogonal to the
    null vector c, the cofactor vector), which makes it the minimum-norm solution."""
    from ncstab.paths.cofactor import minimum_norm_steps

    rng = np.random.default_rng(6 + n)
    matrices, rates, residuals = rng.normal(size=(40, n, n)), rng.normal(size=(40, n)), rng.normal(size=(40, n))
    dv, dlam, solved = minimum_norm_steps(matrices, rates, residuals)
    assert solved.all()
    x = np.column_stack([dv, dlam])
    a = np.concatenate([matrices, -rates[:, :, None]], axis=-1)
    size = np.abs(a).max(axis=(1, 2)) * np.abs(x).max(axis=1)
    assert np.all(np.abs(np.einsum("bij,bj->bi", a, x) + residuals).max(axis=1) <= 1e-13 * size * n)
    c_dv, c_det = cofactor_vectors(matrices, rates)
    c = np.column_stack([c_dv, c_det])
    cosine = np.abs(np.sum(x * c, axis=1)) / (np.linalg.norm(x, axis=1) * np.linalg.norm(c, axis=1))
    assert cosine.max() < 1e-12


def test_a_rank_deficient_constraint_is_left_to_least_squares():
    """[M | -g'] of rank n - 1 (a row of zeros): not solved, NaN out, for the caller's
    least squares (the loop's ``least_squares_step``, below)."""
    from ncstab.paths.cofactor import minimum_norm_steps

    matrices = np.eye(4)[None].copy()
    matrices[0, 2] = 0.0
    rates = np.array([[1.0, 0.0, 0.0, 0.0]])
    dv, dlam, solved = minimum_norm_steps(matrices, rates, np.ones((1, 4)))
    assert not solved[0] and np.isnan(dv).all() and np.isnan(dlam[0])


def test_the_projection_falls_back_to_least_squares_for_a_rank_deficient_constraint():
    """The general loop's Newton projection, where minimum_norm_step finds no
    correction: 4 dofs, one row of [M | -g'] zero and its residual zero (a consistent
    system of lower rank).  Its least-squares step (``least_squares_step``, called
    through a numba function: the loop compiles it without a Python wrapper) solves it
    to rounding (entries of size ~1: 1e-12)."""
    import numba

    from ncstab.paths.loop_general import least_squares_step

    @numba.njit
    def step_of(matrix, rate, residual):
        out = np.empty(rate.size + 1)
        least_squares_step(matrix, rate, residual, out)
        return out

    rng = np.random.default_rng(8)
    matrix = rng.normal(size=(4, 4))
    matrix[2] = 0.0
    rates = rng.normal(size=4)
    rates[2] = 0.0
    residual = rng.normal(size=4)
    residual[2] = 0.0
    x = step_of(matrix, rates, residual)
    a = np.concatenate([matrix, -rates[:, None]], axis=-1)
    assert np.isfinite(x).all()
    np.testing.assert_allclose(a @ x, -residual, rtol=0, atol=1e-12)
