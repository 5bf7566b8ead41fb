"""Stepping over a simple bifurcation point on the branch followed.

At a simple bifurcation point the cofactor tangent of the constrained rate
system, ``c = (adj(M) g', det M)`` mapped to ``(du, dF, dlambda)``, passes
through zero linearly along the branch followed, and a second branch crosses
there.  Integrated into the point, the normalised field ``c / |c|`` is a saddle
seen along its stable direction: an off-branch error ``eps`` made at distance
``d0`` grows like ``eps d0 / d``, the adaptive steps shrink toward the point,
and the path comes out on either branch depending on rounding (Turco,
gamma = 2, F2* = 0 of the stability diagram, docs/paths.md).

A continuation code steps over such a point instead (Keller 1977; Allgower &
Georg, *Numerical Continuation Methods*, Sect. 8.1: a predictor along the
incoming tangent past the point, then a corrector).  The engine does the same
for laws with a total form:

* after each committed step (or piece) of length ``h``, the size of the
  branch test ``b = |c| |cos(c, reference)|`` (:class:`PathTangent.branch`) at
  its start, ``b0``, and end, ``b1``, extrapolate linearly to a zero at
  ``d = h b1 / (b0 - b1)`` ahead; where ``0 < d <= OVER_MARGIN sqrt(newton_tol)``
  (1e-4 by default: well above the ~sqrt(newton_tol) within which rounding
  decides the branch) the next step is an **over step** of length ``L = 2 d``,
  predicted to land as far past the zero as the path now is before it;
* the over step is the linear predictor ``y0 + L dy/ds`` projected onto
  equilibrium (the stage's Newton projection).  It is kept only if it
  crossed a simple bifurcation point: the projection converged, the
  cofactor vector at its end is reversed (the tangent there was flipped to
  continue the reference, :func:`~ncstab.paths.tangent_field.path_tangent`)
  and the continued tangent makes an angle under ``OVER_ALIGNMENT`` with the
  one it left (its cosine above 0.9: the branch followed, not the crossing
  one).  Otherwise nothing is kept (no state, no counter) and a regular
  DOP853 step is taken from the same state;
* a kept over step's arclength is that of the projected arc through its
  start, middle and end (:func:`arc_length`, exact to O(kappa^4 L^5)); its
  states in between are the predictor's points ``y0 + sigma(f) dy/ds``
  projected onto equilibrium (:func:`over_interpolant`, arclength proportional
  to f to O(kappa^2 L^3)).  It is then completed like any step: in pieces of
  ``sample_step``, its indicators' sign changes located to ``event_tol`` on
  that interpolant, cut, stored and counted.

**Degenerate points** (systems of three dofs or more).  Where ``[M | g']``
loses rank by two (K with a two-dimensional null space in the force-controlled
directions: the unreduced diamond at Turco's point, gamma = 2, F2* = 0) the
cofactor vector vanishes quadratically, ``|c| ~ k d^2``, without reversing,
several branches cross, and the same saddle of the normalised field sends the
path onto one of them or another depending on the steps.  There the over step
of the linear extrapolation lands short (``b1 / (b0 - b1)`` underestimates the
distance to a quadratic zero) or, landing past, finds no reversal, and is not
kept.  Where it converged and stayed aligned, the case tries next a
**degenerate over step** of twice the distance extrapolated from ``sqrt(b)``
(:func:`next_degenerate_steps`, exact for a quadratic zero), kept where it
converged, stayed within ``OVER_ALIGNMENT`` of the tangent it left and did
*not* reverse the cofactor vector.  A 2-dof system cannot have such a point
under a drive (its ``2 x 3`` matrix would vanish, ``g'`` with it), so this
applies from three dofs on, to the numpy stepper, which runs those systems.

Rate laws (no total form) are integrated as before: no projection brings a
predicted state back onto their path.  The compiled stepper does the same in
its loop (:mod:`ncstab.paths.loop_step_limits`, called from :mod:`ncstab.paths.loop_cases`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as dop

from ncstab.paths.accepted_steps import AcceptedSteps, Piece
from ncstab.paths.projection import project_finite
from ncstab.paths.rhs import state_derivative

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.stepper import BatchStepper

__all__ = [
    "OVER_ALIGNMENT", "OVER_MARGIN", "arc_length", "next_degenerate_steps", "next_over_steps", "over_distance",
    "plan_over_steps", "reset_over_steps", "take_over_steps",
]

#: Cosine of the largest angle between the tangents at the ends of a kept over step.
OVER_ALIGNMENT = 0.9
#: An over step is tried where a step ends within ``OVER_MARGIN * sqrt(newton_tol)`` of
#: the extrapolated zero of the branch test (see :func:`over_distance`).
OVER_MARGIN = 100.0


def next_over_steps(size_before: np.ndarray, size_after: np.ndarray, reach: np.ndarray, newton_tol: float) -> np.ndarray:
    """Length of the over step each case tries next (0: none), from the size of its branch
    test at the start and end of the step just committed (length ``reach``)."""
    return _twice_the_zero_ahead(size_before, size_after, reach, over_distance(newton_tol))


def next_degenerate_steps(size_before: np.ndarray, size_after: np.ndarray, reach: np.ndarray) -> np.ndarray:
    """Length of the degenerate over step (0: none): twice the distance ahead at which
    ``sqrt`` of the branch test's size extrapolates linearly to zero, exact where the size
    vanishes quadratically, ``|b| = k d^2`` (a point where ``[M | g']`` loses rank by two)."""
    return _twice_the_zero_ahead(np.sqrt(size_before), np.sqrt(size_after), reach, np.inf)


def _twice_the_zero_ahead(before: np.ndarray, after: np.ndarray, reach: np.ndarray, within: float) -> np.ndarray:
    """``2 d``, d the distance ahead at which a value falling from ``before`` to ``after``
    over ``reach`` extrapolates linearly to zero, where it falls toward zero and
    ``d <= within``; else 0."""
    with np.errstate(invalid="ignore", divide="ignore"):
        ahead = reach * after / (before - after)
        tried = (before > after) & (after > 0) & (reach > 0) & (ahead <= within)
        return np.where(tried, 2.0 * ahead, 0.0)


def plan_over_steps(stepper: BatchStepper, cases: np.ndarray, size: np.ndarray, reach: np.ndarray) -> None:
    """After a committed step of length ``reach`` ending with branch-test size ``size``: the
    over step each case tries next, and (three dofs or more) the degenerate one it tries
    if that one finds no reversal (:data:`BatchStepper.over_length`, ``degenerate_length``)."""
    if stepper.batch.has_total_form:
        before = stepper.branch_size[cases]
        stepper.over_length[cases] = length = next_over_steps(before, size, reach, stepper.options.newton_tol)
        if stepper.batch.n_dof >= 3:
            degenerate = next_degenerate_steps(before, size, reach)
            stepper.degenerate_length[cases] = np.where(length > 0, degenerate, 0.0)
    stepper.branch_size[cases] = size


def reset_over_steps(stepper: BatchStepper, cases: np.ndarray) -> None:
    """No over step planned for ``cases`` (a new control: none from the last one)."""
    stepper.branch_size[cases] = np.nan
    stepper.over_length[cases] = 0.0
    stepper.degenerate_length[cases] = 0.0
    stepper.over_degenerate[cases] = False


def over_distance(newton_tol: float) -> float:
    """How near the extrapolated point a step must end for the next to step over it:
    ``OVER_MARGIN * sqrt(newton_tol)`` (1e-4 for the default 1e-12)."""
    return OVER_MARGIN * float(np.sqrt(newton_tol))


def take_over_steps(stepper: BatchStepper, cases: np.ndarray) -> tuple[AcceptedSteps | None, np.ndarray]:
    """The over steps of ``cases`` (their ``over_length``, reset here): those that crossed a
    simple bifurcation point (or, tried as degenerate, a degenerate point) as accepted
    steps on their interpolant (None if none did), and the cases that try a degenerate
    over step next instead of a regular step."""
    length = stepper.over_length[cases]
    degenerate = stepper.over_degenerate[cases]
    stepper.over_length[cases] = 0.0
    stepper.over_degenerate[cases] = False
    layout, options = stepper.layout, stepper.options
    batch, stage = stepper.batch.take(cases), stepper.stages.take(cases)
    y_start, rate = stepper.y[cases], stepper.derivative[cases]
    zero = np.zeros(cases.size)
    predicted = y_start + length[:, None] * rate
    y_end, err, known = project_finite(batch, stage, predicted, zero, layout, options)
    dy, aux = state_derivative(batch, stage, y_end, layout, known)
    y_half, err_half, known_half = project_finite(batch, stage, y_start + 0.5 * length[:, None] * rate, zero,
                                                  layout, options)
    _, aux_half = state_derivative(batch, stage, y_half, layout, known_half)
    _, aux_start = state_derivative(batch, stage, y_start, layout)
    reference = stage.reference
    with np.errstate(invalid="ignore"):
        alignment = np.sum(aux.tangent.motion() * reference, axis=-1) / np.sqrt(np.sum(reference * reference, axis=-1))
    aligned = np.isfinite(err) & np.isfinite(err_half) & (alignment > OVER_ALIGNMENT)
    flipped = aux.tangent.flipped
    crossed = aligned & (flipped != degenerate)  # a reversal at a simple point, none at a degenerate one
    retry = aligned & ~flipped & ~degenerate & (stepper.degenerate_length[cases] > 0)
    again = cases[retry]
    stepper.over_length[again] = stepper.degenerate_length[again]
    stepper.over_degenerate[again] = True
    stepper.degenerate_length[cases] = 0.0
    kept = np.flatnonzero(crossed)
    if kept.size == 0:
        return None, again
    points = [_point(a, y, layout)[kept] for a, y in ((aux_start, y_start), (aux_half, y_half), (aux, y_end))]
    arc = arc_length(*points)
    rows = kept if kept.size < cases.size else slice(None)
    stages = np.broadcast_to(rate[rows], (dop.N_STAGES_EXTENDED,) + rate[rows].shape).copy()
    steps = AcceptedSteps(
        cases[rows], batch.take(kept), stage.take(kept), y_start[rows], arc, predicted[rows], stages,
        y_end[rows], dy[rows], aux.take(kept),
    )
    steps.piece = Piece(over_interpolant(rate[rows], length[rows], arc), steps.y_start, arc, np.zeros(kept.size))
    return steps, again


def _point(aux: Any, y: np.ndarray, layout: Any) -> np.ndarray:
    """``(B, 2n + 1)``: (u, F, lambda) at states ``y``, the coordinates of the arclength."""
    evaluation = aux.evaluation
    return np.concatenate([evaluation.displacements, evaluation.forces, y[:, layout.lam, None]], axis=-1)


def arc_length(start: np.ndarray, middle: np.ndarray, end: np.ndarray) -> np.ndarray:
    """Length of the arc through three points (its start, middle and end, in the metric
    of the arclength): the chord of the halves extrapolated (Richardson) from the chords
    of one and two pieces, exact to O(kappa^4 L^5) for a smooth arc of length L."""
    whole = np.sqrt(np.sum((end - start) ** 2, axis=-1))
    halves = np.sqrt(np.sum((middle - start) ** 2, axis=-1)) + np.sqrt(np.sum((end - middle) ** 2, axis=-1))
    return (4.0 * halves - whole) / 3.0


def over_interpolant(rate: np.ndarray, length: np.ndarray, arc: np.ndarray) -> np.ndarray:
    """Coefficients, in the form of the DOP853 interpolant
    (:func:`ncstab.paths.integrator.evaluate_dense`), of the predictor's point at the
    fraction f of the over step's arclength ``arc``: ``y0 + sigma(f) dy/ds`` with
    ``sigma(f) = L f + (arc - L) f (1 - f)``, which ends at the predictor's end
    (``sigma(1) = L``) and makes the arclength of the projected states proportional to
    f to second order (the projection moves a predicted state along the path by
    O(kappa sigma^2), which the quadratic term takes back)."""
    coefficients = np.zeros((dop.INTERPOLATOR_POWER,) + rate.shape)
    coefficients[0] = length[:, None] * rate
    coefficients[1] = (arc - length)[:, None] * rate
    return coefficients
