"""Stability boundaries as curves: an event's condition continued in two parameters.

:func:`boundary` traces the boundary of ``limit_point``, ``hill_loss``,
``bifurcation``, ``flutter_onset`` or ``divergence`` along a parameter
(docs/boundaries.md); :mod:`~ncstab.boundaries.conditions` holds the extended
system, :mod:`~ncstab.boundaries.continuation` the pseudo-arclength continuation
with its bordered Newton corrector, :mod:`~ncstab.boundaries.dataset` the Dataset.
"""

from ncstab.boundaries.conditions import BOUNDARY_EVENTS, BoundaryError, BoundaryProblem
from ncstab.boundaries.continuation import ContinuationOptions, trace_curve
from ncstab.boundaries.trace import boundary, check_boundary

__all__ = ["BOUNDARY_EVENTS", "BoundaryError", "BoundaryProblem", "ContinuationOptions", "boundary", "check_boundary", "trace_curve"]
