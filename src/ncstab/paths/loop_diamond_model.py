"""The reduced diamond as the compiled stage loop sees it: its evaluation, tangent and indicators.

The law's kernel (the argument ``law``, a C callback of
:data:`ncstab.paths.compiled.LAW_SIGNATURE`) at a state, the cofactor tangent of
the constrained rate system, dy/ds and the event indicators (seed Eq. 4, 30-34;
every helper cites the numpy function it follows operation for operation).
:mod:`ncstab.paths.loop_diamond` answers the rest of what the shared parts of
the loop ask of a model (:mod:`ncstab.paths.loop_dispatch`).  The first argument
of each function the shared parts call is the model's record
(:class:`ncstab.paths.loop_records.DiamondModel`): whether its law has a rate
form (then T is an internal variable, y = (v0, v1, lambda, T, W); else
y = (v0, v1, lambda, W)).
"""

from __future__ import annotations

import math

import numpy as np

from ncstab.jit import hot, njit
from ncstab.operators.one_state import determinant_2, discriminant_2, hill_2
from ncstab.paths.compiled import ACTIVATE_SLOT, ALPHA_SLOT, KAPPA_SLOT, STATE_SLOT
from ncstab.paths.loop_signs import signed_gap, significant, target_indicator

__all__ = [
    "alignment", "angle", "branch_size", "control", "evaluate", "gap", "indicators", "internal_count", "motion",
    "motion_product", "rhs", "rhs_hot", "tangent",
]

# The case's row p: kappa, whether the secondary springs act, the contact-state
# bits, whether the law reads alpha, then the law's parameters (KAPPA_SLOT, ...).
kappa_slot, activate_slot, state_slot, alpha_slot = KAPPA_SLOT, ACTIVATE_SLOT, STATE_SLOT, ALPHA_SLOT


@hot
def internal_count(kind):
    # the internal variables: T for a rate form (one contact family)
    return 1 if kind.rate_form else 0


@hot
def evaluate(kind, y, ctl, law, p, geo, ev):
    # model.CaseBatch._evaluate_fused: ev = (l, alpha, N, T, F0, F1, K00, K01, K10, K11,
    # dT/dD1, dT/dD2, gap0, gap1, vertical, horizontal, delta); alpha only where the law
    # reads it (else NaN here, see angle()); the law writes ev[2:12] (its branch: the
    # normal contact's bit of the contact state) and delta, its normal overlap (NaN
    # unless it is a no_tension law); geo = (cos alpha0, sin alpha0)
    t_in = y[3] if kind.rate_form else 0.0
    vertical = geo[0] - y[0]
    horizontal = geo[1] - y[1]
    length = np.sqrt(vertical * vertical + horizontal * horizontal)
    alpha = math.atan2(horizontal, vertical) if p[alpha_slot] > 0 else np.nan
    law(length, alpha, vertical / length, horizontal / length, t_in, p.ctypes, ev.ctypes)  # ev[2:12], ev[16]
    ev[0] = length
    ev[1] = alpha
    ev[14] = vertical
    ev[15] = horizontal
    if not kind.rate_form:
        ev[10] = np.nan
        ev[11] = np.nan
    ev[12] = gap(vertical)
    ev[13] = gap(horizontal)
    if p[activate_slot] > 0:
        # model.CaseBatch._evaluate_fused: the secondary-contact springs whose bit is set
        kappa, state = p[kappa_slot], int(p[state_slot])
        ev[4] += kappa * ((1.0 - 2.0 * vertical) if (state & 1) > 0 else 0.0)
        ev[6] += 2.0 * kappa * (1.0 if (state & 1) > 0 else 0.0)
        ev[5] += kappa * ((1.0 - 2.0 * horizontal) if (state & 2) > 0 else 0.0)
        ev[9] += 2.0 * kappa * (1.0 if (state & 2) > 0 else 0.0)


@njit
def gap(extent):
    # the secondary-contact gap along one diagonal (model: 2 (cos alpha0 - Delta_1) - 1, ...)
    return extent * 2 - 1


