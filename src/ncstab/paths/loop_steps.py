"""Template, part 2 of 4, of the compiled stage loop: one DOP853 step and what follows it.

Pasted after :func:`ncstab.paths.loop_model.model_part` (see that module): the
DOP853 stage sums and error norm, the Newton projection onto equilibrium, the
dense output, event location by the Illinois iteration and the stored states
and events.  The parameters of :func:`steps_part` are the names it uses from
part 1 (it is never called).
"""

from __future__ import annotations

import numpy as np

from ncstab.paths.compiled import _A, _B, _D, _E3, _E5, _EXTENDED, _POWER, _STAGES, _terms

__all__ = ["steps_part"]


def steps_part(
    rate_form, bifurcation_col, evaluate, hot, indicators, limit_col, njit, no_tangent, project, rhs, rhs_hot,
    state_indicator, state_size, tangent_at, tiny, turning_col,
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

    @hot
    def combine(weights, terms, n_terms, stages, out):
        # sum_k w_k stages[k] for every component: term by term in stage order,
        # the first term and the non-zero weights after it (terms: their stage indices)
        m = state_size(out)
        w = weights[0]
        for j in range(m):
            out[j] = w * stages[0, j]
        for t in range(1, n_terms):
            k = terms[t]
            w = weights[k]
            for j in range(m):
                out[j] += w * stages[k, j]

    @njit
    def error_norm(y0, y1, h, rtol, atol, stages, work):
        # DOP853's error norm (scipy's _estimate_error_norm); inf where y1 or the
        # norm is not finite
        sums, sums3 = work[1], work[2]
        m = state_size(y0)
        err5_sq = 0.0
        err3_sq = 0.0
        finite = True
        combine(E5, E5_TERMS, E5_COUNT, stages, sums)
        combine(E3, E3_TERMS, E3_COUNT, stages, sums3)
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
    def max_nan(a, b):
        # np.maximum: NaN if either is NaN
        if np.isnan(a) or np.isnan(b):
            return np.nan
        return max(a, b)

    @njit
    def dense_coefficients(y0, y_raw, h, case, stages, coefficients, work, ev, aux):
        # DOP853's dense output (scipy's: the three extra stages, unprojected)
        fc, ctl, orient, law, p, geo = case
        m = y0.size
        state, sums = work[0], work[1]
        for s in range(_STAGES + 1, _EXTENDED):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(m):
                state[j] = y0[j] + sums[j] * h
            rhs(state, fc, ctl, orient, law, p, geo, stages[s], ev, aux)
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
        # the dense output at a fraction (scipy's Horner form)
        for j in range(y0.size):
            value = 0.0
            for i in range(_POWER):
                value += coefficients[_POWER - 1 - i, j]
                value *= fraction if i % 2 == 0 else 1 - fraction
            out[j] = value + y0[j]

    @njit
    def indicator_at(y, column, case, goal, settings, ev, aux, values):
        # an indicator inside a piece: project (total form), evaluate, one column.
        # Without a projection, a column that is a function of y alone (the target, the
        # diamond's gaps) takes the same operations without the law (bit for bit).
        fc, ctl, orient, law, p, geo = case
        lam_end, target_sign, turn_end, secondary = goal
        newton_tol, newton_max_iter = settings.newton_tol, settings.newton_max_iter
        if rate_form:
            known, value = state_indicator(y, column, lam_end, target_sign, secondary, geo)
            if known:
                return value
        if not rate_form:
            project(y, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev)
        else:
            evaluate(y, ctl, law, p, geo, ev)
        if column == turning_col(geo) or column == bifurcation_col(geo):
            tangent_at(y, fc, ctl, orient, ev, aux, geo)
        else:
            no_tangent(aux)
        indicators(ev, aux, y, fc, ctl, geo, lam_end, target_sign, turn_end, secondary, values)
        return values[column]

    @njit
    def sign(x):
        if x > 0:
            return 1.0
        if x < 0:
            return -1.0
        return x  # 0 or NaN

    @njit
    def locate(column, offset, span, phi0, phi1, interpolant, case, goal, settings, evaluation, values, state):
        # a sign change located by the Illinois iteration (events), one pair: returns (sigma, lower, upper) in the piece
        # (offset, offset + span) of the step (its interpolant); state at sigma
        y0, coefficients, h = interpolant
        ev, aux = evaluation
        event_tol = settings.event_tol
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
            value = indicator_at(state, column, case, goal, settings, ev, aux, values)
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
    def first_column(columns, sigma):
        # of an event's columns (-1: none), the one crossed first
        best, best_column = np.inf, -1
        for c in columns:
            if c >= 0 and (best_column < 0 or sigma[c] < best):
                best, best_column = sigma[c], c
        return best_column

    @njit
    def drop_limit_at_bifurcation(sigma, span, geo):
        # a zero of det K where the branch test
        # changes sign too (within 1e-6 of the piece) is a simple bifurcation point
        bifurcation, limit = bifurcation_col(geo), limit_col(geo)
        if bifurcation >= 0 and np.isfinite(sigma[bifurcation]) and abs(sigma[limit] - sigma[bifurcation]) <= 1e-6 * span:
            sigma[limit] = np.inf

    @njit
    def piece_count(h, sample_step, max_pieces):
        # PathOptions.pieces: ceil(h / sample_step), between 1 and max_pieces
        if not (h > sample_step):
            return 1
        return min(int(np.ceil(h / sample_step)), max_pieces)

    @njit
    def initial_step_size(y0, f0, f1, probe, rtol, atol):
        # Hairer's starting step (scipy's select_initial_step with a probe step), one case
        m = state_size(y0)
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

    @njit
    def dop853(y0, f0, h, case, settings, stages, y1, work, ev, aux):
        # one DOP853 step (scipy's tableau); leaves ev, aux at the end state y1 (its last stage)
        fc, ctl, orient, law, p, geo = case
        m = state_size(y0)
        state, sums = work[0], work[1]
        for j in range(m):
            stages[0, j] = f0[j]
        for s in range(1, _STAGES):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(m):
                state[j] = y0[j] + sums[j] * h
            rhs_hot(state, fc, ctl, orient, law, p, geo, stages[s], ev, aux)
        combine(B, B_TERMS, B_COUNT, stages, sums)
        for j in range(m):
            y1[j] = y0[j] + h * sums[j]
        rhs_hot(y1, fc, ctl, orient, law, p, geo, stages[_STAGES], ev, aux)
        return error_norm(y0, y1, h, settings.rtol, settings.atol, stages, work)
