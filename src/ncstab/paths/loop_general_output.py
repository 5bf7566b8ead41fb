"""What the shared parts of the compiled stage loop ask of a general model, beyond its tangent.

Its sizes and event columns (from the case's ``geo`` row), the contact state
after a switch (with the pure-shear limit's blocking), the event indicators
(:mod:`ncstab.paths.events`, a general layout: det K, the least eigenvalue of
K_sym, det M of the control, the flutter column without or with inertia, the
gaps and overlaps signed by the contact state, dlambda, the divergence and branch
tests, the end of a turn and the stage target), the domain check, the arc of an
over step, and what is stored (states, events, closed turns).  Its evaluation,
tangent and projection are in :mod:`ncstab.paths.loop_general` (imported here, so
that this module holds every function :mod:`ncstab.paths.loop_dispatch` asks for).
"""

from __future__ import annotations

import numpy as np

from ncstab.jit import hot, njit
from ncstab.operators.onset_cases import damped_onset, frequency_discriminant
from ncstab.operators.one_state import determinant, eigenvalue_discriminant, hill
from ncstab.paths.loop_general import (
    G_BIFURCATION, G_BLOCKING, G_COLUMNS, G_CONTROL, G_CYCLE, G_DAMPING, G_DIVERGENCE, G_DOMAIN, G_EVSIZE,
    G_FORCES, G_GAPCOL, G_GAPS, G_INTERACTIONS, G_LIMIT, G_MASS, G_N, G_NGAPS, G_NINT, G_NOPEN, G_NORMALCOL,
    G_OVERLAPS, G_ROW, G_SIZE, G_STIFFNESS, G_T, G_TARGET, G_TCOUNT, G_TSTRIDE, G_TURNING, control_system,
    displacement, evaluate,
)
from ncstab.paths.loop_general import (  # noqa: F401 (handed on: a general model's MODEL_FUNCTIONS)
    alignment, branch_size, motion, motion_product, no_tangent, project, rhs, rhs_hot, set_reference, tangent_at,
    was_flipped,
)
from ncstab.paths.loop_numerics import richardson_arc
from ncstab.paths.loop_records import MODEL_FUNCTIONS, EventColumns
from ncstab.paths.loop_signs import signed_gap, significant, target_indicator

__all__ = list(MODEL_FUNCTIONS)  # (those of loop_general it imports included)


@hot
def state_size(kind, y):
    return y.shape[0]


@njit
def ev_size(kind, geo):
    return geo[G_EVSIZE]


@njit
def aux_size(kind, geo):
    return 3 * geo[G_N] + 5


@njit
def motion_size(kind, geo):
    return 2 * geo[G_N] + 1


@njit
def event_columns(kind, geo):
    return EventColumns(
        geo[G_COLUMNS], geo[G_TARGET], geo[G_CYCLE], geo[G_TURNING], geo[G_BIFURCATION], geo[G_LIMIT], geo[G_CONTROL]
    )


@njit
def switch_bit(kind, geo, column):
    # IndicatorLayout.switch_bits: gap g is bit 2**g, normal contact j bit 2**(gaps + j)
    gap = column - geo[G_GAPCOL]
    if 0 <= gap < geo[G_NGAPS]:
        return 1 << gap
    normal = column - geo[G_NORMALCOL]
    if 0 <= normal < geo[G_NOPEN]:
        return 1 << (geo[G_NGAPS] + normal)
    return 0


@njit
def cuts_always(kind, geo, column):
    # the target, the end of a turn and a no_tension contact's switch cut a step
    normal = column - geo[G_NORMALCOL]
    return column == geo[G_TARGET] or column == geo[G_CYCLE] or 0 <= normal < geo[G_NOPEN]


@njit
def set_state(kind, p, geo, secondary):
    p[geo[G_ROW] + 1] = secondary


@njit
def tries_degenerate(kind, geo):
    # degenerate over steps from three dofs on (over_steps)
    return geo[G_N] >= 3


