"""Turco's law on the reduced diamond at gamma = 2, alpha0 = pi/4, F2* = 0, in closed form.

The energy written here, from seed Eq. (28)-(29): e = delta^2/2 + gamma sin^2(alpha - alpha0)/2
per contact, delta = cos(alpha - alpha0) - l, and W = 2 e(l(u), alpha(u)) for the reduced
diamond in the seed's units (the factor that gives K = 2I at rest for gamma = 1, checked
in :func:`energy`).  Used by tests/test_bifurcations.py and tests/test_golden.py.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

D1, D2, GAMMA = sp.symbols("d1 d2 gamma")
ALPHA0 = sp.pi / 4


@functools.cache
def energy() -> sp.Expr:
    """W(D1, D2) at gamma = 2 (the factor 2 checked: K = 2I at rest for gamma = 1)."""
    length = sp.sqrt((sp.cos(ALPHA0) - D1) ** 2 + (sp.sin(ALPHA0) - D2) ** 2)
    alpha = sp.atan2(sp.sin(ALPHA0) - D2, sp.cos(ALPHA0) - D1)
    delta = sp.cos(alpha - ALPHA0) - length
    w = 2 * (delta**2 / 2 + GAMMA * sp.sin(alpha - ALPHA0) ** 2 / 2)
    at_rest = sp.hessian(w, (D1, D2)).subs({D1: 0, D2: 0, GAMMA: 1})
    assert sp.simplify(at_rest - 2 * sp.eye(2)) == sp.zeros(2, 2)
    return w.subs(GAMMA, 2)


def bifurcation_point() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(u, F, K) at alpha = 3 pi/8, l = sin(pi/8): F = (2 sqrt 2, 0), K = diag(8 + 4 sqrt 2, 0)."""
    w = energy()
    point = {D1: sp.cos(ALPHA0) - sp.sin(sp.pi / 8) * sp.cos(3 * sp.pi / 8),
             D2: sp.sin(ALPHA0) - sp.sin(sp.pi / 8) * sp.sin(3 * sp.pi / 8)}
    forces = [sp.diff(w, d) for d in (D1, D2)]
    u = np.array([float(point[D1]), float(point[D2])])
    F = np.array([float(sp.N(f.subs(point), 30)) for f in forces])
    K = np.array([[float(sp.N(sp.diff(f, d).subs(point), 30)) for d in (D1, D2)] for f in forces])
    return u, F, K


def equilibrium(d1: float, guess: float) -> tuple[np.ndarray, np.ndarray]:
    """(u, F) with F2 = 0 at D1* = ``d1``: Newton on dW/dD2 from D2* = ``guess`` (30 digits)."""
    w = energy()
    f2 = sp.diff(w, D2).subs(D1, sp.Float(d1, 30))
    d2 = sp.nsolve(f2, D2, guess, prec=30)
    state = {D1: sp.Float(d1, 30), D2: d2}
    F = np.array([float(sp.N(sp.diff(w, d).subs(state), 30)) for d in (D1, D2)])
    return np.array([d1, float(d2)]), F
