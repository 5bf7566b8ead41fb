"""A general model as the compiled stage loop sees it: its evaluation, tangent and projection.

One loop serves every general model (any :class:`~ncstab.systems.SystemDefinition`,
and the diamond's pure-shear limit, :mod:`ncstab.paths.compiled_rigid`): the sizes
are the case's ``geo`` row (:data:`GEO`), and the model is its compiled kernel's
C callback (``law``, :meth:`ncstab.operators.model_kernel.ModelKernel.callback`),
which writes a row of :class:`~ncstab.operators.model_kernel_source.KernelLayout`
(F, K, dF/dP, d(internal)/du, gaps, overlaps, the domain code, the interactions).
The cofactor tangent and the Newton correction are
:func:`ncstab.paths.cofactor.cofactor_vector` and
:func:`~ncstab.paths.cofactor.minimum_norm_step` (seed Eq. 30-34).  Its sizes,
indicators, domain check and storage are in :mod:`ncstab.paths.loop_general_output`.
The first argument of each function the shared parts of the loop call
(:mod:`ncstab.paths.loop_dispatch`) is the model's record
(:class:`ncstab.paths.loop_records.GeneralModel`).
"""

from __future__ import annotations

import math

import numpy as np

from ncstab.jit import hot, njit
from ncstab.paths.cofactor import cofactor_vector, minimum_norm_step

__all__ = [
    "GEO", "alignment", "branch_size", "control_at", "control_system", "displacement", "displacement_step",
    "evaluate", "least_squares_step", "motion", "motion_product", "no_tangent", "project", "rhs", "rhs_hot",
    "set_reference", "tangent_at", "was_flipped", "work_power",
]

#: Slots of a general model's ``geo`` row (int64, the same for every case of a batch):
#: the kernel's layout, the loop's buffer sizes and the event columns
#: (:class:`ncstab.paths.compiled_stages.CompiledStages`).
GEO = {name: slot for slot, name in enumerate((
    "n", "n_internal", "size", "scratch", "forces", "stiffness", "load", "gradient", "gaps", "n_gaps", "overlaps",
    "n_open", "domain", "interactions", "has_load", "columns", "target", "cycle", "turning", "bifurcation", "limit",
    "control", "divergence", "gap_column", "normal_column", "row", "ev_size", "mass", "damping", "tangential",
    "tangential_count", "tangential_stride", "coordinates", "blocking",
))}
G_N, G_NINT, G_SIZE, G_SCRATCH = GEO["n"], GEO["n_internal"], GEO["size"], GEO["scratch"]
G_FORCES, G_STIFFNESS, G_LOAD, G_GRADIENT = GEO["forces"], GEO["stiffness"], GEO["load"], GEO["gradient"]
G_GAPS, G_NGAPS, G_OVERLAPS, G_NOPEN = GEO["gaps"], GEO["n_gaps"], GEO["overlaps"], GEO["n_open"]
G_DOMAIN, G_INTERACTIONS, G_HASLOAD, G_COLUMNS = GEO["domain"], GEO["interactions"], GEO["has_load"], GEO["columns"]
G_TARGET, G_CYCLE, G_TURNING, G_BIFURCATION = GEO["target"], GEO["cycle"], GEO["turning"], GEO["bifurcation"]
G_LIMIT, G_CONTROL, G_DIVERGENCE = GEO["limit"], GEO["control"], GEO["divergence"]
G_GAPCOL, G_NORMALCOL, G_ROW, G_EVSIZE = GEO["gap_column"], GEO["normal_column"], GEO["row"], GEO["ev_size"]
# the offsets of M(u) and C(u) in the kernel's row (-1 without inertia, without damping)
G_MASS, G_DAMPING = GEO["mass"], GEO["damping"]
# T of the first contact family: its offset in the row (-1: none), members, stride
G_T, G_TCOUNT, G_TSTRIDE = GEO["tangential"], GEO["tangential_count"], GEO["tangential_stride"]
# State coordinates v other than u (the pure-shear limit, compiled_rigid): the offset in
# the row of u(v) (n), du/dv and dF/dv (n x n each), -1 where v = u (du/dv = I, dF/dv =
# K); and whether a closing gap blocks the chain (changing the coordinates, below)
G_COORD, G_BLOCKING = GEO["coordinates"], GEO["blocking"]
# The case's p row: the kernel's parameter row (ROW entries), the work factor, then
# the contact-state bits.  ctl: is_cycle, load offset, load slope, g's offset and
# slope (n each), then a cycle's centre (2), radius, theta0, direction and plane (2
# dofs).  ev: the kernel's row, the load parameter, the kernel's scratch, then the
# tangent's (control matrix, rate, cofactor vector, QR work).
# aux: dv, du, dF (n each), dlambda, det M, |c|, 1.0 where flipped, the branch test.