@njit
def stiffness_indicators(ev, fc, ctl, lam, geo, out):
    # the event indicators (events), the four columns built on K (operators.indicators: det K,
    # the least eigenvalue of K_sym, det M, the discriminant of K's characteristic
    # polynomial; NaN where K is not finite), values within rounding of zero unsigned
    n, at = geo[G_N], geo[G_STIFFNESS]
    stiffness = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            stiffness[i, j] = ev[at + i * n + j]
    matrix, _, _, _ = control_system(fc, ctl, lam, ev, geo)
    scale = np.nan
    finite = True
    for i in range(n):
        for j in range(n):
            for value in (stiffness[i, j], matrix[i, j]):
                a = abs(value)
                if not np.isnan(a) and not (a <= scale):  # nanmax
                    scale = a
    for i in range(n):
        for j in range(n):
            finite = finite and np.isfinite(stiffness[i, j])
    if not (np.isfinite(scale) and scale > 0):
        scale = 1.0
    square = scale * scale
    if finite:
        out[0] = significant(determinant(stiffness), square)  # operators.one_state, as the Dataset's
        out[1] = significant(hill(stiffness), scale)
    else:
        out[0] = out[1] = np.nan
    if geo[G_MASS] >= 0:  # M s^2 + C s + K (dynamics.flutter_onset_indicator)
        out[3] = dynamic_onset(ev, geo, stiffness)
    else:
        out[3] = significant(eigenvalue_discriminant(stiffness), square)
    control_finite = True
    for i in range(n):
        for j in range(n):
            control_finite = control_finite and np.isfinite(matrix[i, j])
    out[2] = significant(determinant(matrix), square) if control_finite else np.nan


@njit
def dynamic_onset(ev, geo, stiffness):
    # dynamics.flutter_onset_indicator: with C exactly 0 (or none), the frequencies'
    # discriminant; else the Hurwitz determinant Delta_{2n-1} (onset_cases.frequency_discriminant
    # and damped_onset)
    n, at = geo[G_N], geo[G_DAMPING]
    undamped = True
    damping = np.empty((n, n))
    if at >= 0:
        for i in range(n):
            for j in range(n):
                damping[i, j] = ev[at + i * n + j]
                undamped = undamped and damping[i, j] == 0.0
    mass = np.empty((n, n))
    for i in range(n):
        for j in range(n):
            mass[i, j] = ev[geo[G_MASS] + i * n + j]
    if undamped:
        return frequency_discriminant(mass, stiffness)
    return damped_onset(mass, damping, stiffness, np.empty(2 * n + 1), np.empty((2 * n - 1, 2 * n - 1)))


@njit
def indicators(kind, ev, aux, y, fc, ctl, geo, lam_end, target_sign, turn_end, secondary, out):
    # the event indicators (events) of a general layout without inertia; turn_end: 2 pi
    # (turns done + 1) in a cycle stage, else NaN
    n, lam = geo[G_N], y[geo[G_N]]
    for c in range(geo[G_COLUMNS]):  # (a layout's column the model has no value for: NaN)
        out[c] = np.nan
    stiffness_indicators(ev, fc, ctl, lam, geo, out)
    for g in range(geo[G_NGAPS]):
        out[geo[G_GAPCOL] + g] = signed_gap(ev[geo[G_GAPS] + g], secondary, 1 << g)
    out[geo[G_TURNING]] = aux[3 * n]
    for j in range(geo[G_NOPEN]):
        out[geo[G_NORMALCOL] + j] = signed_gap(ev[geo[G_OVERLAPS] + j], secondary, 1 << (geo[G_NGAPS] + j))
    # the dynamic divergence test: det M of the stage's control, for a system with inertia
    if geo[G_DIVERGENCE] >= 0:
        out[geo[G_DIVERGENCE]] = out[2] if geo[G_MASS] >= 0 else np.nan
    out[geo[G_BIFURCATION]] = aux[3 * n + 4]
    out[geo[G_CYCLE]] = lam - turn_end
    out[geo[G_TARGET]] = target_indicator(lam, lam_end, target_sign)


@njit
def state_indicator(kind, y, column, lam_end, target_sign, secondary, geo):
    # (True, value) for a column that is a function of y alone: the target
    if column == geo[G_TARGET]:
        return True, target_indicator(y[geo[G_N]], lam_end, target_sign)
    return False, np.nan


@njit
def domain_detail(kind, state, ev_state, geo):
    # the domain (domain_edge), one state: -1 inside the domain, else the index of the
    # reason in ModelBatch.domain_reasons (0 non-finite numbers; the kernel's code)
    finite = True
    for j in range(state.size):
        finite = finite and np.isfinite(state[j])
    for i in range(geo[G_N]):
        finite = finite and np.isfinite(ev_state[geo[G_FORCES] + i])
    if not finite:
        return 0
    return int(ev_state[geo[G_DOMAIN]])


