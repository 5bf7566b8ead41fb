"""The pieces of an accepted step: stored states and sign checks on its interpolant.

``PathOptions.sample_step`` bounds how far apart two stored states are, and two
checks of the indicators' signs, apart from the integrator's step: a step of
length h is cut into ``ceil(h / sample_step)`` equal pieces.  The end of every
piece but the last is the step's DOP853 interpolant there (7th order,
:func:`ncstab.paths.integrator.dense_output`), projected onto equilibrium for a
law with a total form; the last ends where the step does.  Each piece is then
completed as a whole step is (:meth:`ncstab.paths.stepper.BatchStepper._complete`):
its indicators' sign changes located on the step's interpolant, cut where a
crossing ends the stage or switches a contact (the rest of the step dropped),
its events stored, its end stored.  A step counts once towards ``max_steps``.
Every piece's end is checked against the admissible domain when its turn
comes, the step's end too: a stage target or a stop inside an earlier piece
ends the case there, so a long step that overshoots a target lying near the
domain's edge does not fail the case.  A piece whose end left the domain is
completed up to the last admissible state on the interpolant, and the case
fails there unless something cut the piece before
(:mod:`ncstab.paths.domain_edge`).
Where an interior end does not project, the step is retried at half its length.

The compiled stepper does the same in its loop (:mod:`ncstab.paths.loop_cases`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.paths.accepted_steps import AcceptedSteps, Piece
from ncstab.paths.domain_edge import split_at_the_edge
from ncstab.paths.integrator import dense_output, evaluate_dense
from ncstab.paths.projection import project_finite
from ncstab.paths.rhs import state_derivative
from ncstab.paths.status import RUNNING

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.stepper import BatchStepper

__all__ = ["complete_in_pieces"]


def complete_in_pieces(stepper: BatchStepper, steps: AcceptedSteps) -> None:
    """Complete the accepted ``steps``, each in ``options.pieces(h)`` pieces."""
    options = stepper.options
    pieces = options.pieces(steps.h) if options.max_pieces > 1 else np.ones(steps.cases.size, dtype=np.int64)
    whole = pieces == 1
    if whole.any():
        kept, edge, why = split_at_the_edge(stepper, steps if whole.all() else steps.take(np.flatnonzero(whole)))
        if kept is not None:
            stepper._complete(kept)
        if edge is not None:
            _complete_to_the_edge(stepper, edge, why, counts_step=True, ends_step=True)
        if whole.all():
            return
        cut = np.flatnonzero(~whole)
        steps, pieces = steps.take(cut), pieces[cut]
    samples, projected = _interior_ends(stepper, steps, pieces)
    retried = np.flatnonzero(~projected)
    if retried.size:
        _retry_shorter(stepper, steps.cases[retried], steps.h[retried])
    alive = np.flatnonzero(projected)
    offset = np.zeros(steps.cases.size)
    for k in range(1, int(pieces.max()) + 1):
        rows = alive[pieces[alive] >= k]
        if rows.size == 0:
            break
        for last in (False, True):
            group = rows[(pieces[rows] == k) == last]
            if group.size == 0:
                continue
            end_at = steps.h[group] if last else steps.h[group] * k / pieces[group]
            inside, edge, why = _piece(stepper, steps, group, samples, k, end_at - offset[group], offset[group], last)
            going_on = np.empty(0, dtype=steps.cases.dtype)
            if inside is not None:
                stage_before = stepper.stage_index[inside.cases].copy()
                is_cut = stepper._complete(inside, counts_step=k == 1, ends_step=last)
                # a piece cut short, a stage ended or a case ended: the rest of its step is dropped
                going_on = inside.cases[
                    ~is_cut & (stepper.status[inside.cases] == RUNNING) & (stepper.stage_index[inside.cases] == stage_before)
                ]
            if edge is not None:  # completed to the domain's edge, then failed unless cut before it
                _complete_to_the_edge(stepper, edge, why, counts_step=k == 1, ends_step=last)
            offset[group] = end_at
            ended = group[~np.isin(steps.cases[group], going_on)]
            alive = np.setdiff1d(alive, ended, assume_unique=True)


def _interior_ends(stepper: BatchStepper, steps: AcceptedSteps, pieces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The steps' interpolant coefficients (kept in ``steps.piece``) and the ends of their
    interior pieces ``(max pieces - 1, rows, m)``, projected for a total form; the mask of
    the steps whose every interior end projected."""
    layout = stepper.layout
    batch, stage = steps.batch, steps.stage
    if steps.piece is None:  # (an over step has its linear interpolant already)
        coefficients = dense_output(
            lambda yy: state_derivative(batch, stage, yy, layout)[0], steps.y_start, steps.y_raw, steps.h,
            steps.dop853_stages,
        )
        steps.piece = Piece(coefficients, steps.y_start, steps.h, np.zeros(steps.cases.size))
    coefficients = steps.piece.dense
    samples = np.full((int(pieces.max()) - 1,) + steps.y_start.shape, np.nan)
    projected = np.ones(steps.cases.size, dtype=bool)
    for k in range(1, int(pieces.max())):
        rows = np.flatnonzero(pieces > k)
        y = evaluate_dense(steps.y_start[rows], coefficients[:, rows], k / pieces[rows])
        if batch.has_total_form:
            y, err, _ = project_finite(
                batch.take(rows), stage.take(rows), y, np.zeros(rows.size), layout, stepper.options
            )
            projected[rows[~np.isfinite(err)]] = False
        samples[k - 1, rows] = y
    return samples, projected


