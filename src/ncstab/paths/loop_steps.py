"""The compiled stage loop's steps: one DOP853 step, its dense output, and events located on it.

A DOP853 step and its dense output through the model's rates, and event location
by the Illinois iteration on that interpolant, for any model: what depends on the
model is asked of it through :mod:`ncstab.paths.loop_dispatch`.  The model-free
numerics (the tableau, the stage sums, the error norm, the dense output's value)
are in :mod:`ncstab.paths.loop_numerics`.
"""

from __future__ import annotations

import numpy as np

from ncstab.jit import njit
from ncstab.paths.compiled import _EXTENDED, _POWER, _STAGES
from ncstab.paths.bracket import illinois_trial, illinois_update
from ncstab.paths.loop_dispatch import (
    evaluate, event_columns, indicators, no_tangent, project, rhs, rhs_hot, state_indicator, state_size, tangent_at,
)
from ncstab.paths.loop_numerics import (
    A_COUNT, A_TERMS, B_COUNT, B_TERMS, D_COUNT, D_TERMS, A, B, D, combine, dense_value, error_norm,
)

__all__ = ["dense_coefficients", "dop853", "drop_limit_at_bifurcation", "indicator_at", "locate"]


@njit
def dense_coefficients(y0, y_raw, h, case, stages, coefficients, work, ev, aux):
    # DOP853's dense output (scipy's: the three extra stages, unprojected)
    kind, fc, ctl, orient, law, p, geo = case
    m = state_size(kind, y0)
    state, sums = work[0], work[1]
    for s in range(_STAGES + 1, _EXTENDED):
        combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums, m)
        for j in range(m):
            state[j] = y0[j] + sums[j] * h
        rhs(kind, state, fc, ctl, orient, law, p, geo, stages[s], ev, aux)
    for j in range(m):
        delta = y_raw[j] - y0[j]
        f_old, f_new = stages[0, j], stages[_STAGES, j]
        coefficients[0, j] = delta
        coefficients[1, j] = h * f_old - delta
        coefficients[2, j] = 2 * delta - h * (f_new + f_old)
    for k in range(_POWER - 3):
        combine(D[k], D_TERMS[k], D_COUNT[k], stages, sums, m)
        for j in range(m):
            coefficients[3 + k, j] = h * sums[j]


@njit
def indicator_at(y, column, case, goal, settings, ev, aux, values):
    # an indicator inside a piece: project (total form), evaluate, one column.
    # Without a projection, a column that is a function of y alone (the target, the
    # diamond's gaps) takes the same operations without the law (bit for bit).
    kind, fc, ctl, orient, law, p, geo = case
    lam_end, target_sign, turn_end, secondary = goal
    newton_tol, newton_max_iter = settings.newton_tol, settings.newton_max_iter
    if kind.rate_form:
        known, value = state_indicator(kind, y, column, lam_end, target_sign, secondary, geo)
        if known:
            return value
    if not kind.rate_form:
        project(kind, y, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev)
    else:
        evaluate(kind, y, ctl, law, p, geo, ev)
    columns = event_columns(kind, geo)
    if column == columns.turning or column == columns.bifurcation:
        tangent_at(kind, y, fc, ctl, orient, ev, aux, geo)
    else:
        no_tangent(kind, aux)
    indicators(kind, ev, aux, y, fc, ctl, geo, lam_end, target_sign, turn_end, secondary, values)
    return values[column]


@njit
def locate(column, offset, span, phi0, phi1, interpolant, case, goal, settings, evaluation, values, state):
    # a sign change located by the Illinois iteration (ncstab.paths.bracket), one pair: returns
    # (sigma, lower, upper) in the piece (offset, offset + span) of the step (its interpolant);
    # state at sigma
    y0, coefficients, h = interpolant
    ev, aux = evaluation
    event_tol = settings.event_tol
    lower, upper = 0.0, span
    f_lower, f_upper = phi0, phi1
    side = 0
    sigma = np.nan
    last_width = upper - lower
    for iteration in range(200):
        candidate, last_width = illinois_trial(lower, upper, f_lower, f_upper, iteration, last_width)
        dense_value(y0, coefficients, (offset + candidate) / h, state)
        value = indicator_at(state, column, case, goal, settings, ev, aux, values)
        sigma = candidate
        lower, upper, f_lower, f_upper, side, exact = illinois_update(lower, upper, f_lower, f_upper, side,
                                                                      candidate, value)
        if upper - lower <= event_tol or exact:
            break
    return sigma, lower, upper


@njit
def drop_limit_at_bifurcation(kind, sigma, span, geo):
    # a zero of det K where the branch test
    # changes sign too (within 1e-6 of the piece) is a simple bifurcation point
    columns = event_columns(kind, geo)
    bifurcation, limit = columns.bifurcation, columns.limit
    if bifurcation >= 0 and np.isfinite(sigma[bifurcation]) and abs(sigma[limit] - sigma[bifurcation]) <= 1e-6 * span:
        sigma[limit] = np.inf


@njit
def dop853(y0, f0, h, case, settings, stages, y1, work, ev, aux):
    # one DOP853 step (scipy's tableau); leaves ev, aux at the end state y1 (its last stage)
    kind, fc, ctl, orient, law, p, geo = case
    m = state_size(kind, y0)
    state, sums = work[0], work[1]
    for j in range(m):
        stages[0, j] = f0[j]
    for s in range(1, _STAGES):
        combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums, m)
        for j in range(m):
            state[j] = y0[j] + sums[j] * h
        rhs_hot(kind, state, fc, ctl, orient, law, p, geo, stages[s], ev, aux)
    combine(B, B_TERMS, B_COUNT, stages, sums, m)
    for j in range(m):
        y1[j] = y0[j] + h * sums[j]
    rhs_hot(kind, y1, fc, ctl, orient, law, p, geo, stages[_STAGES], ev, aux)
    return error_norm(y0, y1, h, settings.rtol, settings.atol, stages, work, m)
