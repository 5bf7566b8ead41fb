"""The state of the arclength system, and the model and its tangent at a batch of states.

The engine integrates, per case, y = (v, lambda, internal variables, W): the
state coordinates v (the displacements u for a deformable system), the
driven parameter lambda of the stage, the internal variables of rate laws
(T per contact for Cundall--Strack) and the work W.  dy/ds is the oriented
unit tangent of the constrained rate system
(:func:`ncstab.paths.tangent_field.path_tangent`), the internal-variable
rates along it, and the work rate ``work_factor (F + P Q_ext) . du`` (the
internal forces' power; for the seed's diamond ``F . du / 2``, the work per
contact, seed Eq. 5).

The compiled loop computes dy/ds per case (``rhs`` in its model parts,
:mod:`ncstab.paths.compiled`); the batched functions here serve what runs once
per stage or event, in numpy: stage entry (:mod:`ncstab.paths.stage_entry`)
and branch switching (:mod:`ncstab.paths.branch_switching`).
"""

from __future__ import annotations

from dataclasses import fields as dataclass_fields
from typing import Any

import numpy as np

from ncstab.paths.model import Evaluation
from ncstab.paths.tangent_field import PathTangent, StageArrays, path_tangent

__all__ = ["StateLayout", "evaluate_at", "gather_evaluations", "tangent_at", "work_forces"]


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


def tangent_at(evaluation: Evaluation, stage: StageArrays, lam: np.ndarray) -> PathTangent:
    """The path tangent at evaluated states, not oriented (:func:`~ncstab.paths.tangent_field.path_tangent`)."""
    return path_tangent(evaluation.du_dv, evaluation.dF_dv, stage, lam, evaluation.dF_dload)


def work_forces(evaluation: Evaluation, stage: StageArrays, lam: np.ndarray) -> np.ndarray:
    """The internal forces F + P Q_ext = F - P dF/dP, whose power is the work rate."""
    if evaluation.dF_dload is None:
        return evaluation.forces
    return evaluation.forces - stage.load(lam)[:, None] * evaluation.dF_dload


def gather_evaluations(pieces: list[tuple[np.ndarray, Evaluation]], size: int) -> Evaluation:
    """One Evaluation of ``size`` rows from pieces (row indices, Evaluation of those rows)."""
    if len(pieces) == 1 and pieces[0][0].size == size:
        return pieces[0][1]
    rows = np.concatenate([index for index, _ in pieces])
    order = np.argsort(rows, kind="stable")
    parts = [piece for _, piece in pieces]
    values = []
    for f in dataclass_fields(Evaluation):
        arrays = [getattr(part, f.name) for part in parts]
        if arrays[0] is None:
            values.append(None)
        elif f.name == "interactions":
            values.append(tuple(
                (np.concatenate([a[k][0] for a in arrays])[order], np.concatenate([a[k][1] for a in arrays])[order])
                for k in range(len(arrays[0]))
            ))
        else:
            values.append(np.concatenate(arrays)[order])
    return Evaluation(*values)
