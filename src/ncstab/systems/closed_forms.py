"""Closed forms of the seed for the diamond chain (Challamel et al. 2022).

Vectorised numpy functions of the branch orientation ``alpha`` (rad): every
argument broadcasts against the others, like a numpy ufunc.  Forces are
dimensionless, in units of ``2R k_n`` (seed Eq. 37), except in the pure-shear
limit (rigid normal, ``k_n -> infinity``) where they are in units of
``2R k_t`` (seed Eq. 62).  Lengths and displacements are in units of ``2R``.

These are the seed's hand-derived results, written once here so that tests
and figures (closed-form overlays) share them:

========================================  =====================================
function                                  seed equations
========================================  =====================================
:func:`mcnamara_load_rotation`            (48), (49), (52), (53)
:func:`mcnamara_branch_length`            (46), first line
:func:`diamond_displacements`             (3), (46) third line
:func:`mcnamara_turning_alpha`            double root of (48)
:func:`turco_load_rotation`               (56), (57), (58)
:func:`turco_branch_length`               (55), first line
:func:`pure_shear_load_rotation`          (62), (65), (66)
:func:`pure_shear_displacement`           (61), (64)
:func:`pure_shear_blocking_alpha`         (66), (67), (68)
:func:`pure_shear_max_displacement`       (67), (68)
========================================  =====================================
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ncstab.systems.pure_shear_forms import (
    PURE_SHEAR_MODELS,
    pure_shear_blocking_alpha,
    pure_shear_displacement,
    pure_shear_load_rotation,
    pure_shear_max_displacement,
)

__all__ = [
    "PURE_SHEAR_MODELS",
    "diamond_displacements",
    "mcnamara_branch_length",
    "mcnamara_load_rotation",
    "mcnamara_turning_alpha",
    "pure_shear_blocking_alpha",
    "pure_shear_displacement",
    "pure_shear_load_rotation",
    "pure_shear_max_displacement",
    "turco_branch_length",
    "turco_load_rotation",
    "ziegler_divergence_load",
    "ziegler_equal_damping_flutter_load",
    "ziegler_flutter_load",
]

def _check_branch(branch: int) -> float:
    if branch not in (-1, 1):
        raise ValueError(f"branch must be -1 or +1, got {branch!r}")
    return float(branch)


def _sqrt_or_nan(delta: np.ndarray) -> np.ndarray:
    """sqrt where delta >= 0, NaN elsewhere (without a RuntimeWarning)."""
    return np.sqrt(np.where(delta >= 0, delta, np.nan))


# --- McNamara et al. (2008): shear rotational springs ---------------------------------------


def mcnamara_load_rotation(
    alpha: ArrayLike, gamma: ArrayLike, alpha0: ArrayLike, F2: ArrayLike = 0.0, branch: int = -1
) -> np.ndarray:
    r"""Load-rotation curve F1*(alpha) of the McNamara chain at constant F2*.

    Seed Eq. (53), the roots of the quadratic Eq. (52):

    .. math::

        F_1^* = \frac{b \pm \sqrt{\delta}}{\sin\alpha\cos\alpha},\quad
        b = \sin\alpha - \tfrac{F_2^*}{2} + F_2^*\cos^2\alpha,\quad
        \delta = b^2 + 2\cos\alpha\sin\alpha\,
        \bigl[-F_2^*\cos\alpha\,(1 - \tfrac{F_2^*}{2}\sin\alpha)
        + 2\gamma(\alpha_0 - \alpha)\bigr].

    For ``F2 = 0`` it reduces to Eq. (48), and ``branch=-1`` to Eq. (49).

    Parameters
    ----------
    alpha : array_like
        Branch orientation (rad), any shape.
    gamma : array_like
        Stiffness ratio k_t/k_n, broadcast against ``alpha``.
    alpha0 : array_like
        Initial orientation (rad), broadcast against ``alpha``.
    F2 : array_like, optional
        Constant lateral force F2* (units of 2R k_n).
    branch : {-1, +1}
        Sign before the square root.  -1 is the branch through the state
        reached from the unloaded configuration (F1* = 0 at alpha = alpha0
        when F2 = 0); +1 is the other branch, which the path joins past the
        maximum of alpha (seed Figs. 3-5).

    Returns
    -------
    ndarray
        F1*, broadcast shape of the inputs; NaN where the discriminant
        ``delta`` is negative (no equilibrium at that alpha).
    """
    branch_sign = _check_branch(branch)
    alpha, gamma, alpha0, F2 = (np.asarray(a, dtype=float) for a in (alpha, gamma, alpha0, F2))
    s, c = np.sin(alpha), np.cos(alpha)
    b = s - F2 / 2 + F2 * c**2
    delta = b**2 + 2 * c * s * (-F2 * c * (1 - F2 / 2 * s) + 2 * gamma * (alpha0 - alpha))
    return (b + branch_sign * _sqrt_or_nan(delta)) / (s * c)


def mcnamara_branch_length(alpha: ArrayLike, F1: ArrayLike, F2: ArrayLike = 0.0) -> np.ndarray:
    r"""Branch length l* of the McNamara chain at equilibrium.

    Seed Eq. (46), first line (from N* = -(l* - 1), Eq. 43-44):
    :math:`l^* = 1 - \tfrac12 (F_1^*\cos\alpha + F_2^*\sin\alpha)`.

    Parameters
    ----------
    alpha : array_like
        Branch orientation (rad).
    F1, F2 : array_like
        Generalized forces F1*, F2* (units of 2R k_n), broadcast against alpha.

    Returns
    -------
    ndarray
        l* = l/(2R), broadcast shape of the inputs.
    """
    alpha, F1, F2 = (np.asarray(a, dtype=float) for a in (alpha, F1, F2))
    return 1 - (F1 * np.cos(alpha) + F2 * np.sin(alpha)) / 2


def diamond_displacements(
    alpha: ArrayLike, l: ArrayLike, alpha0: ArrayLike
) -> tuple[np.ndarray, np.ndarray]:
    r"""Generalized displacements of the diamond from its branch (alpha, l*).

    Seed Eq. (3) in dimensionless form (Eq. 37), the third line of Eq. (46):
    :math:`\Delta_1^* = \cos\alpha_0 - l^*\cos\alpha`,
    :math:`\Delta_2^* = \sin\alpha_0 - l^*\sin\alpha`.

    Parameters
    ----------
    alpha : array_like
        Branch orientation (rad).
    l : array_like
        Branch length l* = l/(2R).
    alpha0 : array_like
        Initial orientation (rad).

    Returns
    -------
    (D1, D2) : tuple of ndarray
        Delta_1*, Delta_2*, broadcast shape of the inputs.
    """
    alpha, l, alpha0 = (np.asarray(a, dtype=float) for a in (alpha, l, alpha0))
    return np.cos(alpha0) - l * np.cos(alpha), np.sin(alpha0) - l * np.sin(alpha)


def _turning_alpha_scalar(gamma: float, alpha0: float) -> float:
    """First root of tan(a) - 4 gamma (a - a0) in (a0, pi/2), or NaN."""
    if not (np.isfinite(gamma) and np.isfinite(alpha0)) or gamma <= 0 or not 0 < alpha0 < np.pi / 2:
        return np.nan

    def g(a: float) -> float:
        return np.tan(a) - 4 * gamma * (a - alpha0)

    # g(alpha0) = tan(alpha0) > 0 and g -> +inf at pi/2; g is convex on
    # (0, pi/2) with its minimum where cos^2(a) = 1/(4 gamma).  A root exists
    # iff that minimum lies beyond alpha0 and is negative; the first root is
    # bracketed by (alpha0, minimum).
    if 4 * gamma <= 1:
        return np.nan
    a_min = float(np.arccos(1 / (2 * np.sqrt(gamma))))
    if a_min <= alpha0 or g(a_min) >= 0:
        return np.nan
    from scipy.optimize import brentq  # imported here: ncstab plot need not pay for scipy.optimize

    return float(brentq(g, alpha0, a_min, xtol=1e-15, rtol=4 * np.finfo(float).eps, maxiter=200))


def mcnamara_turning_alpha(gamma: ArrayLike, alpha0: ArrayLike) -> np.ndarray:
    r"""Maximum of alpha on the McNamara load-rotation branch, F2* = 0.

    The two branches of seed Eq. (48) meet where their discriminant vanishes,
    :math:`\tan\alpha = 4\gamma(\alpha - \alpha_0)`: the path through the
    unloaded state (Eq. 49) reaches its largest alpha there and goes on along
    the + branch (seed Figs. 3-5, 8: only for gamma large enough).  There
    F1* = 1/cos(alpha) and, by Eq. (46), l* = 1/2.

    Solved by :func:`scipy.optimize.brentq` on (alpha0, pi/2).

    Parameters
    ----------
    gamma : array_like
        Stiffness ratio k_t/k_n.
    alpha0 : array_like
        Initial orientation (rad), in (0, pi/2); broadcast against gamma.

    Returns
    -------
    ndarray
        The turning alpha (rad), broadcast shape of the inputs (a 0-d array
        for scalars); NaN where the branch has no maximum of alpha in
        (alpha0, pi/2) (gamma <= 1/4 always; gamma below about 1.55 at alpha0 = pi/4).
    """
    gamma, alpha0 = np.broadcast_arrays(
        np.asarray(gamma, dtype=float), np.asarray(alpha0, dtype=float)
    )
    out = np.empty(gamma.shape)
    for index in np.ndindex(gamma.shape):
        out[index] = _turning_alpha_scalar(float(gamma[index]), float(alpha0[index]))
    return out


# --- Turco et al. (2019): shear translational springs ---------------------------------------


def turco_load_rotation(
    alpha: ArrayLike, gamma: ArrayLike, alpha0: ArrayLike, branch: int = -1
) -> np.ndarray:
    r"""Load-rotation curve F1*(alpha) of the Turco chain, F2* = 0.

    Seed Eq. (57); ``branch=-1`` is Eq. (58), the branch through the unloaded
    state (F1* = 0 at alpha = alpha0):

    .. math::

        F_1^* = 2\,\frac{\sin(2\alpha - \alpha_0) \pm
        \sqrt{\sin^2(2\alpha - \alpha_0)
        + \gamma\sin(2\alpha)\sin(2\alpha_0 - 2\alpha)}}{\sin(2\alpha)}.

    These are the roots of the quadratic Eq. (56),
    :math:`-\tfrac14\sin(2\alpha)F_1^{*2} + F_1^*\sin(2\alpha-\alpha_0)
    + \gamma\sin(2\alpha_0 - 2\alpha) = 0`.  (The printed Eq. (56) reads
    ``sin(2 alpha0 - alpha)`` in its last term; Eq. (55) with F2* = 0 and
    Eq. (57) both give ``sin(2 alpha0 - 2 alpha)``.)

    Parameters
    ----------
    alpha, gamma, alpha0 : array_like
        Branch orientation (rad), stiffness ratio, initial orientation (rad);
        broadcast together.
    branch : {-1, +1}
        Sign before the square root.

    Returns
    -------
    ndarray
        F1* (units of 2R k_n); NaN where the discriminant is negative.
    """
    branch_sign = _check_branch(branch)
    alpha, gamma, alpha0 = (np.asarray(a, dtype=float) for a in (alpha, gamma, alpha0))
    b = np.sin(2 * alpha - alpha0)
    delta = b**2 + gamma * np.sin(2 * alpha) * np.sin(2 * alpha0 - 2 * alpha)
    return 2 * (b + branch_sign * _sqrt_or_nan(delta)) / np.sin(2 * alpha)


def turco_branch_length(
    alpha: ArrayLike, F1: ArrayLike, F2: ArrayLike, alpha0: ArrayLike
) -> np.ndarray:
    r"""Branch length l* of the Turco chain at equilibrium.

    Seed Eq. (55), first line (from N* = -(l* - cos(alpha - alpha0)), Eq. 54):
    :math:`l^* = \cos(\alpha - \alpha_0) - \tfrac12(F_1^*\cos\alpha + F_2^*\sin\alpha)`.

    Parameters
    ----------
    alpha : array_like
        Branch orientation (rad).
    F1, F2 : array_like
        Generalized forces (units of 2R k_n).
    alpha0 : array_like
        Initial orientation (rad).

    Returns
    -------
    ndarray
        l*, broadcast shape of the inputs.
    """
    alpha, F1, F2, alpha0 = (np.asarray(a, dtype=float) for a in (alpha, F1, F2, alpha0))
    return np.cos(alpha - alpha0) - (F1 * np.cos(alpha) + F2 * np.sin(alpha)) / 2


# --- Ziegler's pendulum (two bars, springs k, masses m1 at the middle, m2 at the tip) -------


def ziegler_flutter_load(m1: ArrayLike = 2.0, m2: ArrayLike = 1.0) -> np.ndarray:
    """Undamped flutter load of the follower-loaded pendulum, units k/l.

    det(M mu + K) = m1 m2 mu^2 + (m1 + 5 m2 - 2 m2 P) mu + 1 with
    M = [[m1 + m2, m2], [m2, m2]] and K = [[2 - P, P - 1], [-1, 1]]: the two
    frequencies coalesce where its discriminant vanishes,
    P = (m1 + 5 m2 - 2 sqrt(m1 m2)) / (2 m2): 7/2 - sqrt 2 for m1 = 2 m2.
    """
    m1, m2 = np.asarray(m1, dtype=float), np.asarray(m2, dtype=float)
    return (m1 + 5 * m2 - 2 * np.sqrt(m1 * m2)) / (2 * m2)


def ziegler_divergence_load() -> float:
    """Divergence (and bifurcation) load of the dead-loaded pendulum: det K = P^2 - 3P + 1 = 0."""
    return (3 - np.sqrt(5)) / 2


def ziegler_equal_damping_flutter_load(b: ArrayLike) -> np.ndarray:
    """Flutter load with equal dashpots b1 = b2 = b, masses 2m and m (Routh-Hurwitz on
    det(M s^2 + C s + K) = 2 s^4 + 7b s^3 + (7 + b^2 - 2P) s^2 + 2b s + 1): 41/28 + b^2/2,
    whose limit 41/28 < 7/2 - sqrt 2 as b -> 0 is Ziegler's destabilization paradox."""
    b = np.asarray(b, dtype=float)
    return 41 / 28 + b * b / 2


