"""What the shared parts of the compiled stage loop ask of the reduced diamond.

The shared parts (:mod:`ncstab.paths.loop_steps`, :mod:`~ncstab.paths.loop_step_limits`,
:mod:`~ncstab.paths.loop_start`, :mod:`~ncstab.paths.loop_cases`) know nothing of a
model's layout: through :mod:`ncstab.paths.loop_dispatch` they ask the model for
its sizes and event columns, its tangent, the Newton projection, the domain check,
the arc of an over step and what is stored.  These are the diamond's answers
(its evaluation and indicators are in :mod:`ncstab.paths.loop_diamond_model`); a
general model's are in :mod:`ncstab.paths.loop_general` and
:mod:`ncstab.paths.loop_general_output`, under the same names and parameters.
"""

from __future__ import annotations

import numpy as np

from ncstab.jit import hot, njit
from ncstab.paths.compiled import _N_COLUMNS, BREAK_ALWAYS, STATE_SLOT
from ncstab.paths.events import (
    BIFURCATION_COLUMN, CYCLE_COLUMN, INDICATOR_EVENTS, INDICATOR_GAP, TARGET_COLUMN, TURNING_COLUMN,
)
from ncstab.paths.loop_diamond_model import angle, control, evaluate, gap, internal_count, tangent
from ncstab.paths.loop_diamond_model import (  # noqa: F401 (handed on: the diamond's MODEL_FUNCTIONS)
    alignment, branch_size, indicators, motion, motion_product, rhs, rhs_hot,
)
from ncstab.paths.loop_numerics import richardson_arc
from ncstab.paths.loop_records import MODEL_FUNCTIONS, EventColumns
from ncstab.paths.loop_signs import signed_gap, target_indicator

__all__ = list(MODEL_FUNCTIONS)  # (those of loop_diamond_model and loop_general it imports included)

n_columns, target_column, turning_column, cycle_column = _N_COLUMNS, TARGET_COLUMN, TURNING_COLUMN, CYCLE_COLUMN
bifurcation_column, limit_column = BIFURCATION_COLUMN, INDICATOR_EVENTS.index("limit_point")
control_column = INDICATOR_EVENTS.index("controllability_loss")
gap_columns = (INDICATOR_GAP.index(1), INDICATOR_GAP.index(2))  # the two diagonals (ev[12], ev[13])
switch_bits = np.array(INDICATOR_GAP, dtype=np.int64)
cut_always = np.array([c in (TARGET_COLUMN, CYCLE_COLUMN) or BREAK_ALWAYS[c] for c in range(_N_COLUMNS)])
# Sizes and columns: constants of the diamond (geo, the case's geometry row, is not read).



@hot
def state_size(kind, y):
    # the length of y = (v0, v1, lambda, [T], W)
    return 4 + internal_count(kind)


@hot
def ev_size(kind, geo):
    return 17


@hot
def aux_size(kind, geo):
    return 11


@hot
def motion_size(kind, geo):
    # (du, dF, dlambda): 2n + 1
    return 5


@hot
def event_columns(kind, geo):
    return EventColumns(
        n_columns, target_column, cycle_column, turning_column, bifurcation_column, limit_column, control_column
    )


@hot
def switch_bit(kind, geo, column):
    # the contact-state bit a column's crossing toggles (events.INDICATOR_GAP)
    return switch_bits[column]


@hot
def next_state(kind, geo, secondary, bit, y):
    # the contact state after a switch of ``bit`` (contacts): its bit toggles
    return secondary ^ bit


@hot
def cuts_always(kind, geo, column):
    # the target, the end of a turn and a no_tension contact's switch cut a step
    return cut_always[column]


@hot
def set_state(kind, p, geo, secondary):
    # the contact-state bits, where the law's kernel reads them
    p[STATE_SLOT] = secondary


@njit
def tangent_at(kind, y, fc, ctl, orient, ev, aux, geo):
    # the tangent at an evaluated state (ev), into aux
    _, _, g0, g1 = control(y[2], ctl)
    tangent(ev, fc[0], fc[1], g0, g1, orient, aux)