@hot
def evaluate(kind, y, ctl, law, p, geo, ev):
    # rhs.evaluate_at + ModelBatch.evaluate: the kernel's row at y (the load parameter
    # from lambda where the system has one), the load parameter after it
    n, size = geo[G_N], geo[G_SIZE]
    load = ctl[1] + ctl[2] * y[n] if geo[G_HASLOAD] > 0 else 0.0
    law(y.ctypes, y[n + 1:].ctypes, load, int(p[geo[G_ROW] + 1]), p.ctypes, ev.ctypes, ev[size + 1:].ctypes)
    ev[size] = load


@njit
def control_at(lam, ctl, n, i):
    # StageArrays.control_path, one dof: (g_i, g'_i) at lambda; on a cycle stage's circle
    # for the two dofs of its plane
    offset, slope = ctl[3 + i], ctl[3 + n + i]
    if ctl[0] > 0:
        at = 3 + 2 * n
        angle = ctl[at + 3] + ctl[at + 4] * lam
        rate = ctl[at + 2] * ctl[at + 4]
        if i == int(ctl[at + 5]):
            return ctl[at] + ctl[at + 2] * math.cos(angle), rate * -math.sin(angle)
        if i == int(ctl[at + 6]):
            return ctl[at + 1] + ctl[at + 2] * math.sin(angle), rate * math.cos(angle)
    return offset + slope * lam, slope


@njit
def control_system(fc, ctl, lam, ev, geo):
    # tangent_field.control_matrix and effective_rate: M = rows of K where the force is
    # controlled, of I elsewhere, and g' - Q dF/dP P_slope; views into ev's scratch
    n = geo[G_N]
    base = geo[G_SIZE] + 1 + geo[G_SCRATCH]
    matrix = ev[base:base + n * n].reshape(n, n)
    rate = ev[base + n * n:base + n * n + n]
    stiffness, has_load, load_slope = geo[G_STIFFNESS], geo[G_HASLOAD] > 0, ctl[2]
    coordinates = geo[G_COORD]
    for i in range(n):
        for j in range(n):
            if coordinates >= 0:  # rows of dF/dv where the force is controlled, of du/dv elsewhere
                matrix[i, j] = ev[coordinates + n + (n * n if fc[i] else 0) + i * n + j]
            else:
                matrix[i, j] = ev[stiffness + i * n + j] if fc[i] else (1.0 if i == j else 0.0)
        _, rate[i] = control_at(lam, ctl, n, i)
        if has_load:
            rate[i] = rate[i] - (ev[geo[G_LOAD] + i] if fc[i] else 0.0) * load_slope
    out = ev[base + n * n + n:base + n * n + 2 * n + 1]
    work = ev[base + n * n + 2 * n + 1:]
    return matrix, rate, out, work


@njit
def displacement(y, ev, geo, i):
    # u_i at the evaluated state: v_i, or u(v)_i from the row (state coordinates)
    return y[i] if geo[G_COORD] < 0 else ev[geo[G_COORD] + i]


@njit
def displacement_step(ev, geo, dv, du):
    # du of a step dv: dv itself, or du/dv dv (state coordinates; into du)
    n, coordinates = geo[G_N], geo[G_COORD]
    if coordinates < 0:
        return dv[:n]
    for i in range(n):
        total = 0.0
        for j in range(n):
            total += ev[coordinates + n + i * n + j] * dv[j]
        du[i] = total
    return du


@njit
def tangent_at(kind, y, fc, ctl, orient, ev, aux, geo):
    # the path tangent (tangent_field, n > 2) at an evaluated state: (adj(M) g', det M)
    # normalised in (du, dF, dlambda), times the orientation, flipped where it reverses
    # the reference (orientation by continuity); aux as above
    n = geo[G_N]
    matrix, rate, c, work = control_system(fc, ctl, y[geo[G_N]], ev, geo)
    cofactor_vector(matrix, rate, c, work)
    det_m = c[n]
    stiffness, load_rate, coordinates = geo[G_STIFFNESS], 0.0, geo[G_COORD]
    for i in range(n):
        aux[i] = c[i]
        aux[n + i] = c[i]
    if coordinates >= 0:  # du = du/dv dv, dF = dF/dv dv
        stiffness = coordinates + n + n * n
        for i in range(n):
            total = 0.0
            for j in range(n):
                total += ev[coordinates + n + i * n + j] * c[j]
            aux[n + i] = total
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
    product = alignment(kind, aux, orient)
    aux[3 * n + 4] = (product if np.isfinite(product) else 1.0) * norm
    flip = product < 0
    aux[3 * n + 3] = 1.0 if flip else 0.0
    if flip:
        for k in range(3 * n + 1):
            aux[k] = -aux[k]


