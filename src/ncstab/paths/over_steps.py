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
  branch test ``b = |c| |cos(c, reference)|`` (the loop's ``branch_test``) at
  its start, ``b0``, and end, ``b1``, extrapolate linearly to a zero at
  ``d = h b1 / (b0 - b1)`` ahead; where ``0 < d <= OVER_MARGIN sqrt(newton_tol)``
  (1e-4 by default: well above the ~sqrt(newton_tol) within which rounding
  decides the branch) the next step is an **over step** of length ``L = 2 d``,
  predicted to land as far past the zero as the path now is before it;
* the over step is the linear predictor ``y0 + L dy/ds`` projected onto
  equilibrium (the stage's Newton projection).  It is kept only if it
  crossed a simple bifurcation point: the projection converged, the
  cofactor vector at its end is reversed (the tangent there was flipped to
  continue the reference, :mod:`~ncstab.paths.tangent_field`)
  and the continued tangent makes an angle under ``OVER_ALIGNMENT`` with the
  one it left (its cosine above 0.9: the branch followed, not the crossing
  one).  Otherwise nothing is kept (no state, no counter) and a regular
  DOP853 step is taken from the same state;
* a kept over step's arclength is that of the projected arc through its
  start, middle and end (``arc_through``, exact to O(kappa^4 L^5)); its
  states in between are the predictor's points ``y0 + sigma(f) dy/ds``
  projected onto equilibrium (with
  ``sigma(f) = L f + (arc - L) f (1 - f)``, which ends at the predictor's end and
  makes the arclength of the projected states proportional to f to O(kappa^2 L^3)).  It is then completed like any step: in pieces of
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
(``next_degenerate_length``, exact for a quadratic zero), kept where it
converged, stayed within ``OVER_ALIGNMENT`` of the tangent it left and did
*not* reverse the cofactor vector.  A 2-dof system cannot have such a point
under a drive (its ``2 x 3`` matrix would vanish, ``g'`` with it), so this
applies from three dofs on.

Rate laws (no total form) are integrated as before: no projection brings a
predicted state back onto their path.  The compiled loop implements all of it
(``next_over_length``, ``next_degenerate_length`` and ``over_step`` in
:mod:`ncstab.paths.loop_step_limits`, called from :mod:`ncstab.paths.loop_cases`;
``arc_through`` in the model parts); this module holds its constants and the
stepper's reset of a case's planned over steps at a new control.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.stepper import BatchStepper

__all__ = ["OVER_ALIGNMENT", "OVER_MARGIN", "reset_over_steps"]

#: Cosine of the largest angle between the tangents at the ends of a kept over step.
OVER_ALIGNMENT = 0.9
#: An over step is tried where a step ends within ``OVER_MARGIN * sqrt(newton_tol)`` of
#: the extrapolated zero of the branch test (1e-4 for the default ``newton_tol`` 1e-12).
OVER_MARGIN = 100.0


def reset_over_steps(stepper: BatchStepper, cases: np.ndarray) -> None:
    """No over step planned for ``cases`` (a new control, or a new branch: none from the
    last one; the loop plans them again from the next committed step)."""
    stepper.branch_size[cases] = np.nan
    stepper.over_length[cases] = 0.0
    stepper.degenerate_length[cases] = 0.0
    stepper.over_degenerate[cases] = False
