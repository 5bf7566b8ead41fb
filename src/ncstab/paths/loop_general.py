"""Template, part 1 for a general model, of the compiled stage loop: the model as the loop sees it.

The body of :func:`general_part` takes the place of the diamond's parts 1 and 1b
(:mod:`ncstab.paths.loop_model`, :mod:`ncstab.paths.loop_diamond`) in the stage
loop of a general model (any :class:`~ncstab.systems.SystemDefinition` of three
dofs or more; :func:`ncstab.paths.compiled_source.general_loop_source`): the
shared parts (:mod:`ncstab.paths.loop_steps`, :mod:`~ncstab.paths.loop_step_limits`,
:mod:`~ncstab.paths.loop_cases`) follow it unchanged.  One loop per form of law
serves every general model: the sizes are the case's ``geo`` row (:data:`GEO`),
and the model is its compiled kernel's C callback (``law``,
:meth:`ncstab.operators.model_kernel.ModelKernel.callback`), which writes a row of
:class:`~ncstab.operators.model_kernel_source.KernelLayout` (F, K, dF/dP,
d(internal)/du, gaps, overlaps, the domain code, the interactions).

The cofactor tangent and the Newton correction are those of the numpy
stepper for n > 2 dofs, one implementation: :func:`ncstab.paths.cofactor.cofactor_vector`
and :func:`~ncstab.paths.cofactor.minimum_norm_step`, pasted into the module
(tangent_field.path_tangent, projection.project; seed Eq. 30-34).  The
indicators are events.indicator_values of a general layout without inertia.
"""

from __future__ import annotations

from typing import Any

import numba
import numpy as np

from ncstab.paths.events import SIGN_NOISE, TINY

__all__ = ["GEO", "general_part"]

#: Slots of a general model's ``geo`` row (int64, the same for every case of a batch):
#: the kernel's layout, the loop's buffer sizes and the event columns
#: (:class:`ncstab.paths.compiled_stages.CompiledStages`).
GEO = {name: slot for slot, name in enumerate((
    "n", "n_internal", "size", "scratch", "forces", "stiffness", "load", "gradient", "gaps", "n_gaps", "overlaps",
    "n_open", "domain", "interactions", "has_load", "columns", "target", "cycle", "turning", "bifurcation", "limit",
    "control", "divergence", "gap_column", "normal_column", "row", "ev_size", "mass",
))}


