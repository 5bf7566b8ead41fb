"""Where a step of the numpy stepper is cut, and what happens at the cut point.

A step is cut at its first located crossing that ends the stage (the target,
the end of a cycle's turn), stops the case (a stop event), switches a contact
(a gap closing or opening) or leaves along a bifurcating branch (a pending
branch switch).  At the cut point the contact state switches
(:func:`ncstab.paths.contacts.switch_contacts`), the branch is switched
(:func:`ncstab.paths.branch_switching.switch_branch`), or the turn closes
(:class:`ncstab.paths.cycle_turns.CycleTurns`); dy/ds, the auxiliary
quantities and the indicators then hold at the cut state.  Each function
acts on the stepper (:class:`ncstab.paths.stepper.BatchStepper`) and its
pass's :class:`~ncstab.paths.accepted_steps.AcceptedSteps`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.accepted_steps import AcceptedSteps, indicators_at
from ncstab.paths.contacts import switch_contacts
from ncstab.paths.rhs import state_derivative

if TYPE_CHECKING:
    from ncstab.paths.stepper import BatchStepper

__all__ = [
    "close_turns",
    "cut_points",
    "drop_limit_points_at_bifurcations",
    "move_to_cut_points",
    "switch_branches_at",
    "switch_contacts_at",
]


def drop_limit_points_at_bifurcations(stepper: BatchStepper, crossings: Any, h: np.ndarray) -> None:
    """A zero of det K where the branch test also changes sign is a simple bifurcation
    point, not a limit point: its det K crossing is dropped (in ``crossings``).

    The two roots are located independently to event_tol; they count as one
    point within 1e-6 of the step (a limit point that close to a
    bifurcation is not generic).
    """
    column = stepper.columns.bifurcation
    if column is None:
        return
    branch = crossings.sigma[:, column]
    for limit in stepper.event_column["limit_point"]:
        with np.errstate(invalid="ignore"):
            same = np.isfinite(branch) & (np.abs(crossings.sigma[:, limit] - branch) <= 1e-6 * h)
        crossings.sigma[same, limit] = np.inf


def cut_points(
    stepper: BatchStepper, steps: AcceptedSteps, change: np.ndarray, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Where each step is cut: at its first crossing that ends the stage or the case.

    The crossings that cut are those of the target and cycle columns, of
    stop events and of contact switches.  Returns the mask of the cut
    steps, the column that cuts each step and the step length kept (to the
    cut point, else the whole step).
    """
    stops = stepper.stop_table[stepper.stage_index[steps.cases]]
    cutting = change & (stops | stepper.break_columns[None, :])
    if stepper.columns.bifurcation is not None:  # a pending branch switch cuts the step there
        pending = (steps.stage.switch != 0) & ~steps.stage.switched
        cutting[:, stepper.columns.bifurcation] |= change[:, stepper.columns.bifurcation] & pending
    cutting[:, stepper.columns.target] = change[:, stepper.columns.target]
    cutting[:, stepper.columns.cycle] = change[:, stepper.columns.cycle]
    cut_sigma = np.where(cutting, sigma, np.inf)
    cut_column = np.argmin(cut_sigma, axis=1)
    rows = np.arange(steps.cases.size)
    is_cut = np.isfinite(cut_sigma[rows, cut_column])
    reach = np.where(is_cut, cut_sigma[rows, cut_column], steps.h)
    return is_cut, cut_column, reach


