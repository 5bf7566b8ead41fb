"""Template, part 3 of 4, of the compiled stage loop: where a step cannot go on as integrated.

Pasted after :func:`ncstab.paths.loop_steps.steps_part` (see
:mod:`ncstab.paths.loop_model`), one case at a time:

* the domain's edge (:mod:`ncstab.paths.domain_edge`): whether a state is
  admissible, and the last admissible state of a piece, by bisection;
* simple bifurcation points (:mod:`ncstab.paths.over_steps`): the length of
  the over step a committed step asks for next, and the over step itself (the
  predictor along dy/ds projected onto equilibrium, kept where it crossed such
  a point, with its arclength and its interpolant).

The parameters of :func:`limits_part` are the names it uses from parts 1 and 2
(it is never called).
"""

from __future__ import annotations

import numpy as np

from ncstab.paths.domain_edge import EDGE_HALVINGS
from ncstab.paths.over_steps import OVER_ALIGNMENT, OVER_MARGIN

__all__ = ["limits_part"]


def limits_part(M, N_INT, alignment, angle, dense_value, evaluate, njit, project, rate_form, rhs) -> None:
    """Define the helpers of the domain's edge and of over steps (a template: see the module docstring)."""
    over_alignment, over_margin, edge_halvings = OVER_ALIGNMENT, OVER_MARGIN, EDGE_HALVINGS

    @njit
    def domain_detail(state, ev_state):
        # domain_edge.domain_codes, one state: -1 inside the domain, else the index of the reason
        # in model.DOMAIN_REASONS (0 non-finite numbers, 1 l* <= 0, 2 |alpha| >= pi/2)
        finite = np.isfinite(ev_state[4]) and np.isfinite(ev_state[5])
        for j in range(M):
            finite = finite and np.isfinite(state[j])
        if not finite:
            return 0
        if not (ev_state[0] > 0):
            return 1
        if not (abs(angle(ev_state)) < 0.5 * np.pi):
            return 2
        return -1

    @njit
    def admissible_at(sigma, h, y0, coefficients, fc0, fc1, ctl, orient, law, p, c0, s0, newton_tol,
                      newton_max_iter, state, dy, ev, aux):
        # domain_edge._admissible_at, one case: the state at sigma along its step (projected for a
        # total form) into state, with dy/ds, ev and aux there; whether it is admissible
        dense_value(y0, coefficients, sigma / h, state)
        admissible = True
        if not rate_form:
            admissible = project(state, fc0, fc1, ctl, law, p, c0, s0, newton_tol, newton_max_iter, ev)
        rhs(state, fc0, fc1, ctl, orient, law, p, c0, s0, dy, ev, aux)
        return admissible and domain_detail(state, ev) < 0

    @njit
    def last_admissible(offset, end_at, h, y0, coefficients, fc0, fc1, ctl, orient, law, p, c0, s0, newton_tol,
                        newton_max_iter, event_tol, work, ev, aux):
        # domain_edge._last_admissible, one case: the last admissible state's place in the
        # piece (offset, end_at) of the step, by bisection to event_tol
        lo, hi = offset, end_at
        for _ in range(edge_halvings):
            if not (hi - lo > event_tol):
                break
            mid = 0.5 * (lo + hi)
            if admissible_at(mid, h, y0, coefficients, fc0, fc1, ctl, orient, law, p, c0, s0, newton_tol,
                             newton_max_iter, work[0], work[1], ev, aux):
                lo = mid
            else:
                hi = mid
        return lo

    @njit
    def next_over_length(size_before, size_after, reach, newton_tol):
        # over_steps.next_over_steps, one case: the length of the over step tried next (0: none)
        ahead = reach * size_after / (size_before - size_after)
        tried = size_before > size_after > 0 and reach > 0
        return 2.0 * ahead if tried and ahead <= over_margin * np.sqrt(newton_tol) else 0.0

    @njit
    def over_step(length, y0, rate, fc0, fc1, ctl, orient, law, p, cos0, sin0, newton_tol, newton_max_iter,
                  y_raw, y_new, dy_new, ev_new, aux_new, y_half, ev, coefficients):
        # over_steps.take_over_steps, one case: the predictor's end y0 + length dy/ds projected
        # (y_new, with dy_new, ev_new, aux_new there) and the arclength of the step (arc_length),
        # or 0.0 where it crossed no simple bifurcation point (nothing is kept then); the step's
        # interpolant in coefficients (over_steps.over_interpolant: y0 + sigma(f) dy/ds)
        for j in range(M):
            y_raw[j] = y0[j] + length * rate[j]
            y_new[j] = y_raw[j]
        if not project(y_new, fc0, fc1, ctl, law, p, cos0, sin0, newton_tol, newton_max_iter, ev_new):
            return 0.0
        rhs(y_new, fc0, fc1, ctl, orient, law, p, cos0, sin0, dy_new, ev_new, aux_new)
        if not (aux_new[9] > 0 and alignment(aux_new, orient) > over_alignment):
            return 0.0
        half = 0.5 * length
        for j in range(M):
            y_half[j] = y0[j] + half * rate[j]
        if not project(y_half, fc0, fc1, ctl, law, p, cos0, sin0, newton_tol, newton_max_iter, ev):
            return 0.0
        h0, h1 = ev[4], ev[5]  # F at the middle, then at the start
        evaluate(y0[0], y0[1], y0[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
        a0, a1, a2, a3, a4 = y_half[0] - y0[0], y_half[1] - y0[1], h0 - ev[4], h1 - ev[5], y_half[2] - y0[2]
        b0, b1, b2, b3, b4 = y_new[0] - y_half[0], y_new[1] - y_half[1], ev_new[4] - h0, ev_new[5] - h1, y_new[2] - y_half[2]
        c0, c1, c2, c3, c4 = y_new[0] - y0[0], y_new[1] - y0[1], ev_new[4] - ev[4], ev_new[5] - ev[5], y_new[2] - y0[2]
        whole = np.sqrt(c0 * c0 + c1 * c1 + c2 * c2 + c3 * c3 + c4 * c4)
        halves = np.sqrt(a0 * a0 + a1 * a1 + a2 * a2 + a3 * a3 + a4 * a4)
        halves += np.sqrt(b0 * b0 + b1 * b1 + b2 * b2 + b3 * b3 + b4 * b4)
        arc = (4.0 * halves - whole) / 3.0
        if not arc > 0:
            return 0.0
        for k in range(coefficients.shape[0]):
            for j in range(M):
                coefficients[k, j] = 0.0
        for j in range(M):
            coefficients[0, j] = length * rate[j]
            coefficients[1, j] = (arc - length) * rate[j]
        return arc
