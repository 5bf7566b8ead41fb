"""Template, part 2 of 4, of the compiled stage loop: one DOP853 step and what follows it.

Pasted after :func:`ncstab.paths.loop_model.model_part` (see that module): the
DOP853 stage sums and error norm, the Newton projection onto equilibrium, the
dense output, event location by the Illinois iteration and the stored states
and events.  The parameters of :func:`steps_part` are the names it uses from
part 1 (it is never called).
"""

from __future__ import annotations

import numpy as np

from ncstab.paths.compiled import (
    _A,
    _B,
    _D,
    _E3,
    _E5,
    _EXTENDED,
    _N_COLUMNS,
    _POWER,
    _STAGES,
    _terms,
)
from ncstab.paths.events import (
    BIFURCATION_COLUMN,
    INDICATOR_EVENTS,
    INDICATOR_GAP,
    TARGET_COLUMN,
    TURNING_COLUMN,
)

__all__ = ["steps_part"]


def steps_part(
    rate_form, M, N_INT, angle, control, evaluate, gap, hot, indicators, njit, rhs, rhs_hot, signed_gap, tangent,
    target_indicator, tiny,
) -> None:
    """Define the step's helpers (a template: see the module docstring)."""
    A, B, E3, E5, D = _A, _B, _E3, _E5, _D
    A_TERMS, A_COUNT = _terms(_A, np.arange(_EXTENDED))
    B_TERMS, B_COUNT = _terms(_B[None, :], [_STAGES])
    E5_TERMS, E5_COUNT = _terms(_E5[None, :], [_STAGES + 1])
    E3_TERMS, E3_COUNT = _terms(_E3[None, :], [_STAGES + 1])
    D_TERMS, D_COUNT = _terms(_D, [_EXTENDED] * _D.shape[0])
    B_TERMS, B_COUNT, E5_TERMS, E5_COUNT = B_TERMS[0], B_COUNT[0], E5_TERMS[0], E5_COUNT[0]
    E3_TERMS, E3_COUNT = E3_TERMS[0], E3_COUNT[0]
    n_columns, target_column, turning_column = _N_COLUMNS, TARGET_COLUMN, TURNING_COLUMN  # noqa: F841 (n_columns: part 4)
    bifurcation_column, limit_column = BIFURCATION_COLUMN, INDICATOR_EVENTS.index("limit_point")
    gap_columns = (INDICATOR_GAP.index(1), INDICATOR_GAP.index(2))  # the two diagonals (ev[12], ev[13])

    @hot
    def combine(weights, terms, n_terms, stages, out):
        # integrator.combine_stages for every component: term by term in stage order,
        # the first term and the non-zero weights after it (terms: their stage indices).
        # One accumulator per component (m is 4 or 5, fixed per law), side by side.
        w = weights[0]
        a0, a1, a2, a3 = w * stages[0, 0], w * stages[0, 1], w * stages[0, 2], w * stages[0, 3]
        a4 = w * stages[0, 4] if M == 5 else 0.0
        for t in range(1, n_terms):
            k = terms[t]
            w = weights[k]
            a0 += w * stages[k, 0]
            a1 += w * stages[k, 1]
            a2 += w * stages[k, 2]
            a3 += w * stages[k, 3]
            if M == 5:
                a4 += w * stages[k, 4]
        out[0], out[1], out[2], out[3] = a0, a1, a2, a3
        if M == 5:
            out[4] = a4

    @njit
    def error_norm(y0, y1, h, rtol, atol, stages, work):
        # integrator.dop853_step's error norm (integrator.error_norm); inf where y1 or the
        # norm is not finite
        sums, sums3 = work[1], work[2]
        err5_sq = 0.0
        err3_sq = 0.0
        finite = True
        combine(E5, E5_TERMS, E5_COUNT, stages, sums)
        combine(E3, E3_TERMS, E3_COUNT, stages, sums3)
        for j in range(M):
            scale = atol + max_nan(abs(y0[j]), abs(y1[j])) * rtol
            e5 = sums[j] / scale
            e3 = sums3[j] / scale
            err5_sq += e5 * e5
            err3_sq += e3 * e3
            finite = finite and np.isfinite(y1[j])
        denominator = err5_sq + 0.01 * err3_sq
        err = abs(h) * err5_sq / np.sqrt(denominator * M) if denominator > 0 else 0.0
        if not (finite and np.isfinite(err)):
            err = np.inf
        return err

    @njit
    def max_nan(a, b):
        # np.maximum: NaN if either is NaN
        if np.isnan(a) or np.isnan(b):
            return np.nan
        return max(a, b)

    @njit
    def residual(ev, y, fc0, fc1, g0, g1):
        # StageArrays.residual: P u + Q F - g(lambda), max norm; returns (r0, r1, size)
        r0 = (ev[4] if fc0 else y[0]) - g0
        r1 = (ev[5] if fc1 else y[1]) - g1
        a0, a1 = abs(r0), abs(r1)
        size = np.nan if (np.isnan(a0) or np.isnan(a1)) else max(a0, a1)
        return r0, r1, size

    @njit
    def project(y, fc0, fc1, ctl, law, p, cos0, sin0, newton_tol, newton_max_iter, ev):
        # projection.project + _correction_2, one case; ev left at the final state
        for _ in range(newton_max_iter + 1):
            evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
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
            y[3 + N_INT] += 0.5 * (ev[4] * du0 + ev[5] * du1)
        evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
        return False

    @njit
    def dense_coefficients(y0, y_raw, h, fc0, fc1, ctl, orient, law, p, cos0, sin0, stages,
                           coefficients, work, ev, aux):
        # integrator.dense_output (the three extra stages, unprojected)
        m = y0.size
        state, sums = work[0], work[1]
        for s in range(_STAGES + 1, _EXTENDED):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(m):
                state[j] = y0[j] + sums[j] * h
            rhs(state, fc0, fc1, ctl, orient, law, p, cos0, sin0, stages[s], ev, aux)
        for j in range(m):
            delta = y_raw[j] - y0[j]
            f_old, f_new = stages[0, j], stages[_STAGES, j]
            coefficients[0, j] = delta
            coefficients[1, j] = h * f_old - delta
            coefficients[2, j] = 2 * delta - h * (f_new + f_old)
        for k in range(_POWER - 3):
            combine(D[k], D_TERMS[k], D_COUNT[k], stages, sums)
            for j in range(m):
                coefficients[3 + k, j] = h * sums[j]

    @njit
    def dense_value(y0, coefficients, fraction, out):
        # integrator.evaluate_dense (scipy's Horner form)
        for j in range(y0.size):
            value = 0.0
            for i in range(_POWER):
                value += coefficients[_POWER - 1 - i, j]
                value *= fraction if i % 2 == 0 else 1 - fraction
            out[j] = value + y0[j]

    @njit
    def indicator_at(y, column, fc0, fc1, ctl, lam_end, target_sign, turn_end, orient, secondary, law, p,
                     cos0, sin0, newton_tol, newton_max_iter, ev, aux, values):
        # crossings.locate_crossings.evaluate: project (total form), evaluate, one column.
        # Without a projection the target and the gaps are functions of y alone: the
        # same operations without the law (bit for bit).
        if rate_form and column == target_column:
            return target_indicator(y[2], lam_end, target_sign)
        if rate_form and column == gap_columns[0]:
            return signed_gap(gap(cos0 - y[0]), secondary, 1)
        if rate_form and column == gap_columns[1]:
            return signed_gap(gap(sin0 - y[1]), secondary, 2)
        if not rate_form:
            project(y, fc0, fc1, ctl, law, p, cos0, sin0, newton_tol, newton_max_iter, ev)
        else:
            evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
        if column == turning_column or column == bifurcation_column:
            _, _, g0, g1 = control(y[2], ctl)
            tangent(ev, fc0, fc1, g0, g1, orient, aux)
        else:
            aux[4] = np.nan
            aux[10] = np.nan
        indicators(ev, aux, y[2], fc0, fc1, lam_end, target_sign, turn_end, secondary, values)
        return values[column]

    @njit
    def sign(x):
        if x > 0:
            return 1.0
        if x < 0:
            return -1.0
        return x  # 0 or NaN

    @njit
    def locate(column, h, offset, span, phi0, phi1, y0, coefficients, fc0, fc1, ctl, lam_end, target_sign,
               turn_end, orient, secondary, law, p, cos0, sin0, newton_tol, newton_max_iter, event_tol,
               ev, aux, values, state):
        # events.locate_sign_changes, one pair: returns (sigma, lower, upper) in the piece
        # (offset, offset + span) of the step of length h; state at sigma
        lower, upper = 0.0, span
        f_lower, f_upper = phi0, phi1
        side = 0
        sigma = np.nan
        last_width = upper - lower
        for iteration in range(200):
            width = upper - lower
            candidate = (lower * f_upper - upper * f_lower) / (f_upper - f_lower)
            bisect = not np.isfinite(candidate) or candidate <= lower or candidate >= upper
            if iteration % 5 == 4:
                bisect = bisect or width > 0.5 * last_width
                last_width = width
            if bisect:
                candidate = 0.5 * (lower + upper)
            dense_value(y0, coefficients, (offset + candidate) / h, state)
            value = indicator_at(state, column, fc0, fc1, ctl, lam_end, target_sign, turn_end, orient,
                                 secondary, law, p, cos0, sin0, newton_tol, newton_max_iter, ev, aux, values)
            sigma = candidate
            a_side = sign(value) == sign(f_lower)
            b_side = sign(value) == sign(f_upper)
            exact = abs(value) <= tiny or not np.isfinite(value)
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
            if upper - lower <= event_tol or exact:
                break
        return sigma, lower, upper

    @njit
    def store_record(recorded, i, position, arclength, stage_number, y, ev, aux):
        # stepper.BatchStepper.record, straight into the recorder's padded arrays
        # (``recorded``: one array per field, in the order of BatchStepper.record_fields())
        (r_s, r_stage, r_u, r_lam, r_internal, r_work, r_f, r_l, r_alpha, r_n, r_t, r_k, r_du,
         r_dlam) = recorded
        r_s[i, position] = arclength
        r_stage[i, position] = stage_number
        r_u[i, position, 0] = y[0]
        r_u[i, position, 1] = y[1]
        r_lam[i, position] = y[2]
        for k in range(M - 4):
            r_internal[i, position, k] = y[3 + k]
        r_work[i, position] = y[M - 1]
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
    def store_event(row, arclength, sigma, lower, upper, y, ev):
        # crossings.store_first_events, one event of one case
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

    @njit
    def first_column(columns, sigma):
        # crossings.store_first_events: of an event's columns (-1: none), the one crossed first
        best, best_column = np.inf, -1
        for c in columns:
            if c >= 0 and (best_column < 0 or sigma[c] < best):
                best, best_column = sigma[c], c
        return best_column

    @njit
    def drop_limit_at_bifurcation(sigma, span):
        # cut_points.drop_limit_points_at_bifurcations: a zero of det K where the branch test
        # changes sign too (within 1e-6 of the piece) is a simple bifurcation point
        if np.isfinite(sigma[bifurcation_column]) and abs(sigma[limit_column] - sigma[bifurcation_column]) <= 1e-6 * span:
            sigma[limit_column] = np.inf

    @njit
    def piece_count(h, sample_step, max_pieces):
        # options.PathOptions.pieces: ceil(h / sample_step), between 1 and max_pieces
        if not (h > sample_step):
            return 1
        return min(int(np.ceil(h / sample_step)), max_pieces)

    @njit
    def initial_step_size(y0, f0, f1, probe, rtol, atol):
        # integrator.initial_step_size, one case (np.mean over m: a sum in order, then / m)
        s1 = 0.0
        s2 = 0.0
        for j in range(M):
            scale = atol + abs(y0[j]) * rtol
            a = f0[j] / scale
            b = (f1[j] - f0[j]) / scale
            s1 += a * a
            s2 += b * b
        d1 = np.sqrt(s1 / M)
        d2 = np.sqrt(s2 / M) / probe
        largest = np.nan if (np.isnan(d1) or np.isnan(d2)) else max(d1, d2)
        if not np.isfinite(largest):
            return probe
        if largest <= 1e-15:
            return min(100 * probe, max(1e-6, 1e-3 * probe))
        return min(100 * probe, np.sqrt(np.sqrt(np.sqrt(0.01 / largest))))

    @njit
    def dop853(y0, f0, h, rtol, atol, fc0, fc1, ctl, orient, law, p, cos0, sin0, stages, y1, work, ev,
               aux):
        # integrator.dop853_step; leaves ev, aux at the end state y1 (its last stage)
        state, sums = work[0], work[1]
        for j in range(M):
            stages[0, j] = f0[j]
        for s in range(1, _STAGES):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(M):
                state[j] = y0[j] + sums[j] * h
            rhs_hot(state, fc0, fc1, ctl, orient, law, p, cos0, sin0, stages[s], ev, aux)
        combine(B, B_TERMS, B_COUNT, stages, sums)
        for j in range(M):
            y1[j] = y0[j] + h * sums[j]
        rhs_hot(y1, fc0, fc1, ctl, orient, law, p, cos0, sin0, stages[_STAGES], ev, aux)
        return error_norm(y0, y1, h, rtol, atol, stages, work)