@njit
def next_state(kind, geo, secondary, bit, y):
    # the contact state after a switch of ``bit`` (contacts).
    # Its bit toggles; in the pure-shear limit
    # a closing gap blocks the free chain -- the state becomes that gap, alpha is frozen
    # (the last internal variable) and v = (alpha, Nhat) becomes (Nhat, Rhat = 0) -- and
    # a blocked chain stays as it is
    if geo[G_BLOCKING] <= 0:
        return secondary ^ bit
    if secondary != 0:
        return secondary
    n = geo[G_N]
    y[n + geo[G_NINT]] = y[0]
    y[0] = y[1]
    y[1] = 0.0
    return bit


@njit
def arc_through(kind, y0, y_half, y_new, ev_new, ctl, law, p, geo, ev):
    # the arc (over_steps: exact to O(kappa^4 L^5)) through the start y0, the middle y_half (evaluated in
    # ev on entry) and the end y_new (ev_new), in (u, F, lambda); ev left at the start
    n, forces = geo[G_N], geo[G_FORCES]
    middle = np.empty(2 * n)  # F, then u, at the middle
    for i in range(n):
        middle[i] = ev[forces + i]
        middle[n + i] = displacement(y_half, ev, geo, i)
    evaluate(kind, y0, ctl, law, p, geo, ev)
    whole, first, second = 0.0, 0.0, 0.0
    for i in range(n):
        start, end = displacement(y0, ev, geo, i), displacement(y_new, ev_new, geo, i)
        whole += (end - start) ** 2
        first += (middle[n + i] - start) ** 2
        second += (end - middle[n + i]) ** 2
    for i in range(n):
        whole += (ev_new[forces + i] - ev[forces + i]) ** 2
        first += (middle[i] - ev[forces + i]) ** 2
        second += (ev_new[forces + i] - middle[i]) ** 2
    whole += (y_new[n] - y0[n]) ** 2
    first += (y_half[n] - y0[n]) ** 2
    second += (y_new[n] - y_half[n]) ** 2
    return richardson_arc(np.sqrt(whole), np.sqrt(first) + np.sqrt(second))


@njit
def turn_record(kind, y, ev, row, geo):
    # W, F and T (the first contact family's, per member) where a
    # turn closes
    n = geo[G_N]
    row[0] = y[y.size - 1]
    for i in range(n):
        row[1 + i] = ev[geo[G_FORCES] + i]
    for m in range(geo[G_TCOUNT]):
        row[1 + n + m] = ev[geo[G_T] + m * geo[G_TSTRIDE]] if geo[G_T] >= 0 else np.nan


@njit
def store_record(kind, recorded, i, position, arclength, stage_number, y, ev, aux, geo):
    # a stored state, into the recorder's padded arrays: (s, stage, u, lam,
    # internal, work, F, K, du, dlam) and the interactions' block of the kernel's row
    # (``recorded``, :meth:`ncstab.paths.compiled_stages.CompiledStages.recorded`)
    r_s, r_stage, r_u, r_lam, r_internal, r_work, r_f, r_k, r_du, r_dlam, r_interactions = recorded
    n, n_internal = geo[G_N], geo[G_NINT]
    r_s[i, position] = arclength
    r_stage[i, position] = stage_number
    for k in range(n):
        r_u[i, position, k] = displacement(y, ev, geo, k)
        r_f[i, position, k] = ev[geo[G_FORCES] + k]
        r_du[i, position, k] = aux[n + k]
        for j in range(n):
            r_k[i, position, k, j] = ev[geo[G_STIFFNESS] + k * n + j]
    r_lam[i, position] = y[n]
    for k in range(n_internal):
        r_internal[i, position, k] = y[n + 1 + k]
    r_work[i, position] = y[n + 1 + n_internal]
    r_dlam[i, position] = aux[3 * n]
    first = geo[G_INTERACTIONS]
    for k in range(geo[G_SIZE] - first):
        r_interactions[i, position, k] = ev[first + k]


@njit
def store_event(kind, row, arclength, sigma, lower, upper, y, ev, geo):
    # the first occurrence of an event, one case: s, its bracket, lambda, the
    # load parameter, u, F, K, then the interactions' block of the kernel's row
    n = geo[G_N]
    row[0] = arclength + sigma
    row[1] = arclength + lower
    row[2] = arclength + upper
    row[3] = y[n]
    row[4] = ev[geo[G_SIZE]]
    at = 5
    for k in range(n):
        row[at + k] = displacement(y, ev, geo, k)
    at += n
    for k in range(n):
        row[at + k] = ev[geo[G_FORCES] + k]
    at += n
    for k in range(n * n):
        row[at + k] = ev[geo[G_STIFFNESS] + k]
    at += n * n
    first = geo[G_INTERACTIONS]
    for k in range(geo[G_SIZE] - first):
        row[at + k] = ev[first + k]