def elastica_deflection(load_ratio: float) -> float:
    """Largest deflection over length of Euler's pinned-pinned elastica at P / P_cr = ``load_ratio`` >= 1.

    The elastica of length L under P, with lambda^2 = P / EI and k = sin(theta_0 / 2) (theta_0
    the ends' slope): L = 2 K(k) / lambda and the midspan deflection is 2 k / lambda (Timoshenko
    & Gere, *Theory of Elastic Stability*, section 2.7), so P / P_cr = (2 K(k) / pi)^2 and the
    deflection over L is k / K(k), K the complete elliptic integral of the first kind (here of
    the parameter m = k^2).  Hencky's column of n links (springs C, links a: EI = C a) tends to it
    as n grows, its joints' deflections over n a within O((pi / n)^2) of this value.
    """
    from scipy.optimize import brentq
    from scipy.special import ellipk

    if not load_ratio >= 1.0:
        raise ValueError(f"the elastica has a buckled shape for P / P_cr >= 1, got {load_ratio!r}")
    if load_ratio == 1.0:
        return 0.0
    m = brentq(lambda m: (2.0 * ellipk(m) / np.pi) ** 2 - load_ratio, 0.0, 1.0 - 1e-16, xtol=1e-15, rtol=1e-15)
    return float(np.sqrt(m) / ellipk(m))
