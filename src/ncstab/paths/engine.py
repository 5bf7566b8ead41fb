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
from typing import Callable

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
from ncstab.paths.integrator import END_STAGE, ERROR_EXPONENT, dense_output, dop853_step, evaluate_dense
from ncstab.paths.model import CaseBatch, Evaluation
from ncstab.paths.options import PathOptions
from ncstab.paths.programme import CURRENT, EVENTS, CycleStage, LoadingProgramme, Stage
from ncstab.paths.tangent_field import StageArrays, control_matrix, path_tangent

__all__ = ["CaseResult", "follow_cases"]

RUNNING = "running"
FINISHED = "finished"


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
            self.capacity = max(needed, 16)
            self.arrays = {
                key: self._blank((self.size, self.capacity) + value.shape[1:], value.dtype)
                for key, value in values.items()
            }
        elif needed > self.capacity:
            capacity = max(needed, 2 * self.capacity)
            for key, array in self.arrays.items():
                grown = self._blank((self.size, capacity) + array.shape[2:], array.dtype)
                grown[:, : self.capacity] = array
                self.arrays[key] = grown
            self.capacity = capacity
        flat = case * self.capacity + position  # one 1-D index for every field
        for key, value in values.items():
            array = self.arrays[key]
            array.reshape((self.size * self.capacity,) + array.shape[2:])[flat] = value
        self.count[case] += 1

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