def general_part(rate_form: bool, cofactor_vector: Any, minimum_norm_step: Any) -> None:
    """Define the general model's helpers (a template: see the module docstring).

    Parameters
    ----------
    rate_form
        Whether some law of the model has no total form (no Newton projection).
    cofactor_vector, minimum_norm_step
        :mod:`ncstab.paths.cofactor`'s, pasted after this part.
    """
    njit = numba.njit(cache=False, error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
    hot = numba.njit(cache=False, error_model="numpy", inline="always")
    sign_noise, tiny = SIGN_NOISE, TINY
    G_N, G_NINT, G_SIZE, G_SCRATCH = GEO["n"], GEO["n_internal"], GEO["size"], GEO["scratch"]
    G_FORCES, G_STIFFNESS, G_LOAD, G_GRADIENT = GEO["forces"], GEO["stiffness"], GEO["load"], GEO["gradient"]
    G_GAPS, G_NGAPS, G_OVERLAPS, G_NOPEN = GEO["gaps"], GEO["n_gaps"], GEO["overlaps"], GEO["n_open"]
    G_DOMAIN, G_INTERACTIONS, G_HASLOAD, G_COLUMNS = GEO["domain"], GEO["interactions"], GEO["has_load"], GEO["columns"]
    G_TARGET, G_CYCLE, G_TURNING, G_BIFURCATION = GEO["target"], GEO["cycle"], GEO["turning"], GEO["bifurcation"]
    G_LIMIT, G_CONTROL, G_DIVERGENCE = GEO["limit"], GEO["control"], GEO["divergence"]
    G_GAPCOL, G_NORMALCOL, G_ROW, G_EVSIZE = GEO["gap_column"], GEO["normal_column"], GEO["row"], GEO["ev_size"]
    G_MASS = GEO["mass"]  # the offset of M(u) in the kernel's row, -1 for a system without inertia
    # The case's p row: the kernel's parameter row (ROW entries), the work factor, then
    # the contact-state bits.  ctl: is_cycle, load offset, load slope, then g's offset
    # and slope (n each).  ev: the kernel's row, the load parameter, the kernel's
    # scratch, then the tangent's (control matrix, rate, cofactor vector, QR work).
    # aux: dv, du, dF (n each), dlambda, det M, |c|, 1.0 where flipped, the branch test.

    @hot
    def state_size(y):
        return y.shape[0]

    @njit
    def ev_size(geo):
        return geo[G_EVSIZE]

    @njit
    def aux_size(geo):
        return 3 * geo[G_N] + 5

    @njit
    def motion_size(geo):
        return 2 * geo[G_N] + 1

    @njit
    def column_count(geo):
        return geo[G_COLUMNS]

    @njit
    def target_col(geo):
        return geo[G_TARGET]

    @njit
    def cycle_col(geo):
        return geo[G_CYCLE]

    @njit
    def turning_col(geo):
        return geo[G_TURNING]

    @njit
    def bifurcation_col(geo):
        return geo[G_BIFURCATION]

    @njit
    def limit_col(geo):
        return geo[G_LIMIT]

    @njit
    def control_col(geo):
        return geo[G_CONTROL]

    @njit
    def switch_bit(geo, column):
        # IndicatorLayout.switch_bits: gap g is bit 2**g, normal contact j bit 2**(gaps + j)
        gap = column - geo[G_GAPCOL]
        if 0 <= gap < geo[G_NGAPS]:
            return 1 << gap
        normal = column - geo[G_NORMALCOL]
        if 0 <= normal < geo[G_NOPEN]:
            return 1 << (geo[G_NGAPS] + normal)
        return 0

    @njit
    def cuts_always(geo, column):
        # the target, the end of a turn and a no_tension contact's switch cut a step
        normal = column - geo[G_NORMALCOL]
        return column == geo[G_TARGET] or column == geo[G_CYCLE] or 0 <= normal < geo[G_NOPEN]

    @njit
    def set_state(p, geo, secondary):
        p[geo[G_ROW] + 1] = secondary

    @njit
    def tries_degenerate(geo):
        # over_steps.plan_over_steps: degenerate over steps from three dofs on
        return geo[G_N] >= 3

    @hot
    def evaluate(y, ctl, law, p, geo, ev):
        # rhs.evaluate_at + ModelBatch.evaluate: the kernel's row at y (the load parameter
        # from lambda where the system has one), the load parameter after it
        n, size = geo[G_N], geo[G_SIZE]
        load = ctl[1] + ctl[2] * y[n] if geo[G_HASLOAD] > 0 else 0.0
        law(y.ctypes, y[n + 1:].ctypes, load, int(p[geo[G_ROW] + 1]), p.ctypes, ev.ctypes, ev[size + 1:].ctypes)
        ev[size] = load

    @njit
    def control_system(fc, ctl, ev, geo):
        # tangent_field.control_matrix and effective_rate: M = rows of K where the force is
        # controlled, of I elsewhere, and g' - Q dF/dP P_slope; views into ev's scratch
        n = geo[G_N]
        base = geo[G_SIZE] + 1 + geo[G_SCRATCH]
        matrix = ev[base:base + n * n].reshape(n, n)
        rate = ev[base + n * n:base + n * n + n]
        stiffness, has_load, load_slope = geo[G_STIFFNESS], geo[G_HASLOAD] > 0, ctl[2]
        for i in range(n):
            for j in range(n):
                matrix[i, j] = ev[stiffness + i * n + j] if fc[i] else (1.0 if i == j else 0.0)
            rate[i] = ctl[3 + n + i]
            if has_load:
                rate[i] = rate[i] - (ev[geo[G_LOAD] + i] if fc[i] else 0.0) * load_slope
        out = ev[base + n * n + n:base + n * n + 2 * n + 1]
        work = ev[base + n * n + 2 * n + 1:]
        return matrix, rate, out, work

    @njit
    def tangent_at(y, fc, ctl, orient, ev, aux, geo):
        # tangent_field.path_tangent (n > 2) at an evaluated state: (adj(M) g', det M)
        # normalised in (du, dF, dlambda), times the orientation, flipped where it reverses
        # the reference (_continue_reference); aux as above
        n = geo[G_N]
        matrix, rate, c, work = control_system(fc, ctl, ev, geo)
        cofactor_vector(matrix, rate, c, work)
        det_m = c[n]
        stiffness, load_rate = geo[G_STIFFNESS], 0.0
        for i in range(n):
            aux[i] = c[i]
            aux[n + i] = c[i]
        for i in range(n):
            total = 0.0
            for j in range(n):
                total += ev[stiffness + i * n + j] * c[j]
            if geo[G_HASLOAD] > 0:
                load_rate = ev[geo[G_LOAD] + i] * ctl[2]
                total = total + load_rate * det_m
            aux[2 * n + i] = total
        square_u, square_f = 0.0, 0.0
        for i in range(n):
            square_u += aux[n + i] * aux[n + i]
        for i in range(n):
            square_f += aux[2 * n + i] * aux[2 * n + i]
        norm = np.sqrt(square_u + square_f + det_m * det_m)
        scale = (1.0 / norm if norm > 0 else np.nan) * orient[0]
        for k in range(3 * n):
            aux[k] = aux[k] * scale
        aux[3 * n] = det_m * scale
        aux[3 * n + 1] = det_m
        aux[3 * n + 2] = norm
        product = alignment(aux, orient)
        aux[3 * n + 4] = (product if np.isfinite(product) else 1.0) * norm
        flip = product < 0
        aux[3 * n + 3] = 1.0 if flip else 0.0
        if flip:
            for k in range(3 * n + 1):
                aux[k] = -aux[k]

    @njit
    def no_tangent(aux):
        # dlambda and the branch test left NaN (an indicator that needs no tangent)
        n = (aux.size - 5) // 3
        aux[3 * n] = np.nan
        aux[3 * n + 4] = np.nan

    @njit
    def was_flipped(aux):
        return aux[aux.size - 2] > 0

    @njit
    def alignment(aux, orient):
        # over_steps / _continue_reference: the cosine of the motion (du, dF, dlambda) in aux
        # with the reference orient[1:] (sum(motion * reference) / sqrt(sum(reference**2)))
        n = (aux.size - 5) // 3
        dot, square = 0.0, 0.0
        for k in range(2 * n + 1):
            dot += aux[n + k] * orient[1 + k]
        for k in range(2 * n + 1):
            square += orient[1 + k] * orient[1 + k]
        return dot / np.sqrt(square)

    @njit
    def branch_size(aux, orient):
        # stepper._commit: |PathTangent.branch|
        return abs(aux[aux.size - 1])

    @njit
    def set_reference(aux, orient):
        # stepper._commit: the reference of the next piece, the motion (du, dF, dlambda)
        n = (aux.size - 5) // 3
        for k in range(2 * n + 1):
            orient[1 + k] = aux[n + k]

    @njit
    def motion(ev, aux, out):
        # contacts.switch_contacts.motion: (du, dF, dlambda) of the tangent in aux
        n = (aux.size - 5) // 3
        for k in range(2 * n + 1):
            out[k] = aux[n + k]

    @njit
    def motion_product(before, ev, aux):
        # the sum over (du, dF, dlambda) of motion(after) * motion(before), in order
        n = (aux.size - 5) // 3
        total = 0.0
        for k in range(2 * n + 1):
            total += aux[n + k] * before[k]
        return total

    def rhs_py(y, fc, ctl, orient, law, p, geo, dy, ev, aux):
        # rhs.state_derivative: dy/ds = (dv, dlambda, dinternal, dW), dW = work_factor
        # (F + P Q_ext) . du
        n, n_internal = geo[G_N], geo[G_NINT]
        evaluate(y, ctl, law, p, geo, ev)
        tangent_at(y, fc, ctl, orient, ev, aux, geo)
        for i in range(n):
            dy[i] = aux[i]
        dy[n] = aux[3 * n]
        gradient = geo[G_GRADIENT]
        for k in range(n_internal):
            total = 0.0
            for j in range(n):
                total += ev[gradient + k * n + j] * aux[j]
            dy[n + 1 + k] = total
        dy[n + 1 + n_internal] = p[geo[G_ROW]] * work_power(ev, aux, geo)

    rhs_hot = hot(rhs_py)  # noqa: F841 (read by parts 2 and 3)
    rhs = njit(rhs_py)  # noqa: F841

    @njit
    def work_power(ev, aux, geo):
        # rhs.work_forces . du: (F - P dF/dP) . du
        n, forces, load = geo[G_N], geo[G_FORCES], ev[geo[G_SIZE]]
        total = 0.0
        for i in range(n):
            force = ev[forces + i] - load * ev[geo[G_LOAD] + i] if geo[G_HASLOAD] > 0 else ev[forces + i]
            total += force * aux[n + i]
        return total

    @njit
    def project(y, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev):
        # projection.project with minimum_norm_correction (n > 2), one case; ev left at
        # the final state
        n, forces = geo[G_N], geo[G_FORCES]
        residual = np.empty(n)
        step = np.empty(n + 1)
        for _ in range(newton_max_iter + 1):
            evaluate(y, ctl, law, p, geo, ev)
            size = 0.0
            for i in range(n):
                path = ctl[3 + i] + ctl[3 + n + i] * y[n]
                residual[i] = (ev[forces + i] if fc[i] else y[i]) - path
                a = abs(residual[i])
                size = np.nan if (np.isnan(a) or np.isnan(size)) else max(size, a)
            if size <= newton_tol:
                return True
            if not np.isfinite(size):
                return False
            matrix, rate, _, work = control_system(fc, ctl, ev, geo)
            if not minimum_norm_step(matrix, rate, residual, step, work):
                least_squares_step(matrix, rate, residual, step)
            power = 0.0
            for i in range(n):
                y[i] += step[i]
            for i in range(n):
                force = ev[forces + i] - ev[geo[G_SIZE]] * ev[geo[G_LOAD] + i] if geo[G_HASLOAD] > 0 else ev[forces + i]
                power += force * step[i]
            y[n] += step[n]
            y[n + 1 + geo[G_NINT]] += p[geo[G_ROW]] * power
        evaluate(y, ctl, law, p, geo, ev)
        return False

    @njit
    def least_squares_step(matrix, rate, residual, step):
        # projection.minimum_norm_correction, a rank-deficient case: least squares on the
        # normal matrix M M^T + g' g'^T (NaN where an entry is not finite)
        n = rate.shape[0]
        finite = True
        for i in range(n):
            finite = finite and np.isfinite(rate[i])
            for j in range(n):
                finite = finite and np.isfinite(matrix[i, j])
        if not finite:
            for i in range(n + 1):
                step[i] = np.nan
            return
        normal = matrix @ matrix.T
        for i in range(n):
            for j in range(n):
                normal[i, j] += rate[i] * rate[j]
        least = np.linalg.lstsq(normal, residual.copy(), rcond=np.finfo(np.float64).eps * n)[0]
        for i in range(n):
            total = 0.0
            for j in range(n):
                total += matrix[j, i] * least[j]
            step[i] = -total
        total = 0.0
        for i in range(n):
            total += rate[i] * least[i]
        step[n] = total

    @njit
    def significant(value, size):
        # events.indicator_values.significant
        return 0.0 if abs(value) <= sign_noise * size else value

    @njit
    def signed_gap(value, secondary, bit):
        # events._signed_zero: a contact indicator exactly at zero takes the sign of its state
        if value == 0:
            return -tiny if (secondary & bit) > 0 else tiny
        return value

    @njit
    def target_indicator(lam, lam_end, target_sign):
        # events.indicator_values: the stage target, (lambda - lambda_end) sign
        return (lam - lam_end) * target_sign

    @njit
    def stiffness_indicators(ev, fc, ctl, geo, out):
        # events.indicator_values, the four columns built on K (operators.indicators: det K,
        # the least eigenvalue of K_sym, det M, the discriminant of K's characteristic
        # polynomial; NaN where K is not finite), values within rounding of zero unsigned
        n, at = geo[G_N], geo[G_STIFFNESS]
        stiffness = np.empty((n, n))
        for i in range(n):
            for j in range(n):
                stiffness[i, j] = ev[at + i * n + j]
        matrix, _, _, _ = control_system(fc, ctl, ev, geo)
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
            out[0] = significant(np.linalg.det(stiffness), square)
            out[1] = significant(np.linalg.eigvalsh(0.5 * (stiffness + stiffness.T))[0], scale)
        else:
            out[0] = out[1] = np.nan
        if geo[G_MASS] >= 0:  # M s^2 + K: the frequencies' discriminant (dynamics.flutter_onset_indicator)
            out[3] = frequency_discriminant(ev, geo, stiffness, finite)
        else:
            out[3] = significant(discriminant(stiffness), square) if finite else np.nan
        control_finite = True
        for i in range(n):
            for j in range(n):
                control_finite = control_finite and np.isfinite(matrix[i, j])
        out[2] = significant(np.linalg.det(np.ascontiguousarray(matrix)), square) if control_finite else np.nan

    @njit
    def discriminant(matrix):
        # operators.indicators.flutter_discriminant (n > 2): prod_{i<j} (lambda_i - lambda_j)^2,
        # the eigenvalues of a finite real matrix
        n = matrix.shape[0]
        eigenvalues = np.linalg.eigvals(matrix.astype(np.complex128))
        product = 1.0 + 0.0j
        for i in range(n):
            for j in range(i + 1, n):
                product = product * (eigenvalues[i] - eigenvalues[j]) ** 2
        return product.real

    @njit
    def frequency_discriminant(ev, geo, stiffness, finite):
        # operators.dynamics.frequency_discriminant (n > 2, C = 0): det(M)^(2n - 2) times the
        # discriminant of M^-1 K; NaN where M is not regular (dynamic_matrices.regular_mass:
        # |det M| > n eps prod |M_j|) or K not finite
        n, at = geo[G_N], geo[G_MASS]
        mass = np.empty((n, n))
        identity, mass_finite = True, True
        for i in range(n):
            for j in range(n):
                mass[i, j] = ev[at + i * n + j]
                identity = identity and mass[i, j] == (1.0 if i == j else 0.0)
                mass_finite = mass_finite and np.isfinite(mass[i, j])
        if not (mass_finite and finite):
            return np.nan
        determinant = np.linalg.det(mass)
        norms = 1.0
        for j in range(n):
            column = 0.0
            for i in range(n):
                column += mass[i, j] * mass[i, j]
            norms *= np.sqrt(column)
        if not abs(determinant) > n * np.finfo(np.float64).eps * norms:
            return np.nan
        product = stiffness.copy() if identity else np.linalg.solve(mass, stiffness)
        for i in range(n):
            for j in range(n):
                if not np.isfinite(product[i, j]):
                    return np.nan
        return determinant ** (2 * n - 2) * discriminant(product)

    @njit
    def indicators(ev, aux, y, fc, ctl, geo, lam_end, target_sign, turn_end, secondary, out):
        # events.indicator_values for a general layout without inertia; turn_end: 2 pi
        # (turns done + 1) in a cycle stage, else NaN
        n, lam = geo[G_N], y[geo[G_N]]
        stiffness_indicators(ev, fc, ctl, geo, out)
        for g in range(geo[G_NGAPS]):
            out[geo[G_GAPCOL] + g] = signed_gap(ev[geo[G_GAPS] + g], secondary, 1 << g)
        out[geo[G_TURNING]] = aux[3 * n]
        for j in range(geo[G_NOPEN]):
            out[geo[G_NORMALCOL] + j] = signed_gap(ev[geo[G_OVERLAPS] + j], secondary, 1 << (geo[G_NGAPS] + j))
        # the dynamic divergence test: det M of the stage's control, for a system with inertia
        out[geo[G_DIVERGENCE]] = out[2] if geo[G_MASS] >= 0 else np.nan
        out[geo[G_BIFURCATION]] = aux[3 * n + 4]
        out[geo[G_CYCLE]] = lam - turn_end
        out[geo[G_TARGET]] = target_indicator(lam, lam_end, target_sign)

    @njit
    def state_indicator(y, column, lam_end, target_sign, secondary, geo):
        # (True, value) for a column that is a function of y alone: the target
        if column == geo[G_TARGET]:
            return True, target_indicator(y[geo[G_N]], lam_end, target_sign)
        return False, np.nan

    @njit
    def domain_detail(state, ev_state, geo):
        # domain_edge.domain_codes, one state: -1 inside the domain, else the index of the
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
    def arc_through(y0, y_half, y_new, ev_new, ctl, law, p, geo, ev):
        # over_steps.arc_length: the arc through the start y0, the middle y_half (evaluated in
        # ev on entry) and the end y_new (ev_new), in (u, F, lambda); ev left at the start
        n, forces = geo[G_N], geo[G_FORCES]
        middle = np.empty(n)
        for i in range(n):
            middle[i] = ev[forces + i]
        evaluate(y0, ctl, law, p, geo, ev)
        whole, first, second = 0.0, 0.0, 0.0
        for i in range(n):
            whole += (y_new[i] - y0[i]) ** 2
            first += (y_half[i] - y0[i]) ** 2
            second += (y_new[i] - y_half[i]) ** 2
        for i in range(n):
            whole += (ev_new[forces + i] - ev[forces + i]) ** 2
            first += (middle[i] - ev[forces + i]) ** 2
            second += (ev_new[forces + i] - middle[i]) ** 2
        whole += (y_new[n] - y0[n]) ** 2
        first += (y_half[n] - y0[n]) ** 2
        second += (y_new[n] - y_half[n]) ** 2
        return (4.0 * (np.sqrt(first) + np.sqrt(second)) - np.sqrt(whole)) / 3.0

    @njit
    def turn_record(y, ev, row, geo):
        # (cycle stages do not run in this loop)
        row[0] = y[y.size - 1]

    @njit
    def store_record(recorded, i, position, arclength, stage_number, y, ev, aux, geo):
        # stepper.BatchStepper.record, into the recorder's padded arrays: (s, stage, u, lam,
        # internal, work, F, K, du, dlam) and the interactions' block of the kernel's row
        # (``recorded``, :meth:`ncstab.paths.compiled_stages.CompiledStages.recorded`)
        r_s, r_stage, r_u, r_lam, r_internal, r_work, r_f, r_k, r_du, r_dlam, r_interactions = recorded
        n, n_internal = geo[G_N], geo[G_NINT]
        r_s[i, position] = arclength
        r_stage[i, position] = stage_number
        for k in range(n):
            r_u[i, position, k] = y[k]
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
    def store_event(row, arclength, sigma, lower, upper, y, ev, geo):
        # crossings.store_first_events, one event of one case: s, its bracket, lambda, the
        # load parameter, u, F, K, then the interactions' block of the kernel's row
        n = geo[G_N]
        row[0] = arclength + sigma
        row[1] = arclength + lower
        row[2] = arclength + upper
        row[3] = y[n]
        row[4] = ev[geo[G_SIZE]]
        at = 5
        for k in range(n):
            row[at + k] = y[k]
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
