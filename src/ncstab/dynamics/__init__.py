"""Dynamics after the loss of stability: time integration of a programme's last stage.

A dynamic stage (:class:`DynamicStage`) integrates the nonlinear motion
M(u) u'' + Gamma(u, u') + C u' + R(u, lambda) = F under the stage's controls from
where the programme's earlier stages left each case, with its energy balance
(:mod:`ncstab.dynamics.equations`), and the events during it -- a secondary
contact closing, a kinetic-energy threshold -- located on the integrator's dense
output (:mod:`ncstab.dynamics.motion_events`).  Layer ``dynamics/`` of the architecture:
it knows the operators and the model's compiled kernel, not the studies.
"""

from ncstab.dynamics.motion import Motion, integrate_motion
from ncstab.dynamics.motion_events import MotionEvent, event_watch
from ncstab.dynamics.runs import follow_motions, motion_dataset
from ncstab.dynamics.stage import MOTION_EVENTS, DynamicStage, parse_dynamic_stage

__all__ = ["MOTION_EVENTS", "DynamicStage", "Motion", "MotionEvent", "event_watch", "follow_motions", "integrate_motion",
           "motion_dataset", "parse_dynamic_stage"]
