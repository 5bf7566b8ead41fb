"""The records the compiled stage loop passes around: a case's arrays in a few named groups.

The stage loop (:mod:`ncstab.paths.compiled`) reads and writes a few dozen
per-case arrays and settings.  Grouped here in named tuples, which numba
compiles as plain structures (a field read costs nothing; an array field is
the array itself, written in place), no function of the loop takes more
than a dozen parameters and each says what it works on:

* what the stepper holds per case (:class:`CaseRows`), per stage
  (:class:`StageRows`), its cycle turns (:class:`TurnTables`), its event
  tables (:class:`EventTables`) and what is stored (:class:`Records`), and the
  outcome of each case's call (:class:`Outcomes`); the model's rows
  (:class:`ModelRows`, with the model's record :class:`DiamondModel` or
  :class:`GeneralModel`, by whose type the loop picks the model's functions) and the
  options (:class:`StepSettings`): the arguments
  of ``run_cases`` and ``start`` (:mod:`ncstab.paths.loop_cases`,
  :mod:`ncstab.paths.loop_start`), built by
  :class:`ncstab.paths.compiled_stages.CompiledStages`;
* inside the loop, one case (:class:`Case`: its control, orientation, law,
  parameters and geometry), what its indicators compare with (:class:`Goal`)
  and the interpolant of a step (:class:`Interpolant`), a state's evaluation
  (:class:`Evaluation`) and a state with all that is known there
  (:class:`StateAt`).

Plain named tuples, without numba: the plain-Python route
(:mod:`ncstab.plain_python`) builds the same records.
"""

from __future__ import annotations

from typing import Any, NamedTuple

import numpy as np

__all__ = [
    "Case",
    "CaseRows",
    "DiamondModel",
    "EventColumns",
    "Evaluation",
    "EventTables",
    "GeneralModel",
    "Goal",
    "Interpolant",
    "MODEL_FUNCTIONS",
    "ModelRows",
    "Outcomes",
    "Records",
    "StageRows",
    "StateAt",
    "StepSettings",
    "TurnTables",
]


class CaseRows(NamedTuple):
    """The stepper's arrays, one row per case of the batch (:class:`ncstab.paths.stepper.BatchStepper`)."""

    y: np.ndarray  #: the state (M,) per case: (v, lambda, internal variables)
    derivative: np.ndarray  #: dy/ds there
    indicators: np.ndarray  #: the indicator columns' last values (events)
    step_size: np.ndarray  #: the next step's length (NaN: to be estimated)
    arclength: np.ndarray  #: s
    accepted: np.ndarray  #: accepted steps
    rejected: np.ndarray  #: rejected steps
    located: np.ndarray  #: sign changes located
    branch_size: np.ndarray  #: the branch test's size at the last piece's end (over_steps)
    over_length: np.ndarray  #: the over step planned next (0: none)
    over_degenerate: np.ndarray  #: whether it is a degenerate one
    degenerate_length: np.ndarray  #: the degenerate over step that may follow


class StageRows(NamedTuple):
    """The current stage's arrays, one row per case (``StageArrays``)."""

    force_controlled: np.ndarray  #: whether the stage controls the force (bool per case)
    control: np.ndarray  #: the control path's row (``control_rows``)
    lam_end: np.ndarray  #: the stage target's lambda
    target_sign: np.ndarray  #: the direction of lambda to the target
    orientation: np.ndarray  #: +1 or -1: the tangent's orientation
    reference: np.ndarray  #: the motion at the last piece's end (orientation by continuity)
    secondary_state: np.ndarray  #: the contact-state bits (int64)
    cycles_done: np.ndarray  #: the turns closed so far (cycle stages)
    switch_pending: np.ndarray  #: the stage switches branch at a simple bifurcation point, not done yet


class TurnTables(NamedTuple):
    """The turns of a cycle stage: how many, the first one's slot, and per case and slot
    whether it closed and (W, F1, F2, T) where."""

    count: int
    first: int
    closed: np.ndarray
    values: np.ndarray


class EventTables(NamedTuple):
    """The stage's stop and switch columns and the first events located (``EVENTS``)."""

    stop_row: np.ndarray  #: per indicator column: whether its crossing stops the stage
    break_row: np.ndarray  #: per indicator column: whether its crossing switches a contact
    columns: np.ndarray  #: per event: its indicator columns (-1: none)
    found: np.ndarray  #: (event, case): located already
    values: np.ndarray  #: (event, case, field): the located state's fields (``EVENT_FIELDS``)
    stage: np.ndarray  #: (event, case): the stage where it was located


