"""Where a step leaves the admissible domain: its last admissible state, found on its interpolant.

A step (or a piece of one, :mod:`ncstab.paths.step_pieces`) whose end lies
outside the domain (non-finite numbers, or the batch's own conditions: l* > 0
and |alpha| < pi/2 at every contact...) does not end its case at once: the
last admissible state on the step's DOP853 interpolant is found by bisection
of the piece, to ``event_tol`` in arclength (projected onto equilibrium for a
law with a total form, as a piece's interior end is), the piece is completed
up to there as any other (its indicators' crossings located, cut at a stage
target, a stop or a contact switch, its events and its end stored), and only
then, if nothing cut it, the case fails with ``left_domain``.  Before, the
whole piece was dropped, and with it an event lying in it: a McNamara case
(gamma 2, F2* 0.509 held, alpha0 = 1) lost its limit point and its loss of
Hill's condition, 6e-3 in arclength before alpha reached pi/2, with steps of
0.01 to 0.05 (``tests/test_domain_edge.py``).  Where no admissible state lies beyond the piece's start
the case fails there, as before.

The compiled stepper does the same in its loop (``admissible_at`` and the
bisection, ``last_admissible``, in :mod:`ncstab.paths.loop_step_limits`):
the same midpoints, the same test of each, the same number of halvings.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.accepted_steps import AcceptedSteps, Piece
from ncstab.paths.integrator import dense_output, evaluate_dense
from ncstab.paths.projection import project_finite
from ncstab.paths.rhs import Auxiliary, state_derivative

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.stepper import BatchStepper

__all__ = ["EDGE_HALVINGS", "domain_codes", "split_at_the_edge"]

#: Most halvings of a piece in search of its last admissible state (fewer where the
#: bracket is below ``event_tol`` first: 2^-60 of any piece is).
EDGE_HALVINGS = 60


def domain_codes(batch: Any, y: np.ndarray, evaluation: Any) -> np.ndarray:
    """Per state, -1 inside the domain, else the index of the reason in ``batch.domain_reasons``
    (0, non-finite numbers, where the state or its forces are not finite)."""
    finite = np.isfinite(y).all(-1) & np.isfinite(evaluation.forces).all(-1)
    return np.where(finite, batch.domain_codes(evaluation), 0)


def split_at_the_edge(
    stepper: BatchStepper, steps: AcceptedSteps
) -> tuple[AcceptedSteps | None, AcceptedSteps | None, np.ndarray]:
    """``steps`` split at the domain's edge.

    Returns
    -------
    (inside, edge, why)
        The rows whose ends are admissible (None if none); the rows whose ends
        left the domain, moved back to the last admissible state found on their
        interpolant (None if none; their ``h`` the span to it), and why each
        left.  Rows with no admissible state beyond their start fail here
        (``left_domain``).
    """
    codes = domain_codes(steps.batch, steps.y_new, steps.aux.evaluation)
    outside = codes >= 0
    if not outside.any():
        return steps, None, np.empty(0, dtype=object)
    inside = None if outside.all() else steps.take(np.flatnonzero(~outside))
    leaving = steps.take(np.flatnonzero(outside))
    why = np.asarray(steps.batch.domain_reasons, dtype=object)[codes[outside]]
    if leaving.piece is None:  # a whole step: its interpolant, as a piece from its start
        batch, stage, layout = leaving.batch, leaving.stage, stepper.layout
        dense = dense_output(
            lambda yy: state_derivative(batch, stage, yy, layout)[0], leaving.y_start, leaving.y_raw, leaving.h,
            leaving.dop853_stages,
        )
        leaving.piece = Piece(dense, leaving.y_start, leaving.h, np.zeros(leaving.cases.size))
    lo = _last_admissible(stepper, leaving)
    found = lo > leaving.piece.offset
    stepper.fail_outside_domain(leaving.cases[~found], why[~found])
    if not found.any():
        return inside, None, why[found]
    edge = leaving.take(np.flatnonzero(found))
    _, edge.y_new, edge.dy_new, edge.aux = _admissible_at(stepper, edge, lo[found])
    edge.h = lo[found] - edge.piece.offset
    return inside, edge, why[found]


def _last_admissible(stepper: BatchStepper, steps: AcceptedSteps) -> np.ndarray:
    """Bisection of each row's piece [offset, offset + h]: the last admissible point found
    (its distance from the step's start; the offset where none is)."""
    piece = steps.piece
    lo = piece.offset.copy()
    hi = piece.offset + steps.h
    for _ in range(EDGE_HALVINGS):
        rows = np.flatnonzero(hi - lo > stepper.options.event_tol)
        if rows.size == 0:
            break
        mid = 0.5 * (lo[rows] + hi[rows])
        inside = _admissible_at(stepper, steps.take(rows), mid)[0]
        lo[rows[inside]] = mid[inside]
        hi[rows[~inside]] = mid[~inside]
    return lo


def _admissible_at(
    stepper: BatchStepper, steps: AcceptedSteps, sigma: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, Auxiliary]:
    """The states at ``sigma`` along each row's step (projected for a total form), whether
    each is admissible (projected, and inside the domain), and dy/ds and the auxiliary
    quantities there."""
    piece, batch, stage, layout = steps.piece, steps.batch, steps.stage, stepper.layout
    y = evaluate_dense(piece.step_start, piece.dense, sigma / piece.step_length)
    admissible = np.ones(sigma.size, dtype=bool)
    if batch.has_total_form:
        y, err, _ = project_finite(batch, stage, y, np.zeros(sigma.size), layout, stepper.options)
        admissible = np.isfinite(err)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        dy, aux = state_derivative(batch, stage, y, layout)
    admissible &= domain_codes(batch, y, aux.evaluation) < 0
    return admissible, y, dy, aux