def move_to_cut_points(
    stepper: BatchStepper,
    steps: AcceptedSteps,
    crossings: Any,
    cut_rows: np.ndarray,
    cut_column: np.ndarray,
    indicators: np.ndarray,
) -> None:
    """The steps ``cut_rows`` end at their located cut points instead (in ``steps``).

    Contacts switch and cycle turns close there; dy/ds, the auxiliary
    quantities and the ``indicators`` are updated to the cut states.
    """
    steps.y_new[cut_rows] = crossings.located_y(cut_rows, cut_column[cut_rows])
    closing = cut_rows[stepper.break_columns[cut_column[cut_rows]]]
    if closing.size:
        switch_contacts_at(stepper, steps, closing, cut_column)
    if stepper.columns.bifurcation is not None:
        leaving = cut_rows[(cut_column[cut_rows] == stepper.columns.bifurcation) & (steps.stage.switch[cut_rows] != 0)]
        if leaving.size:
            switch_branches_at(stepper, steps, leaving)
    close_turns(stepper, steps, cut_rows, cut_column)
    batch, stage = steps.batch.take(cut_rows), steps.stage.take(cut_rows)
    dy_cut, aux_cut = state_derivative(batch, stage, steps.y_new[cut_rows], stepper.layout)
    steps.dy_new[cut_rows] = dy_cut
    indicators_cut = indicators_at(batch, stage, steps.y_new[cut_rows], aux_cut, stepper.layout)
    # Keep the post-crossing sign of a break column (secondary contact)
    # so the same crossing is not detected twice.
    column_cut = cut_column[cut_rows]
    brk = np.flatnonzero(stepper.break_columns[column_cut])
    indicators_cut[brk, column_cut[brk]] = indicators[cut_rows[brk], column_cut[brk]]
    # Another break column already past zero at the cut point (a simultaneous crossing,
    # on that side by rounding) keeps its sign from before the piece, so the next piece
    # sees its crossing and switches it too (else it would never switch).
    before = stepper.indicators[steps.cases[cut_rows]]
    simultaneous = stepper.break_columns[None, :] & (np.sign(indicators_cut) * np.sign(before) < 0)
    simultaneous[np.arange(cut_rows.size), column_cut] = False
    indicators_cut = np.where(simultaneous, before, indicators_cut)
    indicators[cut_rows] = indicators_cut
    # Writable copies (fields may be read-only views).
    steps.aux = steps.aux.take(np.arange(steps.cases.size))
    steps.aux.put(cut_rows, aux_cut)


def switch_contacts_at(stepper: BatchStepper, steps: AcceptedSteps, closing: np.ndarray, cut_column: np.ndarray) -> None:
    """Switch the contact state of rows ``closing``, cut at a break column.

    The direction of motion is kept: the orientation flips where the
    switch flips the cofactor tangent.
    """
    bits = np.asarray(stepper.columns.switch_bits)[cut_column[closing]]
    switched = steps.stage.take(closing)
    steps.y_new[closing], flip = switch_contacts(
        steps.batch.take(closing), switched, steps.y_new[closing], bits, cut_column[closing], stepper.layout
    )
    steps.stage.secondary_state[closing] = switched.secondary_state
    stepper.stages.secondary_state[steps.cases[closing]] = switched.secondary_state
    steps.stage.orientation[closing[flip]] *= -1
    stepper.stages.orientation[steps.cases[closing[flip]]] *= -1
    # The motion continues from the switch: no reference across it.
    steps.stage.reference[closing] = np.nan


def switch_branches_at(stepper: BatchStepper, steps: AcceptedSteps, rows: np.ndarray) -> None:
    """Rows ``rows`` are cut at a simple bifurcation point with a switch pending: they
    leave along the bifurcating branch (:func:`ncstab.paths.branch_switching.switch_branch`),
    the motion there becoming the reference the next tangents continue."""
    from ncstab.paths.branch_switching import leave_along_branch

    batch, stage = steps.batch.take(rows), steps.stage.take(rows)
    incoming = np.concatenate([steps.aux.dv[rows], steps.aux.dlam[rows, None]], axis=-1)
    steps.y_new[rows], motion = leave_along_branch(batch, stage, steps.y_new[rows], incoming, stepper.layout,
                                                   stepper.options)
    steps.stage.reference[rows] = motion
    steps.stage.switched[rows] = True
    stepper.stages.switched[steps.cases[rows]] = True
    stepper.branch_index[steps.cases[rows]] = stage.switch


def close_turns(stepper: BatchStepper, steps: AcceptedSteps, cut_rows: np.ndarray, cut_column: np.ndarray) -> None:
    """Close a turn where a cycle stage's step is cut at its cycle (or target) column.

    Stores the work over the turn, the force gap and the drift of T, and
    counts the turn.
    """
    column_cut = cut_column[cut_rows]
    turns_here = stepper.turns.turns[stepper.stage_index[steps.cases[cut_rows]]]
    ends_turn = (
        ((column_cut == stepper.columns.cycle) | (column_cut == stepper.columns.target))
        & steps.stage.is_cycle[cut_rows]
        & (steps.stage.cycles_done[cut_rows] < turns_here)
    )
    rows = cut_rows[ends_turn]
    if rows.size == 0:
        return
    _, aux = state_derivative(steps.batch.take(rows), steps.stage.take(rows), steps.y_new[rows], stepper.layout)
    cases = steps.cases[rows]
    turn = steps.stage.cycles_done[rows]
    work = steps.y_new[rows, stepper.layout.work]
    stepper.turns.close(cases, stepper.stage_index[cases], turn, work, aux.evaluation)
    steps.stage.cycles_done[rows] += 1
    stepper.stages.cycles_done[cases] += 1