class Records(NamedTuple):
    """What ``store_record`` writes: the recorder's arrays, their count per case, and the
    stage number the states belong to."""

    arrays: tuple
    count: np.ndarray
    stage_number: int


class Outcomes(NamedTuple):
    """How each case's call ended (:class:`ncstab.paths.compiled.Outcome`) and its detail."""

    code: np.ndarray
    detail: np.ndarray


#: What the shared modules of the loop ask of a model (:mod:`ncstab.paths.loop_dispatch`):
#: sizes, event columns, the contact state, the evaluation and dy/ds (``rhs``, and
#: ``rhs_hot`` inlined where every DOP853 stage calls it), the tangent, the Newton
#: projection, the indicators, the domain check, the arc of an over step, and what is
#: stored.  The module of each kind of model defines them all, with the same parameters.
MODEL_FUNCTIONS = (
    "state_size", "ev_size", "aux_size", "motion_size", "event_columns", "switch_bit", "next_state", "cuts_always",
    "set_state", "tries_degenerate", "evaluate", "rhs", "rhs_hot", "tangent_at", "no_tangent", "was_flipped",
    "alignment", "branch_size", "set_reference", "motion", "motion_product", "indicators", "state_indicator",
    "project", "domain_detail", "arc_through", "turn_record", "store_record", "store_event",
)


class DiamondModel(NamedTuple):
    """The record of a reduced diamond (:mod:`ncstab.paths.loop_diamond`): the loop's
    model functions are the diamond's (:mod:`ncstab.paths.loop_dispatch`)."""

    rate_form: bool  #: whether the law has a rate form (T an internal variable, no Newton projection)


class GeneralModel(NamedTuple):
    """The record of a general model (:mod:`ncstab.paths.loop_general`): the loop's
    model functions are a general model's (:mod:`ncstab.paths.loop_dispatch`)."""

    rate_form: bool  #: whether some law of the model has no total form (no Newton projection)


class EventColumns(NamedTuple):
    """Where a model's event indicators are (:mod:`ncstab.paths.events`): how many columns,
    and those of the stage target, of the end of a turn, of dlambda (turning points), of
    the branch test (simple bifurcation points), of det K (limit points) and of the mixed
    control's determinant (loss of controllability)."""

    count: int
    target: int
    cycle: int
    turning: int
    bifurcation: int
    limit: int
    control: int


class ModelRows(NamedTuple):
    """The model the loop evaluates: its record (:class:`DiamondModel` or
    :class:`GeneralModel`), the law's (or model kernel's) C callback and each case's row
    of parameters and of geometry."""

    kind: Any
    law: Any
    parameters: np.ndarray
    geometry: np.ndarray


class StepSettings(NamedTuple):
    """The options the loop reads (:class:`ncstab.paths.options.PathOptions`)."""

    rtol: float
    atol: float
    newton_tol: float
    newton_max_iter: int
    min_step: float
    max_step: float
    max_steps: int
    event_tol: float
    sample_step: float
    max_pieces: int


class Case(NamedTuple):
    """One case inside the loop: its model's record, whether its stage controls the force,
    its control path, its orientation (then the reference motion), its law and its rows of
    parameters and geometry: the arguments every model function takes."""

    kind: Any
    fc: bool
    ctl: np.ndarray
    orient: np.ndarray
    law: Any
    p: np.ndarray
    geo: np.ndarray


class Goal(NamedTuple):
    """What a case's indicators compare with: the stage target's lambda and direction,
    the end of the current turn (NaN outside a cycle) and the contact state."""

    lam_end: float
    target_sign: float
    turn_end: float
    secondary: int


class Interpolant(NamedTuple):
    """A step's interpolant: its start, its dense-output coefficients and its length."""

    y0: np.ndarray
    coefficients: np.ndarray
    h: float


class Evaluation(NamedTuple):
    """Scratch for a state's evaluation by the model (``ev``) and the tangent's auxiliaries (``aux``)."""

    ev: np.ndarray
    aux: np.ndarray


class StateAt(NamedTuple):
    """A state with its dy/ds, its evaluation and its tangent's auxiliaries."""

    y: np.ndarray
    dy: np.ndarray
    ev: np.ndarray
    aux: np.ndarray
