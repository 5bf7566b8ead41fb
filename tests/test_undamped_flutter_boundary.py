"""Undamped flutter boundaries of Ziegler's chains: a coalescence of two pairs s = +-i omega.

Without damping the flutter load of the n-bar follower chain is where two
eigenvalues mu = omega^2 of M^-1 K(P) (straight state) coalesce.  The matrices
are written here from the mechanics (docs/boundaries.md, "Ziegler's chains"), not
taken from ncstab, and checked against the evaluators first.
"""

from __future__ import annotations

import numpy as np
import pytest

import ncstab
from ncstab.paths.api import case_batch, resolve_model
from ncstab.systems.bars import ziegler


def chain_matrices(n: int, P: float, m1: float, m2: float, b1: float = 0.0, b2: float = 0.0):
    """K, M, C of the n-bar follower chain at phi = 0 (l = 1, unit springs).

    K = K_s - P D: K_s the springs' (base k phi1, joints k (phi_{i+1} - phi_i)),
    D = dQ/dphi of Q_i = -sin(phi_n - phi_i) (i < n), Q_n = 0: D_ii = 1, D_in = -1
    for i < n.  M_ij = sum_{k >= max(i, j)} m_k (m1 at the inner joints, m2 at the
    tip).  C: b1 at the base, b2 at every joint between two bars.
    """
    springs = np.diag(np.r_[2.0 * np.ones(n - 1), 1.0]) - np.eye(n, k=1) - np.eye(n, k=-1)
    D = np.zeros((n, n))
    D[np.arange(n - 1), np.arange(n - 1)] = 1.0
    D[: n - 1, n - 1] -= 1.0
    tail = np.array([(n - 1 - k) * m1 + m2 for k in range(n)])
    M = tail[np.maximum.outer(np.arange(n), np.arange(n))]
    dashpots = np.r_[b1, np.full(n - 1, b2)]
    C = np.diag(dashpots + np.r_[dashpots[1:], 0.0]) - np.diag(dashpots[1:], 1) - np.diag(dashpots[1:], -1)
    return springs - P * D, M, C


@pytest.mark.parametrize("n", [2, 3, 5])
def test_documented_chain_matrices_are_the_evaluators(n):
    # The documented K, M (phi = 0) and C of the chain are ncstab's to rounding (1e-13).
    model = resolve_model(ziegler("follower", n), None)
    values = {"m1": np.array([1.7]), "m2": np.array([0.6]), "b1": np.array([0.3]), "b2": np.array([0.05])}
    batch = case_batch(model.laws[0], model, values, 1)
    out = batch.evaluate(np.zeros((1, n)), np.zeros((1, batch.n_internal)), None, load=np.array([1.3]))
    K, M, C = chain_matrices(n, 1.3, 1.7, 0.6, 0.3, 0.05)
    np.testing.assert_allclose(out.stiffness[0], K, atol=1e-13)
    np.testing.assert_allclose(out.mass[0], M, atol=1e-13)
    np.testing.assert_allclose(out.damping[0], C, atol=1e-13)


def coalescence_load(n: int, m1: float, m2: float, high: float = 30.0) -> float:
    """The least P where M^-1 K(P) has complex eigenvalues, by bisection (to 1e-15 relative)."""
    def complex_pair(P):
        K, M, _ = chain_matrices(n, P, m1, m2)
        mu = np.linalg.eigvals(np.linalg.solve(M, K))
        return bool(np.any(np.abs(mu.imag) > 1e-9 * np.abs(mu).max()))

    grid = np.linspace(0.0, high, 601)
    first = next(i for i, P in enumerate(grid) if complex_pair(P))
    low, high = grid[first - 1], grid[first]
    while high - low > 1e-15 * high:
        middle = 0.5 * (low + high)
        low, high = (low, middle) if complex_pair(middle) else (middle, high)
    return 0.5 * (low + high)


