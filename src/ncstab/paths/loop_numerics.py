"""The compiled loop's numerics that do not depend on the model: plain compiled functions.

DOP853 as scipy has it (``scipy.integrate.RK45``'s sibling ``DOP853``: its
tableau, the stage sums, the error norm, the dense output's Horner form and
Hairer's starting step), the sign of a value, how many pieces a step is cut
into, which of an event's indicator columns was crossed first, and the
arithmetic of over steps across simple bifurcation points
(:mod:`ncstab.paths.over_steps`: their lengths, interpolant and arclength).  The stage
loops (:mod:`ncstab.paths.compiled_source`) import them; where a function needs
the state's size ``m`` it takes it, so that the diamond's loop passes its
constant and its loops unroll.
"""

from __future__ import annotations

import numba
import numpy as np

from ncstab.paths.compiled import _A, _B, _D, _E3, _E5, _EXTENDED, _POWER, _STAGES, _terms
from ncstab.paths.over_steps import OVER_MARGIN

__all__ = [
    "A_COUNT",
    "A_TERMS",
    "B_COUNT",
    "B_TERMS",
    "D_COUNT",
    "D_TERMS",
    "A",
    "B",
    "D",
    "combine",
    "dense_value",
    "error_norm",
    "first_column",
    "initial_step_size",
    "next_degenerate_length",
    "next_over_length",
    "over_coefficients",
    "piece_count",
    "richardson_arc",
    "sign",
]

# Not cached beside ncstab's files: a loop that calls them compiles them into its own
# machine code, which numba caches in ncstab's cache folder with the loop.
njit = numba.njit(cache=False, error_model="numpy")
hot = numba.njit(cache=False, error_model="numpy", inline="always")

#: DOP853's tableau (scipy's ``dop853_coefficients``): the stage weights A, the
#: solution's B, the two error estimators E3 and E5 and the dense output's D, each
#: row with its terms (:func:`combine` sums the first stage and the non-zero weights).
A, B, E3, E5, D = _A, _B, _E3, _E5, _D
A_TERMS, A_COUNT = _terms(_A, np.arange(_EXTENDED))
D_TERMS, D_COUNT = _terms(_D, [_EXTENDED] * _D.shape[0])
B_TERMS, B_COUNT = (row[0] for row in _terms(_B[None, :], [_STAGES]))
E5_TERMS, E5_COUNT = (row[0] for row in _terms(_E5[None, :], [_STAGES + 1]))
E3_TERMS, E3_COUNT = (row[0] for row in _terms(_E3[None, :], [_STAGES + 1]))


@hot
def combine(weights, terms, n_terms, stages, out, m):
    """``out = sum_k weights[k] stages[k]`` over the first ``m`` components: term by term in
    stage order, the first term and then the non-zero weights (``terms``: their stage
    indices, ``n_terms`` of them)."""
    w = weights[0]
    for j in range(m):
        out[j] = w * stages[0, j]
    for t in range(1, n_terms):
        k = terms[t]
        w = weights[k]
        for j in range(m):
            out[j] += w * stages[k, j]


@njit
def max_nan(a, b):
    """``np.maximum`` of two scalars: NaN if either is NaN."""
    if np.isnan(a) or np.isnan(b):
        return np.nan
    return max(a, b)


@njit
def error_norm(y0, y1, h, rtol, atol, stages, work, m):
    """DOP853's error norm of the step y0 -> y1 of length h (scipy's
    ``_estimate_error_norm``), inf where y1 or the norm is not finite; ``work[1]`` and
    ``work[2]`` are scratch."""
    sums, sums3 = work[1], work[2]
    err5_sq = 0.0
    err3_sq = 0.0
    finite = True
    combine(E5, E5_TERMS, E5_COUNT, stages, sums, m)
    combine(E3, E3_TERMS, E3_COUNT, stages, sums3, m)
    for j in range(m):
        scale = atol + max_nan(abs(y0[j]), abs(y1[j])) * rtol
        e5 = sums[j] / scale
        e3 = sums3[j] / scale
        err5_sq += e5 * e5
        err3_sq += e3 * e3
        finite = finite and np.isfinite(y1[j])
    denominator = err5_sq + 0.01 * err3_sq
    err = abs(h) * err5_sq / np.sqrt(denominator * m) if denominator > 0 else 0.0
    if not (finite and np.isfinite(err)):
        err = np.inf
    return err