@njit
def angle(ev):
    # alpha = arctan2(horizontal, vertical), computed once where the law did not need it
    if np.isnan(ev[1]):  # evaluate() leaves it NaN where the law does not read it
        ev[1] = math.atan2(ev[15], ev[14])
    return ev[1]


@hot
def tangent(ev, fc0, fc1, g0, g1, orient, aux):
    # the path tangent (tangent_field, n = 2) with du/dv = I, dF/dv = K, oriented by continuity:
    # orient = (the stage's orientation, the reference: the motion (du, dF, dlambda) at
    # the start of the step, NaN for none); aux = (dv0, dv1, du0, du1, dlam, det_m, dF0,
    # dF1, |c| the cofactor vector's size, 1.0 where flipped, the branch test), the tangent
    # flipped where its motion (du, dF, dlam) reverses the reference
    k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
    m00 = k00 if fc0 else 1.0
    m01 = k01 if fc0 else 0.0
    m10 = k10 if fc1 else 0.0
    m11 = k11 if fc1 else 1.0
    det_m = m00 * m11 - m01 * m10
    dv0 = m11 * g0 - m01 * g1
    dv1 = m00 * g1 - m10 * g0
    du0 = 1.0 * dv0 + 0.0 * dv1
    du1 = 0.0 * dv0 + 1.0 * dv1
    df0 = k00 * dv0 + k01 * dv1
    df1 = k10 * dv0 + k11 * dv1
    norm = np.sqrt((du0 * du0 + du1 * du1) + (df0 * df0 + df1 * df1) + det_m * det_m)
    # (1 / norm) * orientation, as one division: orientation is +-1, so the
    # same number (one rounding), one operation shorter on the critical path
    scale = orient[0] / norm if norm > 0 else np.nan
    m0, m1, m2, m3, m4 = du0 * scale, du1 * scale, df0 * scale, df1 * scale, det_m * scale
    # orientation by continuity: flipped where the sum over the five, in order,
    # over the reference's norm is negative: where the sum is, the reference being
    # finite (a unit motion) and not zero; NaN (no reference) flips nothing
    dot = m0 * orient[1] + m1 * orient[2] + m2 * orient[3] + m3 * orient[4] + m4 * orient[5]
    aux[8] = norm
    # the branch test (tangent_field): the cosine with the reference (1 without
    # one) times |c|; it changes sign where c passes through zero (events: bifurcation)
    square = orient[1] * orient[1] + orient[2] * orient[2] + orient[3] * orient[3]
    product = dot / np.sqrt(square + orient[4] * orient[4] + orient[5] * orient[5])
    aux[10] = (product if np.isfinite(product) else 1.0) * norm
    if dot < 0:
        aux[0] = -(dv0 * scale)
        aux[1] = -(dv1 * scale)
        m0, m1, m2, m3, m4 = -m0, -m1, -m2, -m3, -m4
        aux[9] = 1.0
    else:
        aux[0] = dv0 * scale
        aux[1] = dv1 * scale
        aux[9] = 0.0
    aux[2] = m0
    aux[3] = m1
    aux[4] = m4
    aux[5] = det_m
    aux[6] = m2
    aux[7] = m3


@hot
def control(lam, ctl):
    # StageArrays.control_path, one case: (g0, g1, g0', g1') at lambda; ctl = (is_cycle,
    # offset0, offset1, slope0, slope1, center0, center1, radius, theta0, turn_direction),
    # a cycle's plane being both dofs of the diamond
    if ctl[0] > 0:
        angle = ctl[8] + ctl[9] * lam
        cos, sin = math.cos(angle), math.sin(angle)
        rate = ctl[7] * ctl[9]
        return ctl[5] + ctl[7] * cos, ctl[6] + ctl[7] * sin, rate * -sin, rate * cos
    return ctl[1] + ctl[3] * lam, ctl[2] + ctl[4] * lam, ctl[3], ctl[4]