def trace(n: int, parameter: str, start: float, stop: float, fixed: dict):
    curve = ncstab.boundary(ziegler("follower", n), None, [{"drive": {"P": 8.0}}], {**fixed, parameter: start},
                            event="flutter_onset", parameter=parameter, start=start, stop=stop)
    count = int(curve.n_points.values.ravel()[0])
    assert str(curve.status.values.ravel()[0]) == "finished", curve.message.values.ravel()[0]
    take = lambda name: curve[name].values.reshape(-1, curve[name].shape[-1])[0, :count]  # noqa: E731
    return take(f"boundary_{parameter}"), take("boundary_load"), take("boundary_frequency"), count


def check_double_eigenvalue(n, p, P, omega, parameter, fixed):
    # numpy's eigenvalues of M^-1 K at the stored point: a double eigenvalue splits by
    # sqrt(rounding) ~ 1e-8 relative, and the Newton tolerance 1e-11 on (P, omega)
    # splits it by sqrt(1e-11) ~ 3e-6: two coincide to 1e-5 relative, at omega^2.
    for x, load, w in zip(p, P, omega):
        values = {**fixed, parameter: x}
        K, M, _ = chain_matrices(n, load, values["m1"], values["m2"])
        mu = np.linalg.eigvals(np.linalg.solve(M, K))
        gap = np.abs(mu[:, None] - mu[None, :]) + np.diag(np.full(n, np.inf))
        i, j = np.unravel_index(np.argmin(gap), gap.shape)
        assert gap[i, j] <= 1e-5 * abs(mu[i])
        assert abs(0.5 * (mu[i] + mu[j]).real - w**2) <= 1e-5 * w**2


@pytest.mark.parametrize("parameter, start, stop, fixed", [
    ("m1", 0.5, 4.0, {"m2": 1.0}),
    ("m2", 0.5, 3.0, {"m1": 2.0}),
])
def test_two_bar_undamped_flutter_boundary_matches_its_closed_form(parameter, start, stop, fixed):
    # det(K - mu M) = m1 m2 mu^2 + ((2P - 5) m2 - m1) mu + 1; its discriminant vanishes
    # at P = (5 + r - 2 sqrt r)/2, r = m1/m2, with the double root mu = 1/sqrt(m1 m2).
    # The curve's points are Newton solutions to 1e-11: 1e-9 relative.
    p, P, omega, count = trace(2, parameter, start, stop, fixed)
    assert count >= 20 and p[0] == start and p[-1] == pytest.approx(stop, abs=1e-12)
    m1 = p if parameter == "m1" else fixed["m1"]
    m2 = p if parameter == "m2" else fixed["m2"]
    r = m1 / m2
    np.testing.assert_allclose(P, (5 + r - 2 * np.sqrt(r)) / 2, rtol=1e-9)
    np.testing.assert_allclose(omega, (m1 * m2) ** -0.25, rtol=1e-9)
    check_double_eigenvalue(2, p, P, omega, parameter, fixed)


@pytest.mark.parametrize("parameter, start, stop, fixed", [
    ("m1", 0.5, 4.0, {"m2": 1.0}),
    ("m2", 0.5, 3.0, {"m1": 2.0}),
])
def test_three_bar_undamped_flutter_boundary_is_the_coalescence(parameter, start, stop, fixed):
    # Each point against the least P where M^-1 K(P) has a complex pair (bisection to
    # 1e-15 on numpy's eigenvalues, independent of the curve): 1e-9 relative.
    p, P, omega, count = trace(3, parameter, start, stop, fixed)
    assert count >= 20 and p[-1] == pytest.approx(stop, abs=1e-12)
    for x, load in zip(p[:: max(1, count // 8)], P[:: max(1, count // 8)]):
        values = {**fixed, parameter: x}
        assert load == pytest.approx(coalescence_load(3, values["m1"], values["m2"]), rel=1e-9)
    check_double_eigenvalue(3, p, P, omega, parameter, fixed)
    if parameter == "m1":
        assert omega[0] == pytest.approx(0.75089, abs=1e-5)
