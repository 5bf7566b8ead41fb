"""Stage entry: cases start a loading stage from their current states.

Each dof is controlled through its displacement or its force; the stage's
control path is g(lambda) = offset + slope lambda (a circle in a dof plane
for a cycle stage), the load parameter P = P_offset + P_slope lambda.
Held quantities keep their current value; a single driven quantity *is*
lambda (slope 1, lambda starts at its current value); several driven
quantities move proportionally, lambda running from 0 to 1.  A dof that a
load-parameter or cycle stage does not name is free: its force is held.
These functions act on a :class:`~ncstab.paths.stepper.BatchStepper`.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from ncstab.paths.programme import BRANCH_DIMENSION, CURRENT, CycleStage, Stage
from ncstab.paths.rhs import evaluate_at
from ncstab.paths.status import held_away, held_away_message
from ncstab.paths.tangent_field import StageArrays

if TYPE_CHECKING:
    from ncstab.paths.stepper import BatchStepper

__all__ = ["enter", "probe_step", "resolve"]


def enter(stepper: BatchStepper, index: np.ndarray, k: int) -> None:
    """Cases ``index`` start stage k (zero-length stages cascade to the next).

    Past the last stage the cases finish.  A case that starts a stage it
    cannot follow fails; the others store their starting state (a case
    that has just reached the target of stage k - 1 stores the same state
    a second time, with the new stage index).
    """
    while index.size:
        if k >= len(stepper.programme):
            stepper.finish(index)
            return
        go, zero_length = _set_up_stage(stepper, index, k)
        if go.any() or not stepper.recorder.started:
            _start_stage(stepper, index[go])
        index, k = index[zero_length], k + 1


def _every_case(stepper: BatchStepper, index: np.ndarray) -> bool:
    """Whether ``index`` is every case, in order."""
    return index.size == stepper.size and bool(np.all(index == np.arange(stepper.size)))


def _batch_of(stepper: BatchStepper, index: np.ndarray):
    """The cases ``index`` as a batch (the batch itself where that is every case)."""
    return stepper.batch if _every_case(stepper, index) else stepper.batch.take(index)


def _set_up_stage(stepper: BatchStepper, index: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Set up stage k for cases ``index`` from their current states (stage arrays, lambda).

    Fails the cases that cannot start it (a held value that is not the
    current one, a cycle of zero radius, a singular control).  Returns the
    masks (over ``index``) of the cases that start it and of those for
    which it has zero length.
    """
    stage = stepper.programme.stages[k]
    layout = stepper.layout
    stepper.stage_index[index] = k
    every = _every_case(stepper, index)
    previous = stepper.stages if every else stepper.stages.take(index)
    y = stepper.y[index]
    evaluation = evaluate_at(_batch_of(stepper, index), previous, y, layout)
    u = evaluation.displacements
    current = {name: u[:, i] for i, name in enumerate(stepper.dof_names)}
    current.update({name: evaluation.forces[:, i] for i, name in enumerate(stepper.force_names)})
    load_name = stepper.batch.load_parameter
    if load_name is not None:
        current[load_name] = previous.load(y[:, layout.lam])
    arrays = StageArrays.empty(index.size, stepper.batch.n_dof)
    arrays.secondary_state = previous.secondary_state.copy()
    if isinstance(stage, Stage):
        lam, bad, reasons = _linear_stage(stepper, stage, k, index, current, arrays)
    else:
        assert isinstance(stage, CycleStage)
        lam, bad, reasons = _cycle_stage(stepper, stage, k, index, current, u, arrays)
    stepper.y[index, layout.lam] = lam
    zero_length = (arrays.target_sign == 0) & ~bad
    # dlambda/ds of the unoriented tangent, from the loop (the cofactor vector's own sign)
    dlam = stepper.compiled.settle(stepper, index, arrays, projected=False)
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
        stepper.stages = arrays
    else:
        stepper.stages.put(index, arrays)
    for reason in np.unique(reasons[bad]):
        which = index[bad & (reasons == reason)]
        stepper.fail(which, "singular_control" if "singular" in reason else "bad_stage_start", reason)
    return ~bad & ~zero_length, zero_length