def rhs_py(kind, y, fc, ctl, orient, law, p, geo, dy, ev, aux):
    # dy/ds (rhs) = (dv, dlambda, dinternal, dW)
    evaluate(kind, y, ctl, law, p, geo, ev)
    _, _, g0, g1 = control(y[2], ctl)
    tangent(ev, fc[0], fc[1], g0, g1, orient, aux)
    dy[0] = aux[0]
    dy[1] = aux[1]
    dy[2] = aux[4]
    n_int = internal_count(kind)
    if n_int:
        dy[3] = ev[10] * aux[0] + ev[11] * aux[1]
    dy[3 + n_int] = 0.5 * (ev[4] * aux[2] + ev[5] * aux[3])


# Inlined where every step evaluates it (the DOP853 stages), called elsewhere:
# inlining it everywhere costs seconds of compilation for no measurable gain.
rhs_hot = hot(rhs_py)
rhs = njit(rhs_py)


@njit
def alignment(kind, aux, orient):
    # the cosine of the (continued) motion in aux with the reference in orient[1:6]
    # (over_steps: sum(motion * reference) / sqrt(sum(reference * reference)), in order)
    dot = aux[2] * orient[1] + aux[3] * orient[2] + aux[6] * orient[3] + aux[7] * orient[4] + aux[4] * orient[5]
    square = orient[1] * orient[1] + orient[2] * orient[2] + orient[3] * orient[3]
    square += orient[4] * orient[4] + orient[5] * orient[5]
    return dot / np.sqrt(square)


@njit
def branch_size(kind, aux, orient):
    # |the branch test| (tangent_field): |the cosine| times |c|, or
    # |c| where there is no reference; the next over step's length reads it (over_steps)
    product = alignment(kind, aux, orient)
    return abs(product if np.isfinite(product) else 1.0) * aux[8]


@njit
def motion(kind, ev, aux, out):
    # the motion (du, dF = K dv, dlambda) of the tangent in aux
    out[0] = aux[2]
    out[1] = aux[3]
    out[2] = ev[6] * aux[0] + ev[7] * aux[1]
    out[3] = ev[8] * aux[0] + ev[9] * aux[1]
    out[4] = aux[4]


@njit
def motion_product(kind, before, ev, aux):
    # the sum over (du, dF, dlambda) of motion(after) * motion(before), in order
    total = aux[2] * before[0]
    total += aux[3] * before[1]
    total += (ev[6] * aux[0] + ev[7] * aux[1]) * before[2]
    total += (ev[8] * aux[0] + ev[9] * aux[1]) * before[3]
    total += aux[4] * before[4]
    return total


@njit
def indicators(kind, ev, aux, y, fc, ctl, geo, lam_end, target_sign, turn_end, secondary, out):
    # the event indicators (events); turn_end: 2 pi (turns done + 1) in a cycle stage, else NaN
    lam, fc0, fc1 = y[2], fc[0], fc[1]
    k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
    m00 = k00 if fc0 else 1.0
    m01 = k01 if fc0 else 0.0
    m10 = k10 if fc1 else 0.0
    m11 = k11 if fc1 else 1.0
    scale = np.nan
    for value in (k00, k01, k10, k11, m00, m01, m10, m11):
        a = abs(value)
        if not np.isnan(a) and not (a <= scale):  # nanmax
            scale = a
    if not (np.isfinite(scale) and scale > 0):
        scale = 1.0
    square = scale * scale
    # operators.one_state: the Dataset's indicators, the same functions
    out[0] = significant(determinant_2(k00, k01, k10, k11), square)
    out[1] = significant(hill_2(k00, k01, k10, k11), scale)
    out[2] = significant(determinant_2(m00, m01, m10, m11), square)
    out[3] = significant(discriminant_2(k00, k01, k10, k11), square)
    out[4] = signed_gap(ev[12], secondary, 1)
    out[5] = signed_gap(ev[13], secondary, 2)
    out[6] = aux[4]
    out[7] = signed_gap(ev[16], secondary, 4)  # a no_tension law's normal overlap (NaN otherwise)
    out[8] = aux[10]  # the branch test (NaN where the tangent was not evaluated)
    out[9] = lam - turn_end  # the end of the current turn (NaN outside a cycle stage)
    out[10] = target_indicator(lam, lam_end, target_sign)