def _retry_shorter(stepper: BatchStepper, cases: np.ndarray, h: np.ndarray) -> None:
    """Steps of ``cases`` whose interior ends did not project: retried at half length (a
    rejected step; below ``min_step`` the case fails)."""
    stepper.step_size[cases] = 0.5 * h
    stepper.rejected[cases] += 1
    stepper.fail_step_size_underflow(cases[stepper.step_size[cases] < stepper.options.min_step])


def _complete_to_the_edge(
    stepper: BatchStepper, edge: AcceptedSteps, why: np.ndarray, counts_step: bool, ends_step: bool
) -> None:
    """Complete steps (or pieces) that end at the domain's edge (:mod:`ncstab.paths.domain_edge`),
    then fail with ``left_domain`` the cases that nothing cut before it (a target, a stop,
    a contact switch: those go on from there, or end as they do)."""
    stage_before = stepper.stage_index[edge.cases].copy()
    is_cut = stepper._complete(edge, counts_step=counts_step, ends_step=ends_step)
    leaving = ~is_cut & (stepper.status[edge.cases] == RUNNING) & (stepper.stage_index[edge.cases] == stage_before)
    stepper.fail_outside_domain(edge.cases[leaving], why[leaving])


def _piece(
    stepper: BatchStepper, steps: AcceptedSteps, rows: np.ndarray, samples: np.ndarray, k: int,
    span: np.ndarray, offset: np.ndarray, last: bool,
) -> tuple[AcceptedSteps | None, AcceptedSteps | None, np.ndarray]:
    """Piece ``k`` of the steps ``rows`` as steps of their own, split at the domain's edge
    (:func:`ncstab.paths.domain_edge.split_at_the_edge`)."""
    cases = steps.cases[rows]
    batch, stage = steps.batch.take(rows), stepper.stages.take(cases)
    piece = Piece(steps.piece.dense[:, rows], steps.y_start[rows], steps.h[rows], offset)
    y_start = stepper.y[cases].copy()
    if last:  # the step's end, checked once the pieces before it are done
        end = AcceptedSteps(
            cases, batch, stage, y_start, span, None, None, steps.y_new[rows], steps.dy_new[rows],
            steps.aux.take(rows), piece,
        )
        return split_at_the_edge(stepper, end)
    y_end = samples[k - 1, rows]
    dy, aux = state_derivative(batch, stage, y_end, stepper.layout)
    return split_at_the_edge(stepper, AcceptedSteps(cases, batch, stage, y_start, span, None, None, y_end, dy, aux, piece))
