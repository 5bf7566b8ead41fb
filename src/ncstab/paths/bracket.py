"""The Illinois iteration on a bracket of a sign change: event location in both engines.

An event is located on sigma, the arclength from the start of the step in which
its indicator changed sign, by the Illinois variant of regula falsi (Dowell &
Jarratt 1971): the next trial is the secant's zero through the bracket's ends;
where the same end is kept twice in a row, the value at the other end is halved,
so that the bracket closes from both sides (superlinear, of order 1.44, where
plain regula falsi is linear); the trial falls back to the bracket's middle
where the secant's zero is not inside it and, every fifth trial, where the last
five did not halve the bracket (no worse than bisection on a noisy indicator).

Both engines call these two functions, each with its own way of evaluating a
trial: the compiled loop (:func:`ncstab.paths.loop_steps.locate`) takes the
point at sigma on the step's DOP853 interpolant; the sparse engine
(:mod:`ncstab.paths.assembled_path`) re-corrects the state at sigma onto the
path.  The compiled loop has them in its machine code; the sparse engine runs the
same text as plain Python (:func:`ncstab.plain_python.plain_import`).
"""

from __future__ import annotations

import numba
import numpy as np

from ncstab.paths.events import TINY
from ncstab.paths.loop_numerics import sign

__all__ = ["illinois_trial", "illinois_update"]

# Not cached beside ncstab's files: a loop that calls them compiles them into its own machine
# code, which numba caches in ncstab's cache folder with the loop.  Called from Python too (tests).
njit = numba.njit(cache=False, error_model="numpy")

#: Every this many trials the bracket must have halved, else the trial is its middle.
HALVING_CHECK = 5


@njit
def illinois_trial(lower, upper, f_lower, f_upper, iteration, last_width):
    """The next trial in the bracket (lower, upper) of a sign change, the values there
    f_lower and f_upper of opposite signs, at the ``iteration``-th trial (from 0).

    Returns the trial (the secant's zero, or the middle: see the module) and the
    bracket's width to compare with ``HALVING_CHECK`` trials on (``last_width``
    starts as the first bracket's width).
    """
    width = upper - lower
    candidate = (lower * f_upper - upper * f_lower) / (f_upper - f_lower)
    bisect = not np.isfinite(candidate) or candidate <= lower or candidate >= upper
    if iteration % HALVING_CHECK == HALVING_CHECK - 1:
        bisect = bisect or width > 0.5 * last_width
        last_width = width
    if bisect:
        candidate = 0.5 * (lower + upper)
    return candidate, last_width


@njit
def illinois_update(lower, upper, f_lower, f_upper, side, candidate, value):
    """The bracket after the trial ``candidate`` gave ``value``.

    The end with the value's sign moves to the trial; where the same end moved
    at the trial before (``side``: 1 the lower, -1 the upper, 0 none yet) the
    value kept at the other end is halved (Illinois).  A value within ``TINY``
    of zero, or not finite, is the crossing itself: both ends move to the trial.

    Returns (lower, upper, f_lower, f_upper, side, exact), ``exact`` where the
    trial was the crossing.
    """
    a_side = sign(value) == sign(f_lower)
    b_side = sign(value) == sign(f_upper)
    exact = abs(value) <= TINY or not np.isfinite(value)
    if a_side:
        if side == 1:
            f_upper *= 0.5
        lower, f_lower, side = candidate, value, 1
    if b_side:
        if side == -1:
            f_lower *= 0.5
        upper, f_upper, side = candidate, value, -1
    if exact:
        lower = upper = candidate
    return lower, upper, f_lower, f_upper, side, exact
