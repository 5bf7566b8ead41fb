"""The state of the arclength system, and the model at a batch of states.

The engine integrates, per case, y = (v, lambda, internal variables, W): the
state coordinates v (the displacements u for a deformable system), the
driven parameter lambda of the stage, the internal variables of rate laws
(T per contact for Cundall--Strack) and the work W.  dy/ds is the oriented
unit tangent of the constrained rate system
(:mod:`ncstab.paths.tangent_field`), the internal-variable
rates along it, and the work rate ``work_factor (F + P Q_ext) . du`` (the
internal forces' power; for the seed's diamond ``F . du / 2``, the work per
contact, seed Eq. 5).

The compiled loop computes dy/ds per case (``rhs`` in its model parts,
:mod:`ncstab.paths.compiled`); the batched evaluation here serves what runs
once per stage or event, in numpy: stage entry (:mod:`ncstab.paths.stage_entry`)
and branch switching (:mod:`ncstab.paths.branch_switching`).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.paths.model import Evaluation
from ncstab.paths.tangent_field import StageArrays

__all__ = ["StateLayout", "evaluate_at", "work_forces"]


class StateLayout:
    """Column layout of the integrated state y = (v, lambda, internal, work)."""

    def __init__(self, n: int, n_internal: int) -> None:
        self.n = n
        self.n_internal = n_internal
        self.v = slice(0, n)
        self.lam = n
        self.internal = slice(n + 1, n + 1 + n_internal)
        self.work = n + 1 + n_internal
        self.size = n + 2 + n_internal


def evaluate_at(batch: Any, stage: StageArrays, y: np.ndarray, layout: StateLayout, geometry_only: bool = False) -> Evaluation:
    """``batch.evaluate`` at the states ``y`` of the stage (the load parameter where the
    system has one, from lambda)."""
    v, internal = y[:, layout.v], y[:, layout.internal]
    if batch.has_load:
        return batch.evaluate(v, internal, stage.secondary_state, geometry_only, load=stage.load(y[:, layout.lam]))
    return batch.evaluate(v, internal, stage.secondary_state, geometry_only)


def work_forces(evaluation: Evaluation, stage: StageArrays, lam: np.ndarray) -> np.ndarray:
    """The internal forces F + P Q_ext = F - P dF/dP, whose power is the work rate."""
    if evaluation.dF_dload is None:
        return evaluation.forces
    return evaluation.forces - stage.load(lam)[:, None] * evaluation.dF_dload
