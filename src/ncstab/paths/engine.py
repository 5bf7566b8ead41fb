"""The batched path engine: arclength continuation of the rate system.

All cases of one law advance together as arrays (B cases, per-case step sizes,
masks for finished cases).  One formulation serves every law: the unit tangent
of the constrained rate system (:mod:`ncstab.paths.tangent_field`) is integrated
in arclength s with a batched DOP853 step, carrying

    y = (u, lambda, internal variables, work W)

with W = int F . du / 2 (the work per contact, seed Eq. 5).  For a law with a
total form every accepted step is then projected onto the equilibrium manifold
by Newton (minimum-norm corrections), so there is no drift; for a strongly
hypoelastic law (T an internal variable) the integration itself is the path,
at the integrator's accuracy.  Events are sign changes of indicators over an
accepted step, located by root finding on the step length
(:mod:`ncstab.paths.events`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from dataclasses import fields as dataclass_fields
from typing import TYPE_CHECKING, Callable

import numpy as np

from ncstab.paths.events import (
    INDICATOR_EVENTS,
    CYCLE_COLUMN,
    INDICATOR_GAP,
    TARGET_COLUMN,
    STIFFNESS_COLUMNS,
    TURNING_COLUMN,
    indicator_values,
    locate_sign_changes,
)
from ncstab.paths.integrator import (
    END_STAGE,
    dense_output,
    dop853_step,
    evaluate_dense,
    initial_step_size,
    step_factor,
)
from ncstab.paths.model import CaseBatch, Evaluation
from ncstab.paths.options import AUTO, PathOptions
from ncstab.paths.programme import CURRENT, EVENTS, CycleStage, LoadingProgramme, Stage
from ncstab.paths.tangent_field import StageArrays, control_matrix, path_tangent

if TYPE_CHECKING:
    from ncstab.paths.compiled_stages import CompiledStages

__all__ = ["CaseResult", "follow_cases"]

RUNNING = "running"
FINISHED = "finished"
#: The fields of every stored state (:meth:`_BatchStepper.record`), in this order.
STORED_FIELDS = ("s", "stage", "u", "lam", "internal", "work", "F", "l", "alpha", "N", "T", "K", "du", "dlam")
#: Why a state is outside the admissible domain (checked in this order).
DOMAIN_REASONS = ("non-finite numbers", "l* <= 0", "alpha outside (-pi/2, pi/2)")


@dataclass
class _Aux:
    evaluation: Evaluation
    dv: np.ndarray
    du: np.ndarray
    dlam: np.ndarray

    def take(self, index: np.ndarray) -> "_Aux":
        return _Aux(self.evaluation.take(index), self.dv[index], self.du[index], self.dlam[index])

    def put(self, index: np.ndarray, other: "_Aux") -> None:
        self.evaluation.put(index, other.evaluation)
        self.dv[index], self.du[index], self.dlam[index] = other.dv, other.du, other.dlam


class _Layout:
    """Column layout of the integrated state y = (v, lambda, internal, work).

    v are the batch's state coordinates (the displacements u for a deformable
    system).
    """

    def __init__(self, n: int, n_internal: int) -> None:
        self.n = n
        self.n_internal = n_internal
        self.v = slice(0, n)
        self.lam = n
        self.internal = slice(n + 1, n + 1 + n_internal)
        self.work = n + 1 + n_internal
        self.size = n + 2 + n_internal


def _rhs(
    batch: CaseBatch, stage: StageArrays, y: np.ndarray, layout: _Layout, evaluation: Evaluation | None = None
) -> tuple[np.ndarray, _Aux]:
    """dy/ds: oriented unit tangent, internal-variable rates, work rate.

    ``evaluation`` is ``batch.evaluate`` at ``y`` where already known.
    """
    v, lam, internal = y[:, layout.v], y[:, layout.lam], y[:, layout.internal]
    if evaluation is None:
        evaluation = batch.evaluate(v, internal, stage.secondary_state)
    dv, du, dlam, _ = path_tangent(evaluation.du_dv, evaluation.dF_dv, stage, lam)
    dinternal = batch.internal_rate(evaluation, dv, stage.secondary_state)
    dy = np.empty(y.shape)
    dy[:, layout.v] = dv
    dy[:, layout.lam] = dlam
    dy[:, layout.internal] = dinternal
    dy[:, layout.work] = 0.5 * np.sum(evaluation.forces * du, axis=-1)
    return dy, _Aux(evaluation, dv, du, dlam)


def _gather_evaluations(pieces: list[tuple[np.ndarray, Evaluation]], size: int) -> Evaluation:
    """One Evaluation of ``size`` rows from pieces (row indices, Evaluation of those rows)."""
    if len(pieces) == 1 and pieces[0][0].size == size:
        return pieces[0][1]
    rows = np.concatenate([index for index, _ in pieces])
    order = np.argsort(rows, kind="stable")
    parts = [piece for _, piece in pieces]
    values = []
    for f in dataclass_fields(Evaluation):
        arrays = [getattr(part, f.name) for part in parts]
        values.append(None if arrays[0] is None else np.concatenate(arrays)[order])
    return Evaluation(*values)


def _newton_correction_2(
    matrix_u: np.ndarray, matrix_f: np.ndarray, force_controlled: np.ndarray, dg: np.ndarray, residual: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-norm correction for n = 2 in closed form: z = (M M^T + g' g'^T)^-1 r,
    dv = -M^T z; returns (dv, z, singular), singular marking the rows whose
    finite normal matrix could not be inverted (for a least-squares fallback)."""
    fc0, fc1 = force_controlled[:, 0], force_controlled[:, 1]
    m00 = np.where(fc0, matrix_f[:, 0, 0], matrix_u[:, 0, 0])
    m01 = np.where(fc0, matrix_f[:, 0, 1], matrix_u[:, 0, 1])
    m10 = np.where(fc1, matrix_f[:, 1, 0], matrix_u[:, 1, 0])
    m11 = np.where(fc1, matrix_f[:, 1, 1], matrix_u[:, 1, 1])
    g0, g1 = dg[:, 0], dg[:, 1]
    a00 = (m00 * m00 + m01 * m01) + g0 * g0
    a01 = (m00 * m10 + m01 * m11) + g0 * g1
    a11 = (m10 * m10 + m11 * m11) + g1 * g1
    r0, r1 = residual[:, 0], residual[:, 1]
    with np.errstate(all="ignore"):
        det = a00 * a11 - a01 * a01
        z = np.empty(residual.shape)
        z[:, 0] = (a11 * r0 - a01 * r1) / det
        z[:, 1] = (a00 * r1 - a01 * r0) / det
    z0, z1 = z[:, 0], z[:, 1]
    dv = np.empty(residual.shape)
    dv[:, 0] = -(m00 * z0 + m10 * z1)
    dv[:, 1] = -(m01 * z0 + m11 * z1)
    singular = np.isfinite(a00) & np.isfinite(a01) & np.isfinite(a11) & ~np.isfinite(z).all(axis=-1)
    return dv, z, singular