def _linear_stage(
    stepper: BatchStepper,
    stage: Stage,
    k: int,
    index: np.ndarray,
    current: dict[str, np.ndarray],
    arrays: StageArrays,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fill ``arrays`` for a linear stage: each dof controlled through u_i or F_i.

    Held quantities keep their offset; one driven quantity has slope 1 in
    lambda, which starts at its current value; several move from their
    current values to their targets as lambda runs from 0 to 1.  Returns
    (lambda at the start, mask of cases that cannot start, reasons).
    """
    bad = np.zeros(index.size, dtype=bool)
    reasons = np.full(index.size, "", dtype=object)
    controls = stage.controls()
    drives = dict(stage.drives)
    single = len(drives) == 1
    targets = {name: resolve(stepper, target, index) for name, target in drives.items()}

    def driven_line(name: str) -> tuple[np.ndarray | float, np.ndarray | float]:
        """(offset, slope) of a driven quantity."""
        if single:
            return 0.0, 1.0
        return current[name], targets[name] - current[name]

    for i, (dof, force) in enumerate(zip(stepper.dof_names, stepper.force_names)):
        name = dof if dof in controls else force  # a free dof (load or cycle stage): its force held
        arrays.force_controlled[:, i] = name == force
        arrays.offset[:, i] = current[name]
        if name in drives:
            arrays.offset[:, i], arrays.slope[:, i] = driven_line(name)
        elif controls.get(name, CURRENT) != CURRENT:
            bad |= _held_away(stepper, k, name, controls[name], index, current[name], reasons)
    load_name = stepper.batch.load_parameter
    if load_name is not None:
        arrays.load_offset[:] = current[load_name]
        if load_name in drives:
            arrays.load_offset[:], arrays.load_slope[:] = driven_line(load_name)
        elif controls.get(load_name, CURRENT) != CURRENT:
            bad |= _held_away(stepper, k, load_name, controls[load_name], index, current[load_name], reasons)
    if stage.at_bifurcation == "switch":
        arrays.switch[:] = stage.direction
    elif stage.at_bifurcation == "branches":
        arrays.switch[:] = np.rint(resolve(stepper, BRANCH_DIMENSION, index)).astype(int)
    if single:
        ((driven_name, _),) = drives.items()
        start = current[driven_name]
        arrays.lam_end = targets[driven_name]
        arrays.target_sign = np.sign(arrays.lam_end - start)
    else:
        start = np.zeros(index.size)
        arrays.lam_end = np.ones(index.size)
        moving = np.zeros(index.size, dtype=bool)
        for name in drives:
            moving |= targets[name] != current[name]
        arrays.target_sign = np.where(moving, 1.0, 0.0)
    return start, bad, reasons


def _held_away(
    stepper: BatchStepper,
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
    nominal = resolve(stepper, held, index)
    mismatch = held_away(nominal, value)
    if not mismatch.any():
        return mismatch
    hint = np.where(
        (stepper.stages.secondary_state[index] & stepper.batch.gap_bits) != 0,
        stepper.batch.closed_gap_hint,
        "",
    )
    text = held_away_message(k + 1, name, held)
    reasons[mismatch] = np.char.add(text, hint[mismatch].astype(str)).astype(object)
    return mismatch


def _cycle_stage(
    stepper: BatchStepper,
    stage: CycleStage,
    k: int,
    index: np.ndarray,
    current: dict[str, np.ndarray],
    u: np.ndarray,
    arrays: StageArrays,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Fill ``arrays`` for a cycle stage: u on the circle through the current state.

    The circle lies in the plane of the stage's two dofs; the other dofs are
    free (their forces held), the load parameter held.  lambda is the angle
    turned, from 0 to 2 pi turns.  Returns (lambda at the start, mask of
    cases that cannot start, reasons).
    """
    reasons = np.full(index.size, "", dtype=object)
    axes = np.array([stepper.dof_names.index(name) for name in stage.dofs])
    for i, force in enumerate(stepper.force_names):
        if i not in axes:
            arrays.force_controlled[:, i] = True
            arrays.offset[:, i] = current[force]
    load_name = stepper.batch.load_parameter
    if load_name is not None:
        arrays.load_offset[:] = current[load_name]
    center = np.column_stack([resolve(stepper, c, index) for c in stage.center])
    relative = u[:, axes] - center
    arrays.is_cycle[:] = True
    arrays.cycle_axes[:] = axes
    arrays.center = center
    arrays.radius = np.hypot(relative[:, 0], relative[:, 1])
    arrays.theta0 = np.arctan2(relative[:, 1], relative[:, 0])
    arrays.turn_direction[:] = stage.direction
    arrays.lam_end[:] = 2 * math.pi * stage.turns
    arrays.target_sign[:] = 1.0
    bad = arrays.radius <= 1e-14
    reasons[bad] = f"stage {k + 1}: the state is at the centre of the cycle (zero radius)"
    return np.zeros(index.size), bad, reasons


def resolve(stepper: BatchStepper, value: float | str, index: np.ndarray) -> np.ndarray:
    """A stage value (a number or a parameter name) for cases ``index``."""
    if isinstance(value, str):
        if value == CURRENT:
            raise AssertionError("resolved by caller")
        named = stepper.values[value]
        if np.ndim(named):
            return np.asarray(named, dtype=float)[index]
        return np.full(index.size, float(named))
    return np.full(index.size, float(value))


def _start_stage(stepper: BatchStepper, index: np.ndarray) -> None:
    """Cases ``index`` start their (set up) stage on the compiled loop: dy/ds, indicators,
    the state stored, a cycle's turn started; the first step length where it is still to
    be estimated (Hairer's estimate from a probe step, :func:`probe_step`)."""
    stepper.compiled.start(stepper, index)


def probe_step(stepper: BatchStepper) -> float:
    """The probe step of the first-step estimate: min(1e-3, max_step)."""
    return min(1e-3, stepper.options.max_step)

