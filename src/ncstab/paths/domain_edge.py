"""Where a step leaves the admissible domain: its last admissible state, found on its interpolant.

A step (or a piece of one, ``sample_step``) whose end lies outside the domain
(non-finite numbers, or the batch's own conditions: l* > 0 and |alpha| < pi/2
at every contact...) does not end its case at once: the last admissible state
on the step's DOP853 interpolant is found by bisection of the piece, to
``event_tol`` in arclength (projected onto equilibrium for a law with a total
form, as a piece's interior end is), the piece is completed up to there as any
other (its indicators' crossings located, cut at a stage target, a stop or a
contact switch, its events and its end stored), and only then, if nothing cut
it, the case fails with ``left_domain``.  Before, the whole piece was dropped,
and with it an event lying in it: a McNamara case (gamma 2, F2* 0.509 held,
alpha0 = 1) lost its limit point and its loss of Hill's condition, 6e-3 in
arclength before alpha reached pi/2, with steps of 0.01 to 0.05
(``tests/test_domain_edge.py``).  Where no admissible state lies beyond the
piece's start the case fails there, as before.

The compiled loop implements it: ``admissible_at`` and the bisection,
``last_admissible``, in :mod:`ncstab.paths.loop_step_limits`, with the model
parts' ``domain_detail`` (the index of the reason in the batch's
``domain_reasons``).  This module holds its constant.
"""

from __future__ import annotations

__all__ = ["EDGE_HALVINGS"]

#: Most halvings of a piece in search of its last admissible state (fewer where the
#: bracket is below ``event_tol`` first: 2^-60 of any piece is).
EDGE_HALVINGS = 60
