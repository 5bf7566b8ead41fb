"""Dynamics after the loss of stability: time integration of a programme's last stage.

A dynamic stage (:class:`DynamicStage`) integrates the nonlinear motion
M(u) u'' + Gamma(u, u') + C u' + R(u, lambda) = F under the stage's controls from
where the programme's earlier stages left each case, with its energy balance
(:mod:`ncstab.dynamics.equations`).  Layer ``dynamics/`` of the architecture:
it knows the operators and the model's compiled kernel, not the studies.
"""

from ncstab.dynamics.motion import Motion, integrate_motion
from ncstab.dynamics.runs import follow_motions, motion_dataset
from ncstab.dynamics.stage import DynamicStage, parse_dynamic_stage

__all__ = ["DynamicStage", "Motion", "follow_motions", "integrate_motion", "motion_dataset", "parse_dynamic_stage"]