@njit
def no_tangent(kind, aux):
    # dlambda and the branch test left NaN (an indicator that needs no tangent)
    aux[4] = np.nan
    aux[10] = np.nan


@hot
def tries_degenerate(kind, geo):
    # degenerate over steps from three dofs on (not the diamond; over_steps)
    return False


@hot
def was_flipped(kind, aux):
    return aux[9] > 0


@njit
def set_reference(kind, aux, orient):
    # the reference of the next piece, the motion (du, dF, dlambda)
    orient[1], orient[2], orient[3], orient[4], orient[5] = aux[2], aux[3], aux[6], aux[7], aux[4]


@njit
def state_indicator(kind, y, column, lam_end, target_sign, secondary, geo):
    # (True, value) for a column that is a function of y alone without a projection (a
    # rate form: the target and the gaps, the same operations without the law, bit for
    # bit); (False, NaN) for the others
    if column == target_column:
        return True, target_indicator(y[2], lam_end, target_sign)
    if column == gap_columns[0]:
        return True, signed_gap(gap(geo[0] - y[0]), secondary, 1)
    if column == gap_columns[1]:
        return True, signed_gap(gap(geo[1] - y[1]), secondary, 2)
    return False, np.nan


@njit
def residual(ev, y, fc0, fc1, g0, g1):
    # StageArrays.residual: P u + Q F - g(lambda), max norm; returns (r0, r1, size)
    r0 = (ev[4] if fc0 else y[0]) - g0
    r1 = (ev[5] if fc1 else y[1]) - g1
    a0, a1 = abs(r0), abs(r1)
    size = np.nan if (np.isnan(a0) or np.isnan(a1)) else max(a0, a1)
    return r0, r1, size


@njit
def project(kind, y, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev):
    # the Newton projection onto equilibrium (projection), one case; ev left at the final state
    fc0, fc1 = fc[0], fc[1]
    for _ in range(newton_max_iter + 1):
        evaluate(kind, y, ctl, law, p, geo, ev)
        path0, path1, g0, g1 = control(y[2], ctl)  # g and g' at this iteration's lambda
        r0, r1, size = residual(ev, y, fc0, fc1, path0, path1)
        if size <= newton_tol:
            return True
        if not np.isfinite(size):
            return False
        k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
        m00 = k00 if fc0 else 1.0
        m01 = k01 if fc0 else 0.0
        m10 = k10 if fc1 else 0.0
        m11 = k11 if fc1 else 1.0
        a00 = (m00 * m00 + m01 * m01) + g0 * g0
        a01 = (m00 * m10 + m01 * m11) + g0 * g1
        a11 = (m10 * m10 + m11 * m11) + g1 * g1
        det = a00 * a11 - a01 * a01
        z0 = (a11 * r0 - a01 * r1) / det
        z1 = (a00 * r1 - a01 * r0) / det
        singular = (
            np.isfinite(a00) and np.isfinite(a01) and np.isfinite(a11)
            and not (np.isfinite(z0) and np.isfinite(z1))
        )
        if singular:  # rank-deficient normal matrix: least squares
            normal = np.empty((2, 2))
            normal[0, 0] = m00 * m00 + m01 * m01 + g0 * g0
            normal[0, 1] = m00 * m10 + m01 * m11 + g0 * g1
            normal[1, 0] = m10 * m00 + m11 * m01 + g1 * g0
            normal[1, 1] = m10 * m10 + m11 * m11 + g1 * g1
            right = np.empty(2)
            right[0], right[1] = r0, r1
            solution = np.linalg.lstsq(normal, right)[0]
            z0, z1 = solution[0], solution[1]
        dv0 = -(m00 * z0 + m10 * z1)
        dv1 = -(m01 * z0 + m11 * z1)
        y[0] += dv0
        y[1] += dv1
        y[2] += g0 * z0 + g1 * z1
        du0 = 1.0 * dv0 + 0.0 * dv1
        du1 = 0.0 * dv0 + 1.0 * dv1
        y[3 + internal_count(kind)] += 0.5 * (ev[4] * du0 + ev[5] * du1)
    evaluate(kind, y, ctl, law, p, geo, ev)
    return False