def _empty_events(size: int, n: int) -> dict[str, dict[str, np.ndarray]]:
    def table() -> dict[str, np.ndarray]:
        return {
            "found": np.zeros(size, dtype=bool),
            "s": np.full(size, np.nan),
            "s_lower": np.full(size, np.nan),
            "s_upper": np.full(size, np.nan),
            "stage": np.full(size, -1, dtype=int),
            "lam": np.full(size, np.nan),
            "u": np.full((size, n), np.nan),
            "F": np.full((size, n), np.nan),
            "l": np.full(size, np.nan),
            "alpha": np.full(size, np.nan),
            "N": np.full(size, np.nan),
            "T": np.full(size, np.nan),
            "K": np.full((size, n, n), np.nan),
        }

    return {name: table() for name in EVENTS}


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
    size = batch.size
    n = batch.n_dof
    layout = _Layout(n, batch.n_internal)
    dofs, forces = batch.system.dof_names, batch.system.force_names
    y = np.zeros((size, layout.size))
    y[:, layout.v] = batch.initial_state()
    # dy/ds at each case's current state (first same as last for the next step).
    derivative = np.full((size, layout.size), np.nan)
    stage_index = np.zeros(size, dtype=int)
    status = np.full(size, RUNNING, dtype=object)
    message = np.full(size, "", dtype=object)
    step_size = np.full(size, options.initial_step)
    arclength = np.zeros(size)
    accepted_count = np.zeros(size, dtype=int)
    rejected_count = np.zeros(size, dtype=int)
    located_count = np.zeros(size, dtype=int)
    previous = np.full((size, len(INDICATOR_EVENTS)), np.nan)
    stages = StageArrays.empty(size, n)
    stages.secondary_state[:] = batch.initial_secondary_state(y[:, layout.v])
    recorder = _Recorder(size)
    events = _empty_events(size, n)

    event_column = {name: [i for i, e in enumerate(INDICATOR_EVENTS) if e == name] for name in EVENTS}
    stop_table = np.zeros((len(programme), len(INDICATOR_EVENTS)), dtype=bool)
    for k, stage in enumerate(programme.stages):
        for name in stage.stop_at:
            stop_table[k, event_column[name]] = True
        if secondary_contacts == "stop":
            stop_table[k, event_column["secondary_contact"]] = True
    cycle_turns = np.array([st.turns if isinstance(st, CycleStage) else 0 for st in programme.stages])
    cycle_offset = np.concatenate([[0], np.cumsum(cycle_turns)])[:-1].astype(int)
    n_cycles = int(cycle_turns.sum())
    cycles = {
        "work": np.full((size, n_cycles), np.nan),
        "force_gap": np.full((size, n_cycles, n), np.nan),
        "tangential_drift": np.full((size, n_cycles), np.nan),
        "stage": np.repeat(np.arange(len(programme)), cycle_turns).astype(int),
    }
    cycle_start_work = np.zeros(size)
    cycle_start_forces = np.zeros((size, n))
    cycle_start_tangential = np.zeros(size)
    break_columns = np.zeros(len(INDICATOR_EVENTS), dtype=bool)
    if secondary_contacts == "activate":
        break_columns[event_column["secondary_contact"]] = True
    # A no_tension law's contact opening/closing is a switch of smooth branch.
    break_columns[INDICATOR_EVENTS.index("normal_contact")] = True

    def fail(index: np.ndarray, reason: str, text: str | np.ndarray) -> None:
        if index.size:
            status[index] = f"failed:{reason}"
            message[index] = text
            if progress:
                progress(index.size)

    def end(index: np.ndarray, state: str, text: str | np.ndarray) -> None:
        if index.size:
            status[index] = state
            message[index] = text
            if progress:
                progress(index.size)

    def record(index: np.ndarray, yy: np.ndarray, aux: _Aux) -> None:
        ev = aux.evaluation
        recorder.add(
            index,
            s=arclength[index],
            stage=stage_index[index],
            u=ev.displacements,
            lam=yy[:, layout.lam],
            internal=yy[:, layout.internal],
            work=yy[:, layout.work],
            F=ev.forces,
            l=ev.q[:, 0, 0],
            alpha=ev.q[:, 0, 1],
            N=ev.normal[:, 0],
            T=ev.tangential[:, 0],
            K=ev.stiffness,
            du=aux.du,
            dlam=aux.dlam,
        )

    def resolve(value: float | str, index: np.ndarray, current: dict[str, np.ndarray]) -> np.ndarray:
        if isinstance(value, str):
            if value == CURRENT:
                raise AssertionError("resolved by caller")
            return np.asarray(values[value], dtype=float)[index] if np.ndim(values[value]) else np.full(
                index.size, float(values[value])
            )
        return np.full(index.size, float(value))

    def enter(index: np.ndarray, k: int) -> None:
        """Cases ``index`` start stage k (vectorized; zero-length stages cascade)."""
        while index.size:
            if k >= len(programme):
                end(index, FINISHED, f"finished all {len(programme)} loading stage(s)")
                return
            stage = programme.stages[k]
            stage_index[index] = k
            sub = batch.take(index)
            v, internal = y[index][:, layout.v], y[index][:, layout.internal]
            evaluation = sub.evaluate(v, internal, stages.secondary_state[index])
            u = evaluation.displacements
            current = {name: u[:, i] for i, name in enumerate(dofs)}
            current.update({name: evaluation.forces[:, i] for i, name in enumerate(forces)})
            arrays = StageArrays.empty(index.size, n)
            arrays.secondary_state = stages.secondary_state[index].copy()
            bad = np.zeros(index.size, dtype=bool)
            reasons = np.full(index.size, "", dtype=object)
            if isinstance(stage, Stage):
                controls = stage.controls()
                driven_name, target = stage.driven
                for i, (dof, force) in enumerate(zip(dofs, forces)):
                    name = force if force in controls else dof
                    arrays.force_controlled[:, i] = name == force
                    arrays.offset[:, i] = current[name]
                    if name == driven_name:
                        arrays.offset[:, i] = 0.0
                        arrays.slope[:, i] = 1.0
                    elif controls[name] != CURRENT:
                        nominal = resolve(controls[name], index, current)
                        mismatch = np.abs(nominal - current[name]) > 1e-9 * (1 + np.abs(nominal))
                        hint = np.where(
                            (stages.secondary_state[index] & 3) != 0,
                            " (secondary-contact springs already act at this state: with "
                            "secondary_contacts = 'activate' the grains overlap at rest unless "
                            "alpha0 is in [pi/6, pi/3])",
                            "",
                        )
                        text = (
                            f"stage {k + 1} holds {name} = {controls[name]} but {name} is not at that "
                            "value when the stage starts; add a stage that drives it there first"
                        )
                        reasons[mismatch] = np.char.add(text, hint[mismatch].astype(str)).astype(object)
                        bad |= mismatch
                start = current[driven_name]
                arrays.lam_end = resolve(target, index, current)
                arrays.target_sign = np.sign(arrays.lam_end - start)
                lam = start
            else:
                assert isinstance(stage, CycleStage)
                center = np.column_stack([resolve(c, index, current) for c in stage.center])
                relative = u - center
                arrays.is_cycle[:] = True
                arrays.center = center
                arrays.radius = np.hypot(relative[:, 0], relative[:, 1])
                arrays.theta0 = np.arctan2(relative[:, 1], relative[:, 0])
                arrays.turn_direction[:] = stage.direction
                arrays.lam_end[:] = 2 * math.pi * stage.turns
                arrays.target_sign[:] = 1.0
                lam = np.zeros(index.size)
                zero = arrays.radius <= 1e-14
                reasons[zero] = f"stage {k + 1}: the state is at the centre of the cycle (zero radius)"
                bad |= zero
            y[index, layout.lam] = lam
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
            stages.put(index, arrays)
            for reason in np.unique(reasons[bad]):
                which = index[bad & (reasons == reason)]
                fail(which, "singular_control" if "singular" in reason else "bad_stage_start", reason)
            go = ~bad & ~zero_length
            if go.any() or not recorder.started:
                gi = index[go]
                sub_go = batch.take(gi)
                st_go = stages.take(gi)
                dy, aux = _rhs(sub_go, st_go, y[gi], layout)
                derivative[gi] = dy
                previous[gi] = _indicators(sub_go, st_go, y[gi], aux, layout)
                record(gi, y[gi], aux)
                cycle_start_work[gi] = y[gi, layout.work]
                cycle_start_forces[gi] = aux.evaluation.forces
                cycle_start_tangential[gi] = aux.evaluation.tangential[:, 0]
            index, k = index[zero_length], k + 1

    enter(np.arange(size), 0)

    while True:
        active = np.flatnonzero(status == RUNNING)
        if active.size == 0:
            break
        sub = batch.take(active) if active.size < size else batch
        st = stages.take(active)
        y0 = y[active]
        h0 = np.minimum(step_size[active], options.max_step)
        y1, err, y_raw, stages_k, end_aux = _advance(sub, st, y0, h0, layout, options, derivative[active])
        accept = err <= 1.0
        with np.errstate(divide="ignore", invalid="ignore"):
            factor = np.where(err == 0, 10.0, np.clip(0.9 * err**ERROR_EXPONENT, 0.2, 10.0))
        factor = np.where(np.isfinite(err), factor, 0.25)
        factor = np.where(accept, factor, np.minimum(factor, 0.9))
        step_size[active] = np.clip(h0 * factor, 0.0, options.max_step)
        rejected_count[active[~accept]] += 1
        underflow = ~accept & (step_size[active] < options.min_step)
        fail(
            active[underflow],
            "step_size_underflow",
            "the step size fell below min_step: the path cannot be continued "
            "(non-convergent Newton projection, a kink or a singular point)",
        )
        local = np.flatnonzero(accept)
        if local.size == 0:
            continue
        cases = active[local]
        if local.size == active.size:  # every step accepted: no copies (st is a copy of stages already)
            sub_a, st_a, y_start, h_a, y_new, y_raw_a, stages_a = sub, st, y0, h0, y1, y_raw, stages_k
            if isinstance(end_aux, _Aux):
                dy_new, aux = stages_k[END_STAGE].copy(), end_aux
            else:
                dy_new, aux = _rhs(sub_a, st_a, y_new, layout, end_aux)
        else:
            sub_a = sub.take(local)
            st_a = st.take(local)
            y_start = y0[local]
            h_a = h0[local]
            y_new = y1[local]
            y_raw_a = y_raw[local]
            stages_a = stages_k[:, local]
            if isinstance(end_aux, _Aux):  # the last DOP853 stage was evaluated at the end state
                dy_new, aux = stages_k[END_STAGE][local], end_aux.take(local)
            else:  # the Newton projection's last evaluation, where it covers every case
                dy_new, aux = _rhs(sub_a, st_a, y_new, layout, None if end_aux is None else end_aux.take(local))
        q = aux.evaluation.q
        length, angle = q[:, 0, 0], q[:, 0, 1]
        finite = np.isfinite(y_new).all(-1) & np.isfinite(aux.evaluation.forces).all(-1)
        outside = ~finite | ~(length > 0) | ~(np.abs(angle) < math.pi / 2)
        if outside.any():
            why = np.where(
                ~finite,
                "non-finite numbers",
                np.where(~(length > 0), "l* <= 0", "alpha outside (-pi/2, pi/2)"),
            )
            for reason in np.unique(why[outside]):
                which = outside & (why == reason)
                fail(
                    cases[which],
                    "left_domain",
                    f"the path left the admissible domain ({reason}) in stage "
                    f"{stage_index[cases[which][0]] + 1}",
                )
        keep = np.flatnonzero(~outside)
        if keep.size == 0:
            continue
        if keep.size < cases.size:
            cases, sub_a, st_a = cases[keep], sub_a.take(keep), st_a.take(keep)
            y_start, h_a, y_new = y_start[keep], h_a[keep], y_new[keep]
            y_raw_a, stages_a = y_raw_a[keep], stages_a[:, keep]
            aux = aux.take(keep)
            dy_new = dy_new[keep]
        indicators = _indicators(sub_a, st_a, y_new, aux, layout)
        before = previous[cases]
        change = np.sign(before) * np.sign(indicators) < 0
        change[:, TARGET_COLUMN] = (before[:, TARGET_COLUMN] < 0) & (indicators[:, TARGET_COLUMN] >= 0)

        crossings = _locate_crossings(
            sub_a, st_a, change, before, indicators, y_start, y_raw_a, y_new, h_a, stages_a, layout, options
        )
        sigma = crossings.sigma
        located_count[cases] += crossings.located

        cutting = change & (stop_table[stage_index[cases]] | break_columns[None, :])
        cutting[:, TARGET_COLUMN] = change[:, TARGET_COLUMN]
        cutting[:, CYCLE_COLUMN] = change[:, CYCLE_COLUMN]
        cut_sigma = np.where(cutting, sigma, np.inf)
        cut_column = np.argmin(cut_sigma, axis=1)
        is_cut = np.isfinite(cut_sigma[np.arange(cases.size), cut_column])
        reach = np.where(is_cut, cut_sigma[np.arange(cases.size), cut_column], h_a)

        _store_first_events(
            events, event_column, cases, crossings, reach + options.event_tol, arclength, stage_index,
            sub_a, st_a, layout,
        )

        # Advance: to the step end, or to the located cut point.
        cut_rows = np.flatnonzero(is_cut)
        y_new = y_new.copy()
        if cut_rows.size:
            y_new[cut_rows] = crossings.located_y(cut_rows, cut_column[cut_rows])
            closing = cut_rows[break_columns[cut_column[cut_rows]]]
            if closing.size:
                gap = np.asarray(INDICATOR_GAP)[cut_column[closing]]
                switched = st_a.take(closing)
                y_new[closing], flip = _switch_contacts(sub_a.take(closing), switched, y_new[closing], gap, layout)
                st_a.secondary_state[closing] = switched.secondary_state
                stages.secondary_state[cases[closing]] = switched.secondary_state
                st_a.orientation[closing[flip]] *= -1
                stages.orientation[cases[closing[flip]]] *= -1
            column_cut = cut_column[cut_rows]
            turns_here = cycle_turns[stage_index[cases[cut_rows]]]
            ends_cycle = (
                ((column_cut == CYCLE_COLUMN) | (column_cut == TARGET_COLUMN))
                & st_a.is_cycle[cut_rows]
                & (st_a.cycles_done[cut_rows] < turns_here)
            )
            cyc = cut_rows[ends_cycle]
            if cyc.size:
                # One turn of a cycle stage closed: work, force gap, T drift.
                _, ax_cyc = _rhs(sub_a.take(cyc), st_a.take(cyc), y_new[cyc], layout)
                where = cases[cyc]
                slot = cycle_offset[stage_index[where]] + st_a.cycles_done[cyc]
                cycles["work"][where, slot] = y_new[cyc, layout.work] - cycle_start_work[where]
                cycles["force_gap"][where, slot] = ax_cyc.evaluation.forces - cycle_start_forces[where]
                cycles["tangential_drift"][where, slot] = ax_cyc.evaluation.tangential[:, 0] - cycle_start_tangential[where]
                cycle_start_work[where] = y_new[cyc, layout.work]
                cycle_start_forces[where] = ax_cyc.evaluation.forces
                cycle_start_tangential[where] = ax_cyc.evaluation.tangential[:, 0]
                st_a.cycles_done[cyc] += 1
                stages.cycles_done[where] += 1
            b, s_ = sub_a.take(cut_rows), st_a.take(cut_rows)
            dy_cut, ax_cut = _rhs(b, s_, y_new[cut_rows], layout)
            dy_new[cut_rows] = dy_cut
            ind_cut = _indicators(b, s_, y_new[cut_rows], ax_cut, layout)
            # Keep the post-crossing sign of a break column (secondary contact)
            # so the same crossing is not detected twice.
            brk = np.flatnonzero(break_columns[column_cut])
            ind_cut[brk, column_cut[brk]] = indicators[cut_rows[brk], column_cut[brk]]
            indicators[cut_rows] = ind_cut
            aux = aux.take(np.arange(cases.size))  # writable copies (fields may be read-only views)
            aux.put(cut_rows, ax_cut)
        y[cases] = y_new
        derivative[cases] = dy_new
        arclength[cases] += reach
        accepted_count[cases] += 1
        previous[cases] = indicators
        record(cases, y_new, aux)

        # Stage ends: target reached, or a stop event.
        stop_hit = is_cut & (cut_column != TARGET_COLUMN) & stop_table[stage_index[cases], cut_column]
        # A cut at (or a rounding error past) the target ends the stage too.
        target_hit = is_cut & ~stop_hit & ((cut_column == TARGET_COLUMN) | (indicators[:, TARGET_COLUMN] >= 0))
        for column in np.unique(cut_column[stop_hit]):
            which = cases[stop_hit & (cut_column == column)]
            name = INDICATOR_EVENTS[column]
            end(which, f"stopped:{name}", f"stopped at {name} in stage {stage_index[which[0]] + 1}")
        too_many = (accepted_count[cases] >= options.max_steps) & ~target_hit & ~stop_hit
        fail(
            cases[too_many],
            "max_steps",
            f"reached max_steps = {options.max_steps} accepted steps before the end of the programme",
        )
        if target_hit.any():
            finished_stage = cases[target_hit]
            # Stage indices before any case enters its next stage (enter() updates them).
            finished_index = stage_index[finished_stage].copy()
            for k in np.unique(finished_index):
                enter(finished_stage[finished_index == k], int(k) + 1)

    steps, counts = recorder.assemble()
    return CaseResult(
        steps=steps,
        n_steps=counts,
        status=status.astype(str),
        message=message.astype(str),
        events=events,
        counters={"accepted": accepted_count, "rejected": rejected_count, "located": located_count},
        cycles=cycles,
    )