def _project(
    batch: CaseBatch, stage: StageArrays, y: np.ndarray, layout: _Layout, options: PathOptions
) -> tuple[np.ndarray, np.ndarray, Evaluation]:
    """Newton projection of (v, lambda) onto equilibrium + control constraints.

    Solves P u(v) + Q F(v) = g(lambda) by minimum-norm Gauss--Newton corrections
    (the system has one more unknown than equations).  Returns the projected
    states, a mask of the cases that converged to ``options.newton_tol`` and
    ``batch.evaluate`` at the projected states (the last residual check
    evaluates there: callers need not evaluate again).
    """
    y = y.copy()
    size_all = y.shape[0]
    converged = np.zeros(size_all, dtype=bool)
    todo = np.arange(size_all)
    pieces: list[tuple[np.ndarray, Evaluation]] = []
    sub, st = batch, stage
    for _ in range(options.newton_max_iter + 1):
        v, lam = y[todo, layout.v], y[todo, layout.lam]
        with np.errstate(all="ignore"):
            evaluation = sub.evaluate(v, y[todo, layout.internal], st.secondary_state)
            residual = st.residual(evaluation.displacements, evaluation.forces, lam)
        size = np.max(np.abs(residual), axis=-1)
        ok = size <= options.newton_tol
        converged[todo[ok]] = True
        keep = ~ok & np.isfinite(size)
        if not keep.any():
            pieces.append((todo, evaluation))
            todo = todo[:0]
            break
        if not keep.all():
            pieces.append((todo[~keep], evaluation.take(~keep)))
        kept = np.flatnonzero(keep)
        todo, residual = todo[kept], residual[kept]
        st = st.take(kept)
        sub = sub.take(kept)
        _, dg = st.control_path(lam[kept])
        du_dv, df_dv = evaluation.du_dv[kept], evaluation.dF_dv[kept]
        if dg.shape[-1] == 2:
            dv, z, singular = _newton_correction_2(du_dv, df_dv, st.force_controlled, dg, residual)
        else:
            singular = np.ones(kept.size, dtype=bool)
            dv = z = np.empty(residual.shape)
        if singular.any():  # rank-deficient normal matrix (or n != 2): least squares per case
            rows = np.flatnonzero(singular)
            matrix = control_matrix(du_dv[rows], df_dv[rows], st.force_controlled[rows])
            normal_matrix = matrix @ np.swapaxes(matrix, -1, -2) + dg[rows, :, None] * dg[rows, None, :]
            with np.errstate(all="ignore"):
                z[rows] = np.stack(
                    [np.linalg.lstsq(a, r, rcond=None)[0] for a, r in zip(normal_matrix, residual[rows])]
                )
            dv[rows] = -np.einsum("bji,bj->bi", matrix, z[rows])
        y[todo, layout.v] += dv
        y[todo, layout.lam] += np.sum(dg * z, axis=-1)
        # Keep the work W = int F . du / 2 consistent with the corrected path.
        if dv.shape[-1] == 2:
            du = np.empty(dv.shape)
            du[:, 0] = du_dv[:, 0, 0] * dv[:, 0] + du_dv[:, 0, 1] * dv[:, 1]
            du[:, 1] = du_dv[:, 1, 0] * dv[:, 0] + du_dv[:, 1, 1] * dv[:, 1]
        else:
            du = (du_dv @ dv[:, :, None])[:, :, 0]
        y[todo, layout.work] += 0.5 * np.sum(evaluation.forces[kept] * du, axis=-1)
    if todo.size:  # out of iterations: evaluate at the last corrected states
        with np.errstate(all="ignore"):
            pieces.append((todo, sub.evaluate(y[todo, layout.v], y[todo, layout.internal], st.secondary_state)))
    return y, converged, _gather_evaluations(pieces, size_all)


def _advance(
    batch: CaseBatch,
    stage: StageArrays,
    y0: np.ndarray,
    h: np.ndarray,
    layout: _Layout,
    options: PathOptions,
    f0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, "_Aux | Evaluation | None"]:
    """One step of length h per case: DOP853, then Newton projection (total forms).

    ``f0`` is dy/ds at ``y0`` where already known (first same as last: the
    derivative at the end of the previous accepted step).  Returns the new
    states, the error norms (inf where Newton failed), the unprojected DOP853
    end states, the stage derivatives (for dense output) and what is already
    known at the new states: without projection the auxiliary quantities
    (an ``_Aux``, from the last stage, which is evaluated there); with it the
    Newton projection's last evaluation (an ``Evaluation``, or ``None`` where
    some states were not projected).
    """
    last: list[_Aux] = []

    def rhs(y: np.ndarray) -> np.ndarray:
        dy, aux = _rhs(batch, stage, y, layout)
        last[:] = [aux]
        return dy

    y_raw, err, stages = dop853_step(rhs, y0, h, options.rtol, options.atol, f0=f0)
    y1 = y_raw.copy()
    if batch.has_total_form and y1.shape[0]:
        y1, err, evaluation = _project_finite(batch, stage, y1, err, layout, options)
        return y1, err, y_raw, stages, evaluation
    return y1, err, y_raw, stages, last[0]


def _project_finite(
    batch: CaseBatch, stage: StageArrays, y: np.ndarray, err: np.ndarray, layout: _Layout, options: PathOptions
) -> tuple[np.ndarray, np.ndarray, Evaluation | None]:
    """Newton-project the finite states; err = inf where projection fails.

    Also returns the evaluation at the projected states when every state
    was projected (else ``None``).
    """
    y, err = y.copy(), err.copy()
    index = np.flatnonzero(np.isfinite(err))
    evaluation = None
    if index.size:
        if index.size == y.shape[0]:
            projected, converged, evaluation = _project(batch, stage, y, layout, options)
        else:
            projected, converged, _ = _project(batch.take(index), stage.take(index), y[index], layout, options)
        y[index] = projected
        err[index[~converged]] = np.inf
    return y, err, evaluation


def _indicators(batch: CaseBatch, stage: StageArrays, y: np.ndarray, aux: _Aux, layout: _Layout) -> np.ndarray:
    return indicator_values(aux.evaluation, stage, y[:, layout.lam], aux.dlam)


class _Recorder:
    """Stores states straight into padded ``(B, capacity, ...)`` arrays.

    Each case's states go to its next free position; the capacity grows
    geometrically, so a sweep costs one scatter per stored state and field
    (no per-step chunks to concatenate and sort at the end).
    """

    def __init__(self, size: int) -> None:
        self.size = size
        self.count = np.zeros(size, dtype=int)
        self.arrays: dict[str, np.ndarray] | None = None
        self.capacity = 0

    @staticmethod
    def _blank(shape: tuple[int, ...], dtype: np.dtype) -> np.ndarray:
        return np.full(shape, -1 if np.dtype(dtype).kind == "i" else np.nan, dtype=dtype)

    def add(self, case: np.ndarray, **values: np.ndarray) -> None:
        values = {key: np.asarray(value) for key, value in values.items()}
        position = self.count[case]
        needed = int(position.max()) + 1 if case.size else 0
        if self.arrays is None:
            # Created even when no case stores a state (all fail at the first
            # stage start): every field still gets its shape and dtype.
            self.capacity = max(needed, 8)
            self.arrays = {
                key: self._blank((self.size, self.capacity) + value.shape[1:], value.dtype)
                for key, value in values.items()
            }
        else:
            self.reserve(needed)
        self._scatter(case * self.capacity + position, values)
        self.count[case] += 1

    def create(self, fields: dict[str, tuple[tuple[int, ...], np.dtype]]) -> None:
        """Create the arrays (if not yet) for ``fields``: name -> (shape after the case
        and step axes, dtype), for a writer that fills them itself."""
        if self.arrays is None:
            self.capacity = 8
            self.arrays = {
                key: self._blank((self.size, self.capacity) + shape, dtype) for key, (shape, dtype) in fields.items()
            }

    def reserve(self, needed: int) -> None:
        """Room for ``needed`` states per case (the capacity at least doubles); also
        for a writer that fills the arrays and ``count`` itself (:mod:`ncstab.paths.compiled`)."""
        assert self.arrays is not None
        if needed > self.capacity:
            capacity = max(needed, 2 * self.capacity)
            for key, array in self.arrays.items():
                grown = self._blank((self.size, capacity) + array.shape[2:], array.dtype)
                grown[:, : self.capacity] = array
                self.arrays[key] = grown
            self.capacity = capacity

    def _scatter(self, flat: np.ndarray, values: dict[str, np.ndarray]) -> None:
        """Write ``values`` at the flat (case * capacity + position) indices ``flat``."""
        assert self.arrays is not None
        for key, value in values.items():
            array = self.arrays[key]
            array.reshape((self.size * self.capacity,) + array.shape[2:])[flat] = value

    @property
    def started(self) -> bool:
        return self.arrays is not None

    def assemble(self) -> tuple[dict[str, np.ndarray], np.ndarray]:
        assert self.arrays is not None
        length = int(self.count.max()) if self.size else 0
        # Views, not copies: the capacity left over is less than the length
        # (geometric growth), and copying every field cost more than the rest
        # of the bookkeeping together.
        return {key: array[:, :length] for key, array in self.arrays.items()}, self.count