@njit
def no_tangent(kind, aux):
    # dlambda and the branch test left NaN (an indicator that needs no tangent)
    n = (aux.size - 5) // 3
    aux[3 * n] = np.nan
    aux[3 * n + 4] = np.nan


@njit
def was_flipped(kind, aux):
    return aux[aux.size - 2] > 0


@njit
def alignment(kind, aux, orient):
    # the cosine of the motion (du, dF, dlambda) in aux
    # with the reference orient[1:] (sum(motion * reference) / sqrt(sum(reference**2)))
    n = (aux.size - 5) // 3
    dot, square = 0.0, 0.0
    for k in range(2 * n + 1):
        dot += aux[n + k] * orient[1 + k]
    for k in range(2 * n + 1):
        square += orient[1 + k] * orient[1 + k]
    return dot / np.sqrt(square)


@njit
def branch_size(kind, aux, orient):
    # |the branch test| (tangent_field)
    return abs(aux[aux.size - 1])


@njit
def set_reference(kind, aux, orient):
    # the reference of the next piece, the motion (du, dF, dlambda)
    n = (aux.size - 5) // 3
    for k in range(2 * n + 1):
        orient[1 + k] = aux[n + k]


@njit
def motion(kind, ev, aux, out):
    # the motion (du, dF, dlambda) of the tangent in aux
    n = (aux.size - 5) // 3
    for k in range(2 * n + 1):
        out[k] = aux[n + k]


@njit
def motion_product(kind, before, ev, aux):
    # the sum over (du, dF, dlambda) of motion(kind, after) * motion(kind, before), in order
    n = (aux.size - 5) // 3
    total = 0.0
    for k in range(2 * n + 1):
        total += aux[n + k] * before[k]
    return total

def rhs_py(kind, y, fc, ctl, orient, law, p, geo, dy, ev, aux):
    # dy/ds (rhs) = (dv, dlambda, dinternal, dW), dW = work_factor
    # (F + P Q_ext) . du
    n, n_internal = geo[G_N], geo[G_NINT]
    evaluate(kind, y, ctl, law, p, geo, ev)
    tangent_at(kind, y, fc, ctl, orient, ev, aux, geo)
    for i in range(n):
        dy[i] = aux[i]
    dy[n] = aux[3 * n]
    gradient = geo[G_GRADIENT]
    for k in range(n_internal):
        total = 0.0
        for j in range(n):
            total += ev[gradient + k * n + j] * aux[j]
        dy[n + 1 + k] = total
    dy[n + 1 + n_internal] = p[geo[G_ROW]] * work_power(ev, geo, aux[n:2 * n])

rhs_hot = hot(rhs_py)
rhs = njit(rhs_py)


@njit
def work_power(ev, geo, du):
    # rhs.work_forces . du: (F - P dF/dP) . du, F and P of the evaluated state in ev
    n, forces, load = geo[G_N], geo[G_FORCES], ev[geo[G_SIZE]]
    total = 0.0
    for i in range(n):
        force = ev[forces + i] - load * ev[geo[G_LOAD] + i] if geo[G_HASLOAD] > 0 else ev[forces + i]
        total += force * du[i]
    return total


@njit
def project(kind, y, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev):
    # the Newton projection (projection, minimum-norm corrections, n > 2), one case; ev left at
    # the final state
    n, forces = geo[G_N], geo[G_FORCES]
    residual = np.empty(n)
    step = np.empty(n + 1)
    du = np.empty(n)
    for _ in range(newton_max_iter + 1):
        evaluate(kind, y, ctl, law, p, geo, ev)
        size = 0.0
        for i in range(n):
            path, _ = control_at(y[n], ctl, n, i)
            residual[i] = (ev[forces + i] if fc[i] else displacement(y, ev, geo, i)) - path
            a = abs(residual[i])
            size = np.nan if (np.isnan(a) or np.isnan(size)) else max(size, a)
        if size <= newton_tol:
            return True
        if not np.isfinite(size):
            return False
        matrix, rate, _, work = control_system(fc, ctl, y[n], ev, geo)
        if not minimum_norm_step(matrix, rate, residual, step, work):
            least_squares_step(matrix, rate, residual, step)
        power = work_power(ev, geo, displacement_step(ev, geo, step, du))  # (F, P before the step)
        for i in range(n):
            y[i] += step[i]
        y[n] += step[n]
        y[n + 1 + geo[G_NINT]] += p[geo[G_ROW]] * power
    evaluate(kind, y, ctl, law, p, geo, ev)
    return False


@njit
def least_squares_step(matrix, rate, residual, step):
    # a rank-deficient correction (minimum_norm_step found none): least squares on the
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
