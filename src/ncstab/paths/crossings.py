"""Sign changes of the indicators over an accepted step: located, stored as events.

Every (case, column) pair whose indicator changes sign over a step is one
root search on the step length, on the DOP853 interpolant of the step,
projected onto equilibrium for laws with a total form
(:func:`ncstab.paths.events.locate_sign_changes`).  The first occurrence of
each event is stored with its bracket and the state there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ncstab.paths.events import STIFFNESS_COLUMNS, IndicatorLayout, indicator_values, locate_sign_changes
from ncstab.paths.integrator import dense_output, evaluate_dense
from ncstab.paths.options import PathOptions
from ncstab.paths.programme import EVENTS, LoadingProgramme
from ncstab.paths.projection import project_finite
from ncstab.paths.rhs import StateLayout, evaluate_at, state_derivative, tangent_at
from ncstab.paths.tangent_field import StageArrays

__all__ = ["Crossings", "event_tables", "locate_crossings", "store_first_events"]


@dataclass
class Crossings:
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


def locate_crossings(
    batch: Any,
    stage: StageArrays,
    change: np.ndarray,
    before: np.ndarray,
    after: np.ndarray,
    y_start: np.ndarray,
    y_raw: np.ndarray,
    y_end: np.ndarray,
    h: np.ndarray,
    stages_k: np.ndarray,
    layout: StateLayout,
    options: PathOptions,
    piece: Any = None,
) -> Crossings:
    """Locate every indicator sign change of a step on the DOP853 interpolant.

    Root finding (Illinois) on the step length, each evaluation on the 7th-order
    interpolant and, for laws with a total form, projected onto equilibrium.
    ``piece``: where the step is a piece of a longer step
    (:mod:`ncstab.paths.step_pieces`), its ``dense`` coefficients, ``step_start``,
    ``step_length`` and ``offset`` in it: the interpolant is the longer step's, at
    ``(offset + sigma) / step_length``.
    """
    columns_of = batch.columns
    target_column = columns_of.target
    rows_n, n_cols = change.shape
    sigma = np.full((rows_n, n_cols), np.inf)
    lower = np.full((rows_n, n_cols), np.nan)
    upper = np.full((rows_n, n_cols), np.nan)
    exact_target = change[:, target_column] & (after[:, target_column] == 0)
    searched = change.copy()
    searched[:, target_column] &= ~exact_target
    # Every (row, column) pair with a sign change is one root search; all
    # pairs of the step advance together (each pair's iterates depend on that
    # pair only, so this equals one search per column, with fewer passes).
    pair_row, pair_column = np.nonzero(searched)
    located = np.bincount(pair_row, minlength=rows_n)
    if pair_row.size:
        # DOP853 interpolant over the step (3 extra stages, only where needed).
        if piece is None:
            needs = np.flatnonzero(searched.any(axis=1))
            b_n, s_n = batch.take(needs), stage.take(needs)
            coefficients = dense_output(
                lambda yy: state_derivative(b_n, s_n, yy, layout)[0], y_start[needs], y_raw[needs], h[needs],
                stages_k[:, needs],
            )
            slot_of_row = np.full(rows_n, -1)
            slot_of_row[needs] = np.arange(needs.size)

        def evaluate(index: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            pick = pair_row[index]
            b, s_ = batch.take(pick), stage.take(pick)
            if piece is None:
                yy = evaluate_dense(y_start[pick], coefficients[:, slot_of_row[pick]], lengths / h[pick])
            else:
                yy = evaluate_dense(
                    piece.step_start[pick], piece.dense[:, pick], (piece.offset[pick] + lengths) / piece.step_length[pick]
                )
            columns = pair_column[index]
            # The turning point and the branch test need the tangent; the columns built on K
            # (and the dynamic divergence) need K; gaps, overlaps, cycle ends and targets neither.
            turning = bool(np.isin(columns, [columns_of.turning, columns_of.bifurcation]).any())
            stiffness_columns = bool(((columns < STIFFNESS_COLUMNS) | (columns == columns_of.divergence)).any())
            if b.has_total_form:
                yy, _, evaluation = project_finite(b, s_, yy, np.zeros(pick.size), layout, options)
            else:
                evaluation = evaluate_at(b, s_, yy, layout, geometry_only=not (turning or stiffness_columns))
            lam = yy[:, layout.lam]
            tangent = tangent_at(evaluation, s_, lam) if turning else None
            dlam = tangent.dlam if turning else np.full(pick.size, np.nan)
            branch = tangent.branch if turning else None
            values = indicator_values(evaluation, s_, lam, dlam, stiffness_columns, columns_of, branch)
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
        sigma[rows, target_column] = lower[rows, target_column] = upper[rows, target_column] = h[rows]
        slot[rows, target_column] = pair_states.shape[0] + np.arange(rows.size)
        pair_states = np.concatenate([pair_states, y_end[rows]])
    return Crossings(sigma, lower, upper, slot, pair_states, located)


def store_first_events(
    events: dict[str, dict[str, np.ndarray]],
    event_column: dict[str, list[int]],
    cases: np.ndarray,
    crossings: Crossings,
    reach: np.ndarray,
    arclength: np.ndarray,
    stage_index: np.ndarray,
    batch: Any,
    stage: StageArrays,
    layout: StateLayout,
) -> None:
    """Store the first occurrence of each event located within ``reach`` (step length).

    ``reach`` includes the location tolerance, so an event that coincides with
    the cut point (a hyperelastic limit point is also a Hill loss) counts.
    """
    for name in EVENTS:
        columns = event_column[name]
        if not columns:
            continue
        sig = crossings.sigma[:, columns]
        best = np.argmin(sig, axis=1)
        best_sigma = sig[np.arange(cases.size), best]
        hit = np.isfinite(best_sigma) & (best_sigma <= reach) & ~events[name]["found"][cases]
        rows = np.flatnonzero(hit)
        if rows.size == 0:
            continue
        col = np.asarray(columns)[best[rows]]
        state = crossings.located_y(rows, col)
        sub_stage = stage.take(rows)
        _, ax = state_derivative(batch.take(rows), sub_stage, state, layout)
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
        for key, value in batch.record_interactions(ax.evaluation).items():
            table[key][target] = value
        if "load" in table:
            table["load"][target] = sub_stage.load(state[:, layout.lam])
        table["K"][target] = ax.evaluation.stiffness


def event_tables(
    programme: LoadingProgramme, secondary_contacts: str, columns: IndicatorLayout
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
    names = columns.events
    event_column = {name: [i for i, e in enumerate(names) if e == name] for name in EVENTS}
    stop_table = np.zeros((len(programme), len(names)), dtype=bool)
    for k, stage in enumerate(programme.stages):
        for name in stage.stop_at:
            stop_table[k, event_column[name]] = True
        if secondary_contacts == "stop":
            stop_table[k, event_column["secondary_contact"]] = True
    break_columns = np.zeros(len(names), dtype=bool)
    if secondary_contacts == "activate":
        break_columns[event_column["secondary_contact"]] = True
    break_columns[[i for i, e in enumerate(names) if e == "normal_contact"]] = True
    return event_column, stop_table, break_columns