@dataclass
class CaseResult:
    """Result of one law's batch of cases (see :class:`ncstab.paths.Path`).

    Attributes
    ----------
    steps
        Padded arrays ``(B, n_steps_max, ...)``: ``s``, ``stage``, ``u``, ``F``,
        ``lam``, ``internal``, ``work``, ``l``, ``alpha``, ``N``, ``T``, ``K``,
        ``du`` (unit tangent), ``dlam``.
    n_steps
        Stored states per case, ``(B,)``.
    status, message
        Per case: ``finished``, ``stopped:<event>`` or ``failed:<reason>``, and a
        sentence saying what happened.
    events
        Per event name: arrays ``found (B,)``, ``s``, ``s_lower``, ``s_upper``,
        ``stage``, ``u (B, n)``, ``F (B, n)``, ``l``, ``alpha``, ``N``, ``T``,
        ``K (B, n, n)``.
    counters
        ``accepted``, ``rejected``, ``located`` per case.
    cycles
        Per turn of every cycle stage (in programme order): ``work`` (B, C),
        the work per contact over the turn (seed Eq. 5, from the integrated
        work, not a quadrature of stored states); ``force_gap`` (B, C, n), F at
        the end minus F at the start of the turn; ``tangential_drift`` (B, C),
        the same for T (the internal variable of a rate law); ``stage`` (C,).
    """

    steps: dict[str, np.ndarray]
    n_steps: np.ndarray
    status: np.ndarray
    message: np.ndarray
    events: dict[str, dict[str, np.ndarray]]
    counters: dict[str, np.ndarray]
    cycles: dict[str, np.ndarray] = field(default_factory=dict)


def _as_strings(values: np.ndarray) -> np.ndarray:
    """``values.astype(str)`` for an object array of strings: by distinct value where
    there are few (statuses, messages: 20x faster than converting every entry)."""
    distinct = set(values.tolist())
    if values.size == 0 or len(distinct) > 32:
        return values.astype(str)
    strings = np.empty(values.shape, dtype=f"<U{max(1, *map(len, distinct))}")
    for text in distinct:
        strings[values == text] = text
    return strings


def _empty_events(size: int, n: int) -> dict[str, dict[str, np.ndarray]]:
    """Per event name, its table of first occurrences (nothing found yet).

    Each field is one block over the events, each table holding a contiguous
    row of it (a dozen allocations for the lot, not six dozen).
    """
    shapes = {
        "found": ((size,), False), "s": ((size,), np.nan), "s_lower": ((size,), np.nan),
        "s_upper": ((size,), np.nan), "stage": ((size,), -1), "lam": ((size,), np.nan),
        "u": ((size, n), np.nan), "F": ((size, n), np.nan), "l": ((size,), np.nan),
        "alpha": ((size,), np.nan), "N": ((size,), np.nan), "T": ((size,), np.nan),
        "K": ((size, n, n), np.nan),
    }
    blocks = {
        key: np.full((len(EVENTS), *shape), blank, dtype=type(blank))
        for key, (shape, blank) in shapes.items()
    }
    return {name: {key: block[e] for key, block in blocks.items()} for e, name in enumerate(EVENTS)}


@dataclass
class _Crossings:
    """Sign changes of the indicators over one accepted step, located.

    ``sigma``, ``lower``, ``upper``: (rows, columns) root and bracket in step
    length (inf / NaN where no change); ``located``: (rows,) number of located
    roots.  The states at the roots are stored for the located pairs only:
    ``slot`` (rows, columns) indexes ``states`` (pairs, m), -1 where none.
    """

    sigma: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    slot: np.ndarray
    states: np.ndarray
    located: np.ndarray

    def located_y(self, rows: np.ndarray, columns: np.ndarray) -> np.ndarray:
        """States at the roots of (rows, columns) pairs, ``(len(rows), m)`` (NaN where none)."""
        slot = self.slot[rows, columns]
        out = self.states[np.maximum(slot, 0)] if self.states.shape[0] else np.full(
            (slot.size, self.states.shape[1]), np.nan
        )
        out[slot < 0] = np.nan
        return out