@njit
def dense_value(y0, coefficients, fraction, out):
    """The step's dense output at ``fraction`` of it (scipy's Horner form), into ``out``."""
    for j in range(y0.size):
        value = 0.0
        for i in range(_POWER):
            value += coefficients[_POWER - 1 - i, j]
            value *= fraction if i % 2 == 0 else 1 - fraction
        out[j] = value + y0[j]


@njit
def sign(x):
    """+1, -1, or x itself where it is 0 or NaN."""
    if x > 0:
        return 1.0
    if x < 0:
        return -1.0
    return x


@njit
def first_column(columns, sigma):
    """Of an event's indicator ``columns`` (-1: none), the one crossed first (least
    ``sigma``); -1 where none is."""
    best, best_column = np.inf, -1
    for c in columns:
        if c >= 0 and (best_column < 0 or sigma[c] < best):
            best, best_column = sigma[c], c
    return best_column


@njit
def piece_count(h, sample_step, max_pieces):
    """How many pieces a step of length h is cut into (``PathOptions.pieces``):
    ceil(h / sample_step), between 1 and ``max_pieces``."""
    if not (h > sample_step):
        return 1
    return min(int(np.ceil(h / sample_step)), max_pieces)


@njit
def initial_step_size(y0, f0, f1, probe, rtol, atol, m):
    """Hairer's starting step (scipy's ``select_initial_step``) from the rates ``f0`` at
    ``y0`` and ``f1`` a ``probe`` step along it, one case of state size ``m``."""
    s1 = 0.0
    s2 = 0.0
    for j in range(m):
        scale = atol + abs(y0[j]) * rtol
        a = f0[j] / scale
        b = (f1[j] - f0[j]) / scale
        s1 += a * a
        s2 += b * b
    d1 = np.sqrt(s1 / m)
    d2 = np.sqrt(s2 / m) / probe
    largest = np.nan if (np.isnan(d1) or np.isnan(d2)) else max(d1, d2)
    if not np.isfinite(largest):
        return probe
    if largest <= 1e-15:
        return min(100 * probe, max(1e-6, 1e-3 * probe))
    return min(100 * probe, np.sqrt(np.sqrt(np.sqrt(0.01 / largest))))


# --- over steps across simple bifurcation points (ncstab.paths.over_steps)


@njit
def next_over_length(size_before, size_after, reach, newton_tol):
    """The length of the over step tried next (0: none): twice the distance ``d`` ahead at
    which the branch test's size, ``size_before`` then ``size_after`` over a step of length
    ``reach``, extrapolates to zero, where ``0 < d <= OVER_MARGIN sqrt(newton_tol)``."""
    ahead = reach * size_after / (size_before - size_after)
    tried = size_before > size_after > 0 and reach > 0
    return 2.0 * ahead if tried and ahead <= OVER_MARGIN * np.sqrt(newton_tol) else 0.0


@njit
def next_degenerate_length(size_before, size_after, reach):
    """The degenerate over step's length (0: none): twice the distance at which the square
    root of the branch test's size extrapolates to zero."""
    before, after = np.sqrt(size_before), np.sqrt(size_after)
    ahead = reach * after / (before - after)
    tried = before > after > 0 and reach > 0 and ahead <= np.inf
    return 2.0 * ahead if tried else 0.0


@njit
def over_coefficients(length, arc, rate, m, coefficients):
    """The over step's interpolant in the form of DOP853's dense output (:func:`dense_value`):
    y0 + sigma(f) dy/ds with sigma(f) = L f + (arc - L) f (1 - f), which ends at the
    predictor's end (sigma(1) = L) and makes the arclength of the projected states
    proportional to f to second order."""
    for k in range(coefficients.shape[0]):
        for j in range(m):
            coefficients[k, j] = 0.0
    for j in range(m):
        coefficients[0, j] = length * rate[j]
        coefficients[1, j] = (arc - length) * rate[j]


@njit
def richardson_arc(whole, halves):
    """The length of an arc from its chord (``whole``) and the chords of its halves
    (``halves``), extrapolated (Richardson): exact to O(kappa^4 L^5) for a smooth arc of
    length L."""
    return (4.0 * halves - whole) / 3.0
