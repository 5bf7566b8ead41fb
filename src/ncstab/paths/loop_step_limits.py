"""The compiled stage loop where a step cannot go on as integrated: the domain's edge and over steps.

One case at a time, any model (:mod:`ncstab.paths.loop_dispatch`):

* the domain's edge (:mod:`ncstab.paths.domain_edge`): whether a state is
  admissible, and the last admissible state of a piece, by bisection;
* simple bifurcation points (:mod:`ncstab.paths.over_steps`): the over step
  itself (the predictor along dy/ds projected onto equilibrium, kept where it
  crossed such a point, with its arclength and its interpolant; the arithmetic
  of its length and interpolant is in :mod:`ncstab.paths.loop_numerics`).
"""

from __future__ import annotations

from ncstab.jit import njit
from ncstab.paths.domain_edge import EDGE_HALVINGS
from ncstab.paths.loop_dispatch import alignment, arc_through, domain_detail, project, rhs, state_size, was_flipped
from ncstab.paths.loop_numerics import dense_value, over_coefficients
from ncstab.paths.over_steps import OVER_ALIGNMENT

__all__ = ["admissible_at", "last_admissible", "over_step"]


@njit
def admissible_at(sigma, interpolant, case, settings, state, dy, ev, aux):
    # domain_edge._admissible_at, one case: the state at sigma along its step (its
    # interpolant; projected for a total form) into state, with dy/ds, ev and aux there;
    # whether it is admissible
    y0, coefficients, h = interpolant
    kind, fc, ctl, orient, law, p, geo = case
    dense_value(y0, coefficients, sigma / h, state)
    admissible = True
    if not kind.rate_form:
        admissible = project(kind, state, fc, ctl, law, p, geo, settings.newton_tol, settings.newton_max_iter, ev)
    rhs(kind, state, fc, ctl, orient, law, p, geo, dy, ev, aux)
    return admissible and domain_detail(kind, state, ev, geo) < 0


@njit
def last_admissible(offset, end_at, interpolant, case, settings, work, ev, aux):
    # domain_edge._last_admissible, one case: the last admissible state's place in the
    # piece (offset, end_at) of the step (its interpolant), by bisection to event_tol
    lo, hi = offset, end_at
    for _ in range(EDGE_HALVINGS):
        if not (hi - lo > settings.event_tol):
            break
        mid = 0.5 * (lo + hi)
        if admissible_at(mid, interpolant, case, settings, work[0], work[1], ev, aux):
            lo = mid
        else:
            hi = mid
    return lo


@njit
def over_step(length, y0, rate, case, settings, y_raw, end, y_half, ev, coefficients, degenerate, can_retry):
    # the over step (over_steps), one case: the predictor's end y0 + length dy/ds projected
    # (end: y_new, with dy_new, ev_new, aux_new there) and the arclength of the step (arc_through)
    # where it is kept: it crossed a simple bifurcation point (the cofactor vector reversed,
    # the tangent within OVER_ALIGNMENT of the one it left), or, tried as ``degenerate``, a
    # degenerate point (aligned, not reversed).  Else 0.0 (nothing is kept), or -1.0 where
    # a degenerate over step is to follow (``can_retry``: aligned, not reversed, not
    # degenerate).  The step's interpolant in coefficients (over_steps:
    # y0 + sigma(f) dy/ds)
    kind, fc, ctl, orient, law, p, geo = case
    y_new, dy_new, ev_new, aux_new = end
    newton_tol, newton_max_iter = settings.newton_tol, settings.newton_max_iter
    m = state_size(kind, y0)
    for j in range(m):
        y_raw[j] = y0[j] + length * rate[j]
        y_new[j] = y_raw[j]
    if not project(kind, y_new, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev_new):
        return 0.0
    rhs(kind, y_new, fc, ctl, orient, law, p, geo, dy_new, ev_new, aux_new)
    if not alignment(kind, aux_new, orient) > OVER_ALIGNMENT:
        return 0.0
    half = 0.5 * length
    for j in range(m):
        y_half[j] = y0[j] + half * rate[j]
    if was_flipped(kind, aux_new) == degenerate:  # no reversal at a simple point, or one at a degenerate point
        if degenerate or not can_retry:
            return 0.0
        converged = project(kind, y_half, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev)
        return -1.0 if converged else 0.0
    if not project(kind, y_half, fc, ctl, law, p, geo, newton_tol, newton_max_iter, ev):
        return 0.0
    arc = arc_through(kind, y0, y_half, y_new, ev_new, ctl, law, p, geo, ev)
    if not arc > 0:
        return 0.0
    over_coefficients(length, arc, rate, m, coefficients)
    return arc
