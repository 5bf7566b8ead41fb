"""The dynamic spectrum of M x'' + C x' + K x = 0 and its smooth stability indicators.

Every function takes the mass, damping and stiffness matrices ``M``, ``C``, ``K``
of shape ``(..., n, n)`` (leading batch dimensions broadcast against each other,
like :mod:`numpy.linalg`); ``C = None`` is an undamped system.  The roots ``s`` of
the characteristic equation

    det(M s^2 + C s + K) = 0                                             (1)

are the 2n eigenvalues of the companion (first-order) matrix

    A = [[0, I], [-M^-1 K, -M^-1 C]]                                     (2)

and a solution x = x0 exp(s t) grows where Re s > 0.  Stability is lost in two
ways: by *divergence*, a real root through s = 0 (``divergence_indicator``,
det K), and by *flutter*, a complex pair through the imaginary axis
(``flutter_onset_indicator``).  The growth rate max Re s (``flutter_indicator``)
says whether a state is stable but is not smooth (a maximum over roots, flat at
0 for an undamped system), so the events are located on the polynomial
indicators, which are smooth functions of the entries of M, C and K.

Where M is singular to working precision (|det M| at most n eps times the
product of its column norms, :func:`~ncstab.operators.dynamic_matrices.regular_mass`)
or an input is not finite, the functions that need M^-1 return NaN for that case; the other cases are unaffected, and every case's
result is the same whether it is computed alone or in a batch.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from ncstab.operators.dynamic_matrices import as_dynamic_matrices, regular_mass, solve_mass
from ncstab.operators.indicators import det_K
from ncstab.operators.onset_cases import damped_onsets, frequency_discriminants
from ncstab.operators.stored_states import undamped_growths

__all__ = [
    "critical_frequency",
    "divergence_indicator",
    "dynamic_spectrum",
    "flutter_indicator",
    "flutter_onset_indicator",
    "frequency_discriminant",
]


def _undamped(damping: np.ndarray | None, batch: tuple[int, ...]) -> np.ndarray:
    """``(...)`` bool: C is None or exactly zero in that case."""
    if damping is None:
        return np.ones(batch, dtype=bool)
    return np.all(damping == 0, axis=(-2, -1))


def dynamic_spectrum(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """The 2n roots s of det(M s^2 + C s + K) = 0, Eq. (1), sorted.

    They are computed as the eigenvalues of the companion matrix of Eq. (2) by one
    call of :func:`numpy.linalg.eigvals` on the whole batch (LAPACK ``geev`` per
    matrix, so a case's spectrum does not depend on the batch it is in).

    Parameters
    ----------
    mass, damping, stiffness
        M, C, K of shape ``(..., n, n)``; ``damping=None`` means C = 0.

    Returns
    -------
    numpy.ndarray
        ``(..., 2n)`` complex, sorted by imaginary part and, for equal imaginary
        parts (the real roots, whose imaginary part is exactly 0), by real part.
        The order is a function of the values alone, so it does not depend on
        the batch.  NaN where M is singular or an input is not finite.
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    n = mass.shape[-1]
    rhs = stiffness if damping is None else np.concatenate([stiffness, damping], axis=-1)
    product, valid = solve_mass(mass, rhs)
    companion = np.zeros(mass.shape[:-2] + (2 * n, 2 * n))
    companion[..., :n, n:] = np.eye(n)
    companion[..., n:, : product.shape[-1]] = -product
    eigenvalues = np.linalg.eigvals(companion).astype(complex)
    order = np.lexsort((eigenvalues.real, eigenvalues.imag), axis=-1)
    eigenvalues = np.take_along_axis(eigenvalues, order, axis=-1)
    return np.where(valid[..., None], eigenvalues, complex(np.nan, np.nan))


def flutter_indicator(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """Growth rate max Re s over the roots of Eq. (1): ``(...)``, > 0 unstable.

    A state is asymptotically stable where it is < 0.  For an undamped system
    below its flutter load every root is imaginary, so the indicator is flat at
    0 (up to rounding, ~1e-15) over a whole range of loads and then grows like
    the square root of the distance to the onset: events are located on
    :func:`flutter_onset_indicator` and :func:`divergence_indicator`, not on it.

    Undamped cases take a shortcut with the same roots: s = +-sqrt(mu) with mu
    the n eigenvalues of -M^-1 K, so max Re s is the largest |Re sqrt(mu)| --
    an n x n problem instead of the 2n x 2n companion; for n = 2 in closed
    form (:func:`ncstab.operators.one_state.undamped_growth_2`).
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    undamped = _undamped(damping, mass.shape[:-2])
    if undamped.all():
        return _undamped_growth(mass, stiffness)
    # each case by its own kind, so that its value does not depend on the others in the batch
    growth = np.empty(mass.shape[:-2])
    damped = ~undamped
    growth[damped] = dynamic_spectrum(mass[damped], damping[damped], stiffness[damped]).real.max(axis=-1)
    growth[undamped] = _undamped_growth(mass[undamped], stiffness[undamped])
    return growth


def _undamped_growth(mass: np.ndarray, stiffness: np.ndarray) -> np.ndarray:
    """max Re s of M s^2 + K (C = 0): the largest |Re sqrt(mu)| over the n eigenvalues
    mu of -M^-1 K (:func:`flutter_indicator`), NaN where M is singular."""
    product, valid = solve_mass(mass, stiffness)
    if mass.shape[-1] == 2:
        growth = undamped_growths(product)  # (the Dataset's compiled pass calls the same function)
    else:
        mu = -np.linalg.eigvals(product).astype(complex)
        growth = np.abs(np.sqrt(mu).real).max(axis=-1)
    return np.where(valid, growth, np.nan)


def divergence_indicator(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """det K ``(...)``: a real root s of Eq. (1) passes through 0 where it vanishes.

    At s = 0 the characteristic polynomial is det(M 0 + C 0 + K) = det K, so
    s = 0 is a root exactly when det K = 0, whatever M and C; a simple root
    crossing 0 changes the sign of det K.  M and C are only checked for shape.
    NaN where K is not finite.
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    finite = np.isfinite(stiffness).all(axis=(-2, -1))
    return np.where(finite, det_K(np.where(finite[..., None, None], stiffness, 0.0)), np.nan)


def frequency_discriminant(mass: ArrayLike, stiffness: ArrayLike) -> np.ndarray:
    """Discriminant of q(mu) = det(M mu + K), the undamped polynomial in mu = s^2.

    With C = 0 the roots of Eq. (1) are s = +-sqrt(mu) for the n roots mu of q.
    The system is stable (all s imaginary) while every mu is real and negative;
    flutter starts where two real negative mu (two frequencies) coalesce and
    leave the real axis as a complex pair: the discriminant crosses zero from
    positive to negative.  It is a polynomial in the entries of M and K, hence
    smooth along a path.

    n = 1: 1 (a linear polynomial has no pair to coalesce).  n = 2, with
    q(mu) = a mu^2 + b mu + c, a = det M, c = det K and
    b = M11 K22 + K11 M22 - M12 K21 - K12 M21: b^2 - 4 a c.  n >= 3:
    a^(2n - 2) prod_{i<j} (mu_i - mu_j)^2, computed as
    det(M)^(2n-2) * ``flutter_discriminant(M^-1 K)`` (the mu are minus the
    eigenvalues of M^-1 K; backward-stable eigenvalues give it to an absolute
    accuracy of a few eps times its scale).  Each complex pair of mu contributes
    a negative factor, so for n >= 4 a second pair makes it positive again: the
    event is the crossing, not the sign.

    Parameters
    ----------
    mass, stiffness
        ``(..., n, n)``.

    Returns
    -------
    numpy.ndarray
        ``(...)``; NaN where M is singular or an input is not finite.  For M = m I
        it is m^(n(n-1)) times ``flutter_discriminant(K)`` (equal for n = 2).
    """
    mass, _, stiffness = as_dynamic_matrices(mass, None, stiffness)
    n = mass.shape[-1]
    if n > 2:  # each case alone, the compiled stepper's function (NaN where not valid)
        return frequency_discriminants(mass, stiffness)
    valid = regular_mass(mass) & np.isfinite(stiffness).all(axis=(-2, -1))
    if n == 1:
        discriminant = np.ones(mass.shape[:-2])
    elif n == 2:
        a = det_K(mass)
        b = (
            mass[..., 0, 0] * stiffness[..., 1, 1]
            + stiffness[..., 0, 0] * mass[..., 1, 1]
            - mass[..., 0, 1] * stiffness[..., 1, 0]
            - stiffness[..., 0, 1] * mass[..., 1, 0]
        )
        discriminant = b * b - 4.0 * a * det_K(stiffness)
    return np.where(valid, discriminant, np.nan)


def flutter_onset_indicator(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """Smooth function whose zero is a flutter onset: ``(...)``, > 0 on the stable side.

    Undamped cases (``damping=None``, or C exactly 0 in that case):
    :func:`frequency_discriminant`.  Damped cases: the Hurwitz determinant
    Delta_{2n-1} of the characteristic polynomial made monic (divided by its
    leading coefficient det M).  By Orlando's formula, for a polynomial
    a0 s^N + ... + aN with roots s_1..s_N,

        Delta_{N-1} = (-1)^(N(N-1)/2) a0^(N-1) prod_{i<j} (s_i + s_j),

    so Delta_{2n-1} vanishes exactly where two roots sum to zero: a pair
    +-i omega on the imaginary axis (a complex pair crossing it; the real
    pair +-sigma and a double root at 0 also make it vanish).  While every root
    has Re s < 0 all Hurwitz determinants are positive (Routh-Hurwitz), and
    Delta_{2n} = a_{2n} Delta_{2n-1} with a_{2n} = det K: with divergence
    (det K = 0) excluded, a loss of stability of a damped system is a zero of
    Delta_{2n-1}.  For C = 0 the roots come in pairs +-s, so Delta_{2n-1} is
    identically 0, which is why undamped cases use the discriminant instead.

    The value's magnitude has no meaning (Delta_{2n-1} scales like the damping
    squared for a light damping); its sign changes are the events.  NaN where
    M is singular or an input is not finite.
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    undamped = _undamped(damping, mass.shape[:-2])
    # (an array, of the batch's shape, even for an empty batch: a stage entered by no case)
    discriminant = frequency_discriminant(mass, stiffness) if undamped.any() else np.full(undamped.shape, np.nan)
    if damping is None:
        return discriminant
    # each case alone, by the compiled per-case function the compiled stepper calls too
    return np.where(undamped, discriminant, damped_onsets(mass, damping, stiffness))


def critical_frequency(
    mass: ArrayLike, damping: ArrayLike | None, stiffness: ArrayLike
) -> np.ndarray:
    """Imaginary part omega >= 0 of the critical pair s = +-i omega at an onset point.

    Damped cases: the two roots s_i, s_j of Eq. (1) with the smallest |s_i + s_j|
    (the pair that makes Orlando's product, and so Delta_{2n-1}, vanish), and
    omega = |Im(s_i - s_j)| / 2.  Undamped cases (C None or exactly 0): the two
    closest roots mu_i, mu_j of det(M mu + K) (the coalescing frequencies;
    the only root for n = 1), and omega = |Im sqrt((mu_i + mu_j) / 2)|: at the
    coalescence mu_i = mu_j = -omega^2, and the mean of the pair is accurate
    even where each mu carries the sqrt(eps) error of a double root.

    Meaningful at an onset located by :func:`flutter_onset_indicator`; elsewhere
    it is the frequency of the pair nearest to that condition.

    Returns
    -------
    numpy.ndarray
        ``(...)``; NaN where M is singular or an input is not finite.
    """
    mass, damping, stiffness = as_dynamic_matrices(mass, damping, stiffness)
    n = mass.shape[-1]
    undamped = _undamped(damping, mass.shape[:-2])
    frequency = np.full(mass.shape[:-2], np.nan)
    if undamped.any():
        product, valid = solve_mass(mass, stiffness)
        mu = (-np.linalg.eigvals(product)).astype(complex)
        if n == 1:
            mean = mu[..., 0]
        else:
            i, j = _closest_pair(np.abs(mu[..., :, None] - mu[..., None, :]))
            mean = 0.5 * (np.take_along_axis(mu, i, -1) + np.take_along_axis(mu, j, -1))[..., 0]
        omega = np.abs(np.sqrt(mean).imag)
        frequency = np.where(undamped & valid, omega, frequency)
    if damping is not None and not undamped.all():
        roots = dynamic_spectrum(mass, damping, stiffness)
        i, j = _closest_pair(np.abs(roots[..., :, None] + roots[..., None, :]))
        difference = (np.take_along_axis(roots, i, -1) - np.take_along_axis(roots, j, -1))[..., 0]
        frequency = np.where(undamped, frequency, 0.5 * np.abs(difference.imag))
    return frequency


def _closest_pair(distance: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Indices ``(..., 1)`` of the off-diagonal minimum of ``(..., m, m)`` distances.

    NaN distances (invalid cases) are treated as infinite, so every case gets
    a pair (its result is masked by the caller).
    """
    m = distance.shape[-1]
    distance = np.where(np.eye(m, dtype=bool) | np.isnan(distance), np.inf, distance)
    flat = np.argmin(distance.reshape(distance.shape[:-2] + (m * m,)), axis=-1)
    return (flat // m)[..., None], (flat % m)[..., None]