def _locate_crossings(
    batch: CaseBatch,
    stage: StageArrays,
    change: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    y_start: np.ndarray,
    y_raw: np.ndarray,
    y_end: np.ndarray,
    h: np.ndarray,
    stages_k: np.ndarray,
    layout: _Layout,
    options: PathOptions,
) -> _Crossings:
    """Locate every indicator sign change of a step on the DOP853 interpolant.

    Root finding (Illinois) on the step length, each evaluation on the 7th-order
    interpolant and, for laws with a total form, projected onto equilibrium.
    """
    rows_n, n_cols = change.shape
    sigma = np.full((rows_n, n_cols), np.inf)
    lower = np.full((rows_n, n_cols), np.nan)
    upper = np.full((rows_n, n_cols), np.nan)
    exact_target = change[:, TARGET_COLUMN] & (after[:, TARGET_COLUMN] == 0)
    searched = change.copy()
    searched[:, TARGET_COLUMN] &= ~exact_target
    # Every (row, column) pair with a sign change is one root search; all
    # pairs of the step advance together (each pair's iterates depend on that
    # pair only, so this equals one search per column, with fewer passes).
    pair_row, pair_column = np.nonzero(searched)
    located = np.bincount(pair_row, minlength=rows_n)
    if pair_row.size:
        # DOP853 interpolant over the step (3 extra stages, only where needed).
        needs = np.flatnonzero(searched.any(axis=1))
        b_n, s_n = batch.take(needs), stage.take(needs)
        coefficients = dense_output(
            lambda yy: _rhs(b_n, s_n, yy, layout)[0], y_start[needs], y_raw[needs], h[needs], stages_k[:, needs]
        )
        slot_of_row = np.full(rows_n, -1)
        slot_of_row[needs] = np.arange(needs.size)

        def evaluate(index: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            pick = pair_row[index]
            b, s_ = batch.take(pick), stage.take(pick)
            yy = evaluate_dense(y_start[pick], coefficients[:, slot_of_row[pick]], lengths / h[pick])
            columns = pair_column[index]
            turning = bool((columns == TURNING_COLUMN).any())  # the only column needing the tangent
            stiffness_columns = bool((columns < STIFFNESS_COLUMNS).any())
            if b.has_total_form:
                yy, _, evaluation = _project_finite(b, s_, yy, np.zeros(pick.size), layout, options)
            elif turning or stiffness_columns or not isinstance(b, CaseBatch):
                evaluation = b.evaluate(yy[:, layout.v], yy[:, layout.internal], s_.secondary_state)
            else:  # gaps, overlap, cycle end and target need no forces nor K
                evaluation = b.evaluate(
                    yy[:, layout.v], yy[:, layout.internal], s_.secondary_state, geometry_only=True
                )
            lam = yy[:, layout.lam]
            if turning:
                _, _, dlam, _ = path_tangent(evaluation.du_dv, evaluation.dF_dv, s_, lam)
            else:
                dlam = np.full(pick.size, np.nan)
            values = indicator_values(evaluation, s_, lam, dlam, stiffness_columns)
            return values[np.arange(pick.size), columns], yy

        root, lo, hi, _, state = locate_sign_changes(
            evaluate, h[pair_row], before[pair_row, pair_column], after[pair_row, pair_column], options.event_tol
        )
        sigma[pair_row, pair_column], lower[pair_row, pair_column], upper[pair_row, pair_column] = root, lo, hi
        pair_states = state
    else:
        pair_states = np.empty((0, layout.size))
    slot = np.full((rows_n, n_cols), -1)
    slot[pair_row, pair_column] = np.arange(pair_row.size)
    if exact_target.any():
        rows = np.flatnonzero(exact_target)
        sigma[rows, TARGET_COLUMN] = lower[rows, TARGET_COLUMN] = upper[rows, TARGET_COLUMN] = h[rows]
        slot[rows, TARGET_COLUMN] = pair_states.shape[0] + np.arange(rows.size)
        pair_states = np.concatenate([pair_states, y_end[rows]])
    return _Crossings(sigma, lower, upper, slot, pair_states, located)


def _store_first_events(
    events: dict[str, dict[str, np.ndarray]],
    event_column: dict[str, list[int]],
    cases: np.ndarray,
    crossings: _Crossings,
    reach: np.ndarray,
    arclength: np.ndarray,
    stage_index: np.ndarray,
    batch: CaseBatch,
    stage: StageArrays,
    layout: _Layout,
) -> None:
    """Store the first occurrence of each event located within ``reach`` (step length).

    ``reach`` includes the location tolerance, so an event that coincides with
    the cut point (a hyperelastic limit point is also a Hill loss) counts.
    """
    for name in EVENTS:
        columns = event_column[name]
        sig = crossings.sigma[:, columns]
        best = np.argmin(sig, axis=1)
        best_sigma = sig[np.arange(cases.size), best]
        hit = np.isfinite(best_sigma) & (best_sigma <= reach) & ~events[name]["found"][cases]
        rows = np.flatnonzero(hit)
        if rows.size == 0:
            continue
        col = np.asarray(columns)[best[rows]]
        state = crossings.located_y(rows, col)
        _, ax = _rhs(batch.take(rows), stage.take(rows), state, layout)
        table = events[name]
        target = cases[rows]
        table["found"][target] = True
        table["s"][target] = arclength[target] + crossings.sigma[rows, col]
        table["s_lower"][target] = arclength[target] + crossings.lower[rows, col]
        table["s_upper"][target] = arclength[target] + crossings.upper[rows, col]
        table["stage"][target] = stage_index[target]
        table["lam"][target] = state[:, layout.lam]
        table["u"][target] = ax.evaluation.displacements
        table["F"][target] = ax.evaluation.forces
        table["l"][target] = ax.evaluation.q[:, 0, 0]
        table["alpha"][target] = ax.evaluation.q[:, 0, 1]
        table["N"][target] = ax.evaluation.normal[:, 0]
        table["T"][target] = ax.evaluation.tangential[:, 0]
        table["K"][target] = ax.evaluation.stiffness


def _switch_contacts(
    batch: CaseBatch, stage: StageArrays, y: np.ndarray, gap: np.ndarray, layout: _Layout
) -> tuple[np.ndarray, np.ndarray]:
    """Switch the contact state where a gap crossed zero (in ``stage``, in place).

    The batch switches its springs (or, in the pure-shear limit, its state
    coordinates).  The switch may flip the cofactor tangent, so the direction of
    motion in (u, F, lambda) is kept: returns the new states and a mask of the
    cases whose orientation must flip.
    """
    y = y.copy()
    _, before = _rhs(batch, stage, y, layout)
    batch.close_contact(y, stage.secondary_state, gap, layout)
    _, after = _rhs(batch, stage, y, layout)

    def motion(ax: _Aux) -> np.ndarray:
        df = (ax.evaluation.dF_dv @ ax.dv[:, :, None])[:, :, 0]
        return np.concatenate([ax.du, df, ax.dlam[:, None]], axis=-1)

    return y, np.sum(motion(after) * motion(before), axis=-1) < 0


def _event_tables(
    programme: LoadingProgramme, secondary_contacts: str
) -> tuple[dict[str, list[int]], np.ndarray, np.ndarray]:
    """What a sign change of each indicator column means for the path.

    Returns
    -------
    event_column
        Per event name, its indicator columns.
    stop_table
        ``(stages, columns)`` bool: a crossing of the column stops the case in
        that stage (the stage's ``stop_at``; every secondary contact with
        ``secondary_contacts = "stop"``).
    break_columns
        ``(columns,)`` bool: a crossing switches the contact state, so the step
        is cut there (secondary contacts with ``"activate"``; the normal
        contact of a no_tension law, whose opening and closing switch smooth
        branch, seed Eq. 59).
    """
    event_column = {name: [i for i, e in enumerate(INDICATOR_EVENTS) if e == name] for name in EVENTS}
    stop_table = np.zeros((len(programme), len(INDICATOR_EVENTS)), dtype=bool)
    for k, stage in enumerate(programme.stages):
        for name in stage.stop_at:
            stop_table[k, event_column[name]] = True
        if secondary_contacts == "stop":
            stop_table[k, event_column["secondary_contact"]] = True
    break_columns = np.zeros(len(INDICATOR_EVENTS), dtype=bool)
    if secondary_contacts == "activate":
        break_columns[event_column["secondary_contact"]] = True
    break_columns[INDICATOR_EVENTS.index("normal_contact")] = True
    return event_column, stop_table, break_columns


class _CycleTurns:
    """Per-turn results of the cycle stages of a programme (``CaseResult.cycles``).

    A turn starts where a case enters a stage or closes the previous turn, and
    closes where the cycle (or target) column of a cycle stage is cut.

    Attributes
    ----------
    turns
        ``(stages,)`` turns of each stage (0 for a linear stage).
    first
        ``(stages,)`` column of each stage's first turn in the tables.
    tables
        ``work`` ``(B, C)``: the work per contact over the turn (seed Eq. 5,
        from the integrated work W); ``force_gap`` ``(B, C, n)``: F at the end
        minus F at the start; ``tangential_drift`` ``(B, C)``: the same for T;
        ``stage`` ``(C,)``.
    start_work, start_forces, start_tangential
        W, F and T where each case's current turn started.
    """

    def __init__(self, programme: LoadingProgramme, size: int, n: int) -> None:
        self.turns = np.array([st.turns if isinstance(st, CycleStage) else 0 for st in programme.stages])
        self.first = np.concatenate([[0], np.cumsum(self.turns)])[:-1].astype(int)
        n_cycles = int(self.turns.sum())
        self.tables = {
            "work": np.full((size, n_cycles), np.nan),
            "force_gap": np.full((size, n_cycles, n), np.nan),
            "tangential_drift": np.full((size, n_cycles), np.nan),
            "stage": np.repeat(np.arange(len(programme)), self.turns).astype(int),
        }
        self.start_work = np.zeros(size)
        self.start_forces = np.zeros((size, n))
        self.start_tangential = np.zeros(size)

    def start(self, cases: np.ndarray, work: np.ndarray, evaluation: Evaluation) -> None:
        """A turn starts for ``cases`` at the work ``work`` and the state of ``evaluation``."""
        self.start_work[cases] = work
        self.start_forces[cases] = evaluation.forces
        self.start_tangential[cases] = evaluation.tangential[:, 0]

    def close(
        self,
        cases: np.ndarray,
        stage_index: np.ndarray,
        turn: np.ndarray,
        work: np.ndarray,
        evaluation: Evaluation,
    ) -> None:
        """Turn ``turn`` of stage ``stage_index`` closes for ``cases``; the next turn starts."""
        slot = self.first[stage_index] + turn
        self.tables["work"][cases, slot] = work - self.start_work[cases]
        self.tables["force_gap"][cases, slot] = evaluation.forces - self.start_forces[cases]
        drift = evaluation.tangential[:, 0] - self.start_tangential[cases]
        self.tables["tangential_drift"][cases, slot] = drift
        self.start(cases, work, evaluation)


@dataclass
class _AcceptedSteps:
    """The accepted steps of one pass of the stepper, one row per case.

    Attributes
    ----------
    cases
        ``(A,)`` the rows' case indices in the batch.
    batch, stage
        The rows' cases and stage arrays (``stage`` is a copy, changed in place
        where contacts switch or turns close).
    y_start, h
        States at the start of the step and step lengths.
    y_raw, dop853_stages
        DOP853 end states before the Newton projection and the stage
        derivatives ``(stages, A, m)`` (for dense output).
    y_new
        States at the end of the step, then at the cut point where a step is cut.
    dy_new, aux
        dy/ds and the auxiliary quantities at ``y_new``.
    """

    cases: np.ndarray
    batch: CaseBatch
    stage: StageArrays
    y_start: np.ndarray
    h: np.ndarray
    y_raw: np.ndarray
    dop853_stages: np.ndarray
    y_new: np.ndarray
    dy_new: np.ndarray | None = None
    aux: _Aux | None = None

    def take(self, rows: np.ndarray) -> _AcceptedSteps:
        return _AcceptedSteps(
            self.cases[rows],
            self.batch.take(rows),
            self.stage.take(rows),
            self.y_start[rows],
            self.h[rows],
            self.y_raw[rows],
            self.dop853_stages[:, rows],
            self.y_new[rows],
            None if self.dy_new is None else self.dy_new[rows],
            None if self.aux is None else self.aux.take(rows),
        )


class _BatchStepper:
    """Arclength continuation of a batch of cases through a loading programme.

    Every running case advances by one DOP853 step per pass (:meth:`step`),
    all cases as arrays.  Sign changes of the indicators over an accepted step
    are located; the first crossing that ends the stage, stops the case or
    switches a contact cuts the step there.  Cases enter their next stage at
    the target (:meth:`enter`) and end when the programme is done, at a stop
    event or on a failure.

    Parameters
    ----------
    batch, programme, values, options, secondary_contacts, progress
        As for :func:`follow_cases`.

    Attributes
    ----------
    y
        ``(B, m)`` each case's current state y = (v, lambda, internal, W).
    derivative
        ``(B, m)`` dy/ds there (first same as last for the next step).
    indicators
        ``(B, columns)`` the event indicators there.
    stages, stage_index
        Each case's current stage (:class:`StageArrays`) and its index.
    status, message
        Per case: ``running``, then how it ended.
    step_size, arclength
        Next step length and arclength s reached.
    accepted, rejected, located
        Counters of steps and located events.
    recorder, events, turns
        Stored states, first occurrences of events, cycle turns.
    """

    def __init__(
        self,
        batch: CaseBatch,
        programme: LoadingProgramme,
        values: dict[str, np.ndarray],
        options: PathOptions,
        secondary_contacts: str,
        progress: Callable[[int], None] | None,
    ) -> None:
        self.batch, self.programme, self.values, self.options = batch, programme, values, options
        self.progress = progress
        self.size = size = batch.size
        n = batch.n_dof
        self.layout = layout = _Layout(n, batch.n_internal)
        self.dof_names, self.force_names = batch.system.dof_names, batch.system.force_names
        self.y = np.zeros((size, layout.size))
        self.y[:, layout.v] = batch.initial_state()
        self.derivative = np.full((size, layout.size), np.nan)
        self.stage_index = np.zeros(size, dtype=int)
        self.status = np.empty(size, dtype=object)  # (np.full is 20x slower for objects)
        self.status[:] = RUNNING
        self.message = np.empty(size, dtype=object)
        self.message[:] = ""
        auto = isinstance(options.initial_step, str) and options.initial_step == AUTO
        self.step_size = np.full(size, np.nan if auto else float(options.initial_step))
        self.arclength = np.zeros(size)
        self.accepted = np.zeros(size, dtype=int)
        self.rejected = np.zeros(size, dtype=int)
        self.located = np.zeros(size, dtype=int)
        self.indicators = np.full((size, len(INDICATOR_EVENTS)), np.nan)
        self.stages = StageArrays.empty(size, n)
        self.stages.secondary_state[:] = batch.initial_secondary_state(self.y[:, layout.v])
        self.recorder = _Recorder(size)
        self.events = _empty_events(size, n)
        tables = _event_tables(programme, secondary_contacts)
        self.event_column, self.stop_table, self.break_columns = tables
        self.turns = _CycleTurns(programme, size, n)
        self.compiled = _compiled_stepper(batch, programme, options, secondary_contacts)

    def run(self) -> CaseResult:
        """Follow every case to its end; the result."""
        self.enter(np.arange(self.size), 0)
        if self.compiled is not None:
            self.compiled.run(self)
        while self.step():
            pass
        steps, counts = self.recorder.assemble()
        return CaseResult(
            steps=steps,
            n_steps=counts,
            status=_as_strings(self.status),
            message=_as_strings(self.message),
            events=self.events,
            counters={"accepted": self.accepted, "rejected": self.rejected, "located": self.located},
            cycles=self.turns.tables,
        )

    # --- ending cases and storing states ---------------------------------------------------------

    def end(self, index: np.ndarray, state: str, text: str | np.ndarray) -> None:
        """Cases ``index`` end with status ``state`` and message ``text``."""
        if index.size:
            self.status[index] = state
            self.message[index] = text
            if self.progress:
                self.progress(index.size)

    def fail(self, index: np.ndarray, reason: str, text: str | np.ndarray) -> None:
        """Cases ``index`` fail (status ``failed:<reason>``)."""
        self.end(index, f"failed:{reason}", text)

    def record(self, index: np.ndarray, y: np.ndarray, aux: _Aux) -> None:
        """Store the states ``y`` of cases ``index`` (with ``aux`` there)."""
        ev = aux.evaluation
        self.recorder.add(
            index,
            s=self.arclength[index],
            stage=self.stage_index[index],
            u=ev.displacements,
            lam=y[:, self.layout.lam],
            internal=y[:, self.layout.internal],
            work=y[:, self.layout.work],
            F=ev.forces,
            l=ev.q[:, 0, 0],
            alpha=ev.q[:, 0, 1],
            N=ev.normal[:, 0],
            T=ev.tangential[:, 0],
            K=ev.stiffness,
            du=aux.du,
            dlam=aux.dlam,
        )

    def record_fields(self) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
        """Shape (after the case and step axes) and dtype of each stored field."""
        n, floating = self.batch.n_dof, np.dtype(float)
        shapes = {"u": (n,), "internal": (self.layout.n_internal,), "F": (n,), "K": (n, n), "du": (n,)}
        return {
            name: (shapes.get(name, ()), np.dtype(int) if name == "stage" else floating) for name in STORED_FIELDS
        }

    # --- stage entry ---------------------------------------------------------------------------

    def enter(self, index: np.ndarray, k: int) -> None:
        """Cases ``index`` start stage k (zero-length stages cascade to the next).

        Past the last stage the cases finish.  A case that starts a stage it
        cannot follow fails; the others store their starting state (a case
        that has just reached the target of stage k - 1 stores the same state
        a second time, with the new stage index).
        """
        while index.size:
            if k >= len(self.programme):
                self.end(index, FINISHED, f"finished all {len(self.programme)} loading stage(s)")
                return
            go, zero_length = self._set_up_stage(index, k)
            if go.any() or not self.recorder.started:
                self._start_stage(index[go])
            index, k = index[zero_length], k + 1

    def _every_case(self, index: np.ndarray) -> bool:
        """Whether ``index`` is every case, in order."""
        return index.size == self.size and bool(np.all(index == np.arange(self.size)))

    def _batch_of(self, index: np.ndarray) -> CaseBatch:
        """The cases ``index`` as a batch (the batch itself where that is every case)."""
        return self.batch if self._every_case(index) else self.batch.take(index)

    def _set_up_stage(self, index: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
        """Set up stage k for cases ``index`` from their current states (stage arrays, lambda).

        Fails the cases that cannot start it (a held value that is not the
        current one, a cycle of zero radius, a singular control).  Returns the
        masks (over ``index``) of the cases that start it and of those for
        which it has zero length.
        """
        stage = self.programme.stages[k]
        self.stage_index[index] = k
        v, internal = self.y[index, self.layout.v], self.y[index, self.layout.internal]
        secondary_state = self.stages.secondary_state[index]
        every = self._every_case(index)
        evaluation = (self.batch if every else self.batch.take(index)).evaluate(v, internal, secondary_state)
        u = evaluation.displacements
        current = {name: u[:, i] for i, name in enumerate(self.dof_names)}
        current.update({name: evaluation.forces[:, i] for i, name in enumerate(self.force_names)})
        arrays = StageArrays.empty(index.size, self.batch.n_dof)
        arrays.secondary_state = secondary_state.copy()
        if isinstance(stage, Stage):
            lam, bad, reasons = self._linear_stage(stage, k, index, current, arrays)
        else:
            assert isinstance(stage, CycleStage)
            lam, bad, reasons = self._cycle_stage(stage, k, index, u, arrays)
        self.y[index, self.layout.lam] = lam
        zero_length = (arrays.target_sign == 0) & ~bad
        _, _, dlam, _ = path_tangent(evaluation.du_dv, evaluation.dF_dv, arrays, lam, oriented=False)
        singular = ~(np.abs(dlam) > 0) & ~bad & ~zero_length
        reasons[singular] = (
            f"stage {k + 1}: the control is singular at the stage start (det of the "
            "force-controlled block of K is 0): the driven quantity cannot start"
        )
        bad |= singular
        arrays.orientation = np.where(np.abs(dlam) > 0, np.sign(dlam), 1.0) * np.where(
            arrays.target_sign == 0, 1.0, arrays.target_sign
        )
        if every:
            self.stages = arrays
        else:
            self.stages.put(index, arrays)
        for reason in np.unique(reasons[bad]):
            which = index[bad & (reasons == reason)]
            self.fail(which, "singular_control" if "singular" in reason else "bad_stage_start", reason)
        return ~bad & ~zero_length, zero_length

    def _linear_stage(
        self,
        stage: Stage,
        k: int,
        index: np.ndarray,
        current: dict[str, np.ndarray],
        arrays: StageArrays,
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fill ``arrays`` for a linear stage: each dof controlled through u_i or F_i.

        Held quantities keep their offset, the driven one has slope 1 in
        lambda, which starts at the driven quantity's current value.  Returns
        (lambda at the start, mask of cases that cannot start, reasons).
        """
        bad = np.zeros(index.size, dtype=bool)
        reasons = np.full(index.size, "", dtype=object)
        controls = stage.controls()
        driven_name, target = stage.driven
        for i, (dof, force) in enumerate(zip(self.dof_names, self.force_names)):
            name = force if force in controls else dof
            arrays.force_controlled[:, i] = name == force
            arrays.offset[:, i] = current[name]
            if name == driven_name:
                arrays.offset[:, i] = 0.0
                arrays.slope[:, i] = 1.0
            elif controls[name] != CURRENT:
                mismatch = self._held_away(k, name, controls[name], index, current[name], reasons)
                bad |= mismatch
        start = current[driven_name]
        arrays.lam_end = self._resolve(target, index)
        arrays.target_sign = np.sign(arrays.lam_end - start)
        return start, bad, reasons

    def _held_away(
        self,
        k: int,
        name: str,
        held: float | str,
        index: np.ndarray,
        value: np.ndarray,
        reasons: np.ndarray,
    ) -> np.ndarray:
        """Mask of the cases whose ``name`` (at ``value``) is not at its held value ``held``.

        Says why in ``reasons``.
        """
        nominal = self._resolve(held, index)
        mismatch = np.abs(nominal - value) > 1e-9 * (1 + np.abs(nominal))
        if not mismatch.any():
            return mismatch
        hint = np.where(
            (self.stages.secondary_state[index] & 3) != 0,
            " (secondary-contact springs already act at this state: with "
            "secondary_contacts = 'activate' the grains overlap at rest unless "
            "alpha0 is in [pi/6, pi/3])",
            "",
        )
        text = (
            f"stage {k + 1} holds {name} = {held} but {name} is not at that "
            "value when the stage starts; add a stage that drives it there first"
        )
        reasons[mismatch] = np.char.add(text, hint[mismatch].astype(str)).astype(object)
        return mismatch

    def _cycle_stage(
        self, stage: CycleStage, k: int, index: np.ndarray, u: np.ndarray, arrays: StageArrays
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Fill ``arrays`` for a cycle stage: u on the circle through the current state.

        lambda is the angle turned, from 0 to 2 pi turns.  Returns (lambda at
        the start, mask of cases that cannot start, reasons).
        """
        reasons = np.full(index.size, "", dtype=object)
        center = np.column_stack([self._resolve(c, index) for c in stage.center])
        relative = u - center
        arrays.is_cycle[:] = True
        arrays.center = center
        arrays.radius = np.hypot(relative[:, 0], relative[:, 1])
        arrays.theta0 = np.arctan2(relative[:, 1], relative[:, 0])
        arrays.turn_direction[:] = stage.direction
        arrays.lam_end[:] = 2 * math.pi * stage.turns
        arrays.target_sign[:] = 1.0
        bad = arrays.radius <= 1e-14
        reasons[bad] = f"stage {k + 1}: the state is at the centre of the cycle (zero radius)"
        return np.zeros(index.size), bad, reasons

    def _resolve(self, value: float | str, index: np.ndarray) -> np.ndarray:
        """A stage value (a number or a parameter name) for cases ``index``."""
        if isinstance(value, str):
            if value == CURRENT:
                raise AssertionError("resolved by caller")
            named = self.values[value]
            if np.ndim(named):
                return np.asarray(named, dtype=float)[index]
            return np.full(index.size, float(named))
        return np.full(index.size, float(value))

    def _start_stage(self, index: np.ndarray) -> None:
        """Cases ``index`` start their (set up) stage: dy/ds, indicators, state stored, turn;
        the first step length where it is still to be estimated."""
        if self.compiled is not None:  # no cycle stage there: no turn to start
            self.compiled.start(self, index)  # estimates the first steps too
            return
        batch, stage, y = self._batch_of(index), self.stages.take(index), self.y[index]
        dy, aux = _rhs(batch, stage, y, self.layout)
        self.derivative[index] = dy
        self.indicators[index] = _indicators(batch, stage, y, aux, self.layout)
        self.record(index, y, aux)
        self.turns.start(index, self.y[index, self.layout.work], aux.evaluation)
        self._estimate_first_steps(index[np.isnan(self.step_size[index])])

    @property
    def probe_step(self) -> float:
        """The probe step of the first-step estimate: min(1e-3, max_step)."""
        return min(1e-3, self.options.max_step)

    def _estimate_first_steps(self, index: np.ndarray) -> None:
        """First step lengths of cases ``index`` (``initial_step = "auto"``): Hairer's
        estimate (:func:`~ncstab.paths.integrator.initial_step_size`) from a probe step
        along dy/ds."""
        if index.size == 0:
            return
        probe = self.probe_step
        y0, f0 = self.y[index], self.derivative[index]
        with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
            f1, _ = _rhs(self._batch_of(index), self.stages.take(index), y0 + probe * f0, self.layout)
        self.step_size[index] = initial_step_size(y0, f0, f1, probe, self.options.rtol, self.options.atol)

    # --- one pass of the loop --------------------------------------------------------------------

    def step(self) -> bool:
        """Advance every running case by one step; False when none is running."""
        active = np.flatnonzero(self.status == RUNNING)
        if active.size == 0:
            return False
        steps = self._take_steps(active)
        if steps is not None:
            steps = self._fail_outside_domain(steps)
        if steps is not None:
            self._complete(steps)
        return True

    def _take_steps(self, active: np.ndarray) -> _AcceptedSteps | None:
        """One DOP853 step (Newton-projected for total forms) of the cases ``active``.

        Returns the accepted steps (None if none) with dy/ds and the auxiliary
        quantities at their ends, reusing what the step already evaluated there.
        """
        batch = self.batch.take(active) if active.size < self.size else self.batch
        stage = self.stages.take(active)
        y0 = self.y[active]
        h0 = np.minimum(self.step_size[active], self.options.max_step)
        y1, err, y_raw, dop853_stages, end_aux = _advance(
            batch, stage, y0, h0, self.layout, self.options, self.derivative[active]
        )
        local = np.flatnonzero(self._control_step_size(active, h0, err))
        if local.size == 0:
            return None
        steps = _AcceptedSteps(active, batch, stage, y0, h0, y_raw, dop853_stages, y1)
        every = local.size == active.size  # no copies then (stage is a copy of self.stages already)
        if not every:
            steps = steps.take(local)
        if isinstance(end_aux, _Aux):  # the last DOP853 stage was evaluated at the end state
            if every:
                steps.dy_new, steps.aux = dop853_stages[END_STAGE].copy(), end_aux
            else:
                steps.dy_new, steps.aux = dop853_stages[END_STAGE][local], end_aux.take(local)
        else:  # the Newton projection's last evaluation, where it covers every case
            known = end_aux if every or end_aux is None else end_aux.take(local)
            steps.dy_new, steps.aux = _rhs(steps.batch, steps.stage, steps.y_new, self.layout, known)
        return steps

    def _control_step_size(self, active: np.ndarray, h0: np.ndarray, err: np.ndarray) -> np.ndarray:
        """Next step sizes from the error norms ``err`` of steps ``h0``; the mask of accepted steps.

        Counts the rejected steps and fails the cases whose step size fell
        below ``min_step``.
        """
        accept = err <= 1.0
        factor = np.where(np.isfinite(err), step_factor(err), 0.25)
        factor = np.where(accept, factor, np.minimum(factor, 0.9))
        self.step_size[active] = np.clip(h0 * factor, 0.0, self.options.max_step)
        self.rejected[active[~accept]] += 1
        underflow = ~accept & (self.step_size[active] < self.options.min_step)
        self.fail_step_size_underflow(active[underflow])
        return accept

    def fail_step_size_underflow(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: their step size fell below ``min_step``."""
        self.fail(
            cases,
            "step_size_underflow",
            "the step size fell below min_step: the path cannot be continued "
            "(non-convergent Newton projection, a kink or a singular point)",
        )

    def fail_outside_domain(self, cases: np.ndarray, why: np.ndarray) -> None:
        """Cases ``cases`` fail: they left the admissible domain (``why``, per case)."""
        for reason in np.unique(why):
            which = cases[why == reason]
            self.fail(
                which,
                "left_domain",
                f"the path left the admissible domain ({reason}) in stage "
                f"{self.stage_index[which[0]] + 1}",
            )

    def _fail_outside_domain(self, steps: _AcceptedSteps) -> _AcceptedSteps | None:
        """Fail the cases whose new state left the admissible domain.

        Admissible: finite numbers, l* > 0 and alpha in (-pi/2, pi/2).
        Returns the other cases' steps (None if none).
        """
        q = steps.aux.evaluation.q
        length, angle = q[:, 0, 0], q[:, 0, 1]
        finite = np.isfinite(steps.y_new).all(-1) & np.isfinite(steps.aux.evaluation.forces).all(-1)
        outside = ~finite | ~(length > 0) | ~(np.abs(angle) < math.pi / 2)
        if outside.any():
            why = np.asarray(DOMAIN_REASONS)[np.where(~finite, 0, np.where(~(length > 0), 1, 2))]
            self.fail_outside_domain(steps.cases[outside], why[outside])
        keep = np.flatnonzero(~outside)
        if keep.size == 0:
            return None
        return steps.take(keep) if keep.size < steps.cases.size else steps

    def _complete(self, steps: _AcceptedSteps) -> None:
        """Locate the steps' crossings, cut the steps, store events and states, end stages."""
        indicators = _indicators(steps.batch, steps.stage, steps.y_new, steps.aux, self.layout)
        before = self.indicators[steps.cases]
        change = np.sign(before) * np.sign(indicators) < 0
        change[:, TARGET_COLUMN] = (before[:, TARGET_COLUMN] < 0) & (indicators[:, TARGET_COLUMN] >= 0)
        crossings = _locate_crossings(
            steps.batch, steps.stage, change, before, indicators, steps.y_start, steps.y_raw,
            steps.y_new, steps.h, steps.dop853_stages, self.layout, self.options,
        )
        self.located[steps.cases] += crossings.located
        is_cut, cut_column, reach = self._cut_points(steps, change, crossings.sigma)
        _store_first_events(
            self.events, self.event_column, steps.cases, crossings, reach + self.options.event_tol,
            self.arclength, self.stage_index, steps.batch, steps.stage, self.layout,
        )
        cut_rows = np.flatnonzero(is_cut)
        steps.y_new = steps.y_new.copy()
        if cut_rows.size:
            self._move_to_cut_points(steps, crossings, cut_rows, cut_column, indicators)
        self._commit(steps, reach, indicators)
        self._end_stages(steps.cases, is_cut, cut_column, indicators)

    def _cut_points(
        self, steps: _AcceptedSteps, change: np.ndarray, sigma: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each step is cut: at its first crossing that ends the stage or the case.

        The crossings that cut are those of the target and cycle columns, of
        stop events and of contact switches.  Returns the mask of the cut
        steps, the column that cuts each step and the step length kept (to the
        cut point, else the whole step).
        """
        stops = self.stop_table[self.stage_index[steps.cases]]
        cutting = change & (stops | self.break_columns[None, :])
        cutting[:, TARGET_COLUMN] = change[:, TARGET_COLUMN]
        cutting[:, CYCLE_COLUMN] = change[:, CYCLE_COLUMN]
        cut_sigma = np.where(cutting, sigma, np.inf)
        cut_column = np.argmin(cut_sigma, axis=1)
        rows = np.arange(steps.cases.size)
        is_cut = np.isfinite(cut_sigma[rows, cut_column])
        reach = np.where(is_cut, cut_sigma[rows, cut_column], steps.h)
        return is_cut, cut_column, reach

    def _move_to_cut_points(
        self,
        steps: _AcceptedSteps,
        crossings: _Crossings,
        cut_rows: np.ndarray,
        cut_column: np.ndarray,
        indicators: np.ndarray,
    ) -> None:
        """The steps ``cut_rows`` end at their located cut points instead (in ``steps``).

        Contacts switch and cycle turns close there; dy/ds, the auxiliary
        quantities and the ``indicators`` are updated to the cut states.
        """
        steps.y_new[cut_rows] = crossings.located_y(cut_rows, cut_column[cut_rows])
        closing = cut_rows[self.break_columns[cut_column[cut_rows]]]
        if closing.size:
            self._switch_contacts_at(steps, closing, cut_column)
        self._close_turns(steps, cut_rows, cut_column)
        batch, stage = steps.batch.take(cut_rows), steps.stage.take(cut_rows)
        dy_cut, aux_cut = _rhs(batch, stage, steps.y_new[cut_rows], self.layout)
        steps.dy_new[cut_rows] = dy_cut
        indicators_cut = _indicators(batch, stage, steps.y_new[cut_rows], aux_cut, self.layout)
        # Keep the post-crossing sign of a break column (secondary contact)
        # so the same crossing is not detected twice.
        column_cut = cut_column[cut_rows]
        brk = np.flatnonzero(self.break_columns[column_cut])
        indicators_cut[brk, column_cut[brk]] = indicators[cut_rows[brk], column_cut[brk]]
        indicators[cut_rows] = indicators_cut
        # Writable copies (fields may be read-only views).
        steps.aux = steps.aux.take(np.arange(steps.cases.size))
        steps.aux.put(cut_rows, aux_cut)

    def _switch_contacts_at(
        self, steps: _AcceptedSteps, closing: np.ndarray, cut_column: np.ndarray
    ) -> None:
        """Switch the contact state of rows ``closing``, cut at a break column.

        The direction of motion is kept: the orientation flips where the
        switch flips the cofactor tangent.
        """
        gap = np.asarray(INDICATOR_GAP)[cut_column[closing]]
        switched = steps.stage.take(closing)
        steps.y_new[closing], flip = _switch_contacts(
            steps.batch.take(closing), switched, steps.y_new[closing], gap, self.layout
        )
        steps.stage.secondary_state[closing] = switched.secondary_state
        self.stages.secondary_state[steps.cases[closing]] = switched.secondary_state
        steps.stage.orientation[closing[flip]] *= -1
        self.stages.orientation[steps.cases[closing[flip]]] *= -1

    def _close_turns(
        self, steps: _AcceptedSteps, cut_rows: np.ndarray, cut_column: np.ndarray
    ) -> None:
        """Close a turn where a cycle stage's step is cut at its cycle (or target) column.

        Stores the work per contact over the turn (seed Eq. 5), the force gap
        and the drift of T, and counts the turn.
        """
        column_cut = cut_column[cut_rows]
        turns_here = self.turns.turns[self.stage_index[steps.cases[cut_rows]]]
        ends_turn = (
            ((column_cut == CYCLE_COLUMN) | (column_cut == TARGET_COLUMN))
            & steps.stage.is_cycle[cut_rows]
            & (steps.stage.cycles_done[cut_rows] < turns_here)
        )
        rows = cut_rows[ends_turn]
        if rows.size == 0:
            return
        _, aux = _rhs(steps.batch.take(rows), steps.stage.take(rows), steps.y_new[rows], self.layout)
        cases = steps.cases[rows]
        turn = steps.stage.cycles_done[rows]
        work = steps.y_new[rows, self.layout.work]
        self.turns.close(cases, self.stage_index[cases], turn, work, aux.evaluation)
        steps.stage.cycles_done[rows] += 1
        self.stages.cycles_done[cases] += 1

    def _commit(self, steps: _AcceptedSteps, reach: np.ndarray, indicators: np.ndarray) -> None:
        """The cases move to ``steps.y_new`` (arclength + ``reach``) and store it."""
        cases = steps.cases
        self.y[cases] = steps.y_new
        self.derivative[cases] = steps.dy_new
        self.arclength[cases] += reach
        self.accepted[cases] += 1
        self.indicators[cases] = indicators
        self.record(cases, steps.y_new, steps.aux)

    def _end_stages(
        self, cases: np.ndarray, is_cut: np.ndarray, cut_column: np.ndarray, indicators: np.ndarray
    ) -> None:
        """End the stage of ``cases`` at a stop event or its target; fail cases out of steps.

        A case that reached its target enters the next stage (and stores its
        state there again, see :meth:`enter`).
        """
        stops = self.stop_table[self.stage_index[cases], cut_column]
        stop_hit = is_cut & (cut_column != TARGET_COLUMN) & stops
        # A cut at (or a rounding error past) the target ends the stage too.
        at_target = (cut_column == TARGET_COLUMN) | (indicators[:, TARGET_COLUMN] >= 0)
        target_hit = is_cut & ~stop_hit & at_target
        self.stop(cases[stop_hit], cut_column[stop_hit])
        too_many = (self.accepted[cases] >= self.options.max_steps) & ~target_hit & ~stop_hit
        self.fail_max_steps(cases[too_many])
        self.enter_next_stage(cases[target_hit])

    def stop(self, cases: np.ndarray, columns: np.ndarray) -> None:
        """Cases ``cases`` stop at the stop event of indicator column ``columns`` (per case)."""
        for column in np.unique(columns):
            which = cases[columns == column]
            name = INDICATOR_EVENTS[column]
            number = self.stage_index[which[0]] + 1
            self.end(which, f"stopped:{name}", f"stopped at {name} in stage {number}")

    def fail_max_steps(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: ``max_steps`` accepted steps before the end of the programme."""
        self.fail(
            cases,
            "max_steps",
            f"reached max_steps = {self.options.max_steps} accepted steps before the end of the "
            "programme",
        )

    def enter_next_stage(self, cases: np.ndarray) -> None:
        """Cases ``cases`` reached their stage target: they enter the next stage."""
        if cases.size:
            # Stage indices before any case enters its next stage (enter() updates them).
            finished_index = self.stage_index[cases].copy()
            for k in np.unique(finished_index):
                self.enter(cases[finished_index == k], int(k) + 1)


def _compiled_stepper(
    batch: CaseBatch, programme: LoadingProgramme, options: PathOptions, secondary_contacts: str
) -> CompiledStages | None:
    """The compiled stage loop where ``options.backend`` asks for it and it applies.

    Raises RuntimeError (from :func:`ncstab.paths.compiled.stage_runner`) when
    the compiled backend is asked for and numba is missing.
    """
    if options.backend != "compiled":
        return None
    from ncstab.paths import compiled

    if not compiled.NUMBA_AVAILABLE:
        compiled.stage_runner(batch)  # raises, naming the extra to install
    if compiled.unsupported_reason(batch, programme, secondary_contacts) is not None:
        return None
    from ncstab.paths.compiled_stages import CompiledStages

    return CompiledStages(batch, compiled.stage_runner(batch))


def follow_cases(
    batch: CaseBatch,
    programme: LoadingProgramme,
    values: dict[str, np.ndarray],
    options: PathOptions,
    secondary_contacts: str = "activate",
    progress: Callable[[int], None] | None = None,
) -> CaseResult:
    """Follow a loading programme for a batch of cases of one law.

    Parameters
    ----------
    batch
        The cases (system + law with parameter arrays of shape (B,)).
    programme
        Validated loading programme.
    values
        Every named parameter the programme refers to, as arrays ``(B,)``.
    options
        Engine options.
    secondary_contacts
        ``"activate"``, ``"ignore"`` or ``"stop"`` (see ``SystemSpec``).
    progress
        Called with the number of cases that just ended (progress bars).

    Returns
    -------
    CaseResult
    """
    return _BatchStepper(batch, programme, values, options, secondary_contacts, progress).run()