@njit
def domain_detail(kind, state, ev_state, geo):
    # the domain (domain_edge), one state: -1 inside the domain, else the index of the reason
    # in model.DOMAIN_REASONS (0 non-finite numbers, 1 l* <= 0, 2 |alpha| >= pi/2)
    finite = np.isfinite(ev_state[4]) and np.isfinite(ev_state[5])
    for j in range(state_size(kind, state)):
        finite = finite and np.isfinite(state[j])
    if not finite:
        return 0
    if not (ev_state[0] > 0):
        return 1
    if not (abs(angle(ev_state)) < 0.5 * np.pi):
        return 2
    return -1


@njit
def arc_through(kind, y0, y_half, y_new, ev_new, ctl, law, p, geo, ev):
    # the arc (over_steps: exact to O(kappa^4 L^5)) through the start y0, the middle y_half (evaluated in
    # ev on entry) and the end y_new (ev_new), in (u, F, lambda); ev left at the start
    h0, h1 = ev[4], ev[5]  # F at the middle, then at the start
    evaluate(kind, y0, ctl, law, p, geo, ev)
    a0, a1, a2, a3, a4 = y_half[0] - y0[0], y_half[1] - y0[1], h0 - ev[4], h1 - ev[5], y_half[2] - y0[2]
    b0, b1, b2, b3, b4 = y_new[0] - y_half[0], y_new[1] - y_half[1], ev_new[4] - h0, ev_new[5] - h1, y_new[2] - y_half[2]
    c0, c1, c2, c3, c4 = y_new[0] - y0[0], y_new[1] - y0[1], ev_new[4] - ev[4], ev_new[5] - ev[5], y_new[2] - y0[2]
    whole = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3 + c4 * c4)
    halves = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3 + a4 * a4)
    halves += np.sqrt(b0 * b0 + b1 * b1 + b2 * b2 + b3 * b3 + b4 * b4)
    return richardson_arc(whole, halves)


@njit
def turn_record(kind, y, ev, row, geo):
    # W, F1, F2 and T where a turn closes (the cycle tables)
    row[0] = y[state_size(kind, y) - 1]
    row[1] = ev[4]
    row[2] = ev[5]
    row[3] = ev[3]


@njit
def store_record(kind, recorded, i, position, arclength, stage_number, y, ev, aux, geo):
    # a stored state, straight into the recorder's padded arrays
    # (``recorded``: one array per field, in the order of BatchStepper.record_fields())
    (r_s, r_stage, r_u, r_lam, r_internal, r_work, r_f, r_l, r_alpha, r_n, r_t, r_k, r_du,
     r_dlam) = recorded
    r_s[i, position] = arclength
    r_stage[i, position] = stage_number
    r_u[i, position, 0] = y[0]
    r_u[i, position, 1] = y[1]
    r_lam[i, position] = y[2]
    for k in range(internal_count(kind)):
        r_internal[i, position, k] = y[3 + k]
    r_work[i, position] = y[state_size(kind, y) - 1]
    r_f[i, position, 0] = ev[4]
    r_f[i, position, 1] = ev[5]
    r_l[i, position] = ev[0]
    r_alpha[i, position] = angle(ev)
    r_n[i, position] = ev[2]
    r_t[i, position] = ev[3]
    r_k[i, position, 0, 0] = ev[6]
    r_k[i, position, 0, 1] = ev[7]
    r_k[i, position, 1, 0] = ev[8]
    r_k[i, position, 1, 1] = ev[9]
    r_du[i, position, 0] = aux[2]
    r_du[i, position, 1] = aux[3]
    r_dlam[i, position] = aux[4]


@njit
def store_event(kind, row, arclength, sigma, lower, upper, y, ev, geo):
    # the first occurrence of an event, one case
    row[0] = arclength + sigma
    row[1] = arclength + lower
    row[2] = arclength + upper
    row[3] = y[2]
    row[4] = y[0]
    row[5] = y[1]
    row[6] = ev[4]
    row[7] = ev[5]
    row[8] = ev[0]
    row[9] = angle(ev)
    row[10] = ev[2]
    row[11] = ev[3]
    row[12] = ev[6]
    row[13] = ev[7]
    row[14] = ev[8]
    row[15] = ev[9]
