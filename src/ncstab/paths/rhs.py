"""The right-hand side of the arclength system: dy/ds at a batch of states.

The engine integrates, per case, y = (v, lambda, internal variables, W): the
state coordinates v (the displacements u for a deformable system), the
driven parameter lambda of the stage, the internal variables of rate laws
(T per contact for Cundall--Strack) and the work W.  dy/ds is the oriented
unit tangent of the constrained rate system
(:func:`ncstab.paths.tangent_field.path_tangent`), the internal-variable
rates along it, and the work rate ``work_factor (F + P Q_ext) . du`` (the
internal forces' power; for the seed's diamond ``F . du / 2``, the work per
contact, seed Eq. 5).
"""

from __future__ import annotations

from dataclasses import dataclass
from dataclasses import fields as dataclass_fields
from typing import Any

import numpy as np

from ncstab.paths.model import Evaluation
from ncstab.paths.tangent_field import PathTangent, StageArrays, path_tangent

__all__ = ["Auxiliary", "StateLayout", "evaluate_at", "gather_evaluations", "state_derivative", "tangent_at"]


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


@dataclass
class Auxiliary:
    """What a right-hand side evaluation knows at its states besides dy/ds."""

    evaluation: Evaluation
    tangent: PathTangent

    @property
    def dv(self) -> np.ndarray:
        return self.tangent.dv

    @property
    def du(self) -> np.ndarray:
        return self.tangent.du

    @property
    def dlam(self) -> np.ndarray:
        return self.tangent.dlam

    def take(self, index: np.ndarray) -> "Auxiliary":
        t = self.tangent
        tangent = PathTangent(
            t.dv[index], t.du[index], t.dF[index], t.dlam[index], t.det_m[index],
            None if t.branch is None else t.branch[index], None if t.flipped is None else t.flipped[index],
        )
        return Auxiliary(self.evaluation.take(index), tangent)

    def put(self, index: np.ndarray, other: "Auxiliary") -> None:
        self.evaluation.put(index, other.evaluation)
        for name in ("dv", "du", "dF", "dlam", "det_m", "branch", "flipped"):
            mine = getattr(self.tangent, name)
            if mine is not None:
                mine[index] = getattr(other.tangent, name)


def evaluate_at(batch: Any, stage: StageArrays, y: np.ndarray, layout: StateLayout, geometry_only: bool = False) -> Evaluation:
    """``batch.evaluate`` at the states ``y`` of the stage (the load parameter where the
    system has one, from lambda)."""
    v, internal = y[:, layout.v], y[:, layout.internal]
    if batch.has_load:
        return batch.evaluate(v, internal, stage.secondary_state, geometry_only, load=stage.load(y[:, layout.lam]))
    return batch.evaluate(v, internal, stage.secondary_state, geometry_only)


def tangent_at(evaluation: Evaluation, stage: StageArrays, lam: np.ndarray, oriented: bool = True) -> PathTangent:
    """The path tangent at evaluated states (:func:`~ncstab.paths.tangent_field.path_tangent`)."""
    return path_tangent(evaluation.du_dv, evaluation.dF_dv, stage, lam, oriented, evaluation.dF_dload)


def state_derivative(
    batch: Any, stage: StageArrays, y: np.ndarray, layout: StateLayout, evaluation: Evaluation | None = None
) -> tuple[np.ndarray, Auxiliary]:
    """dy/ds: oriented unit tangent, internal-variable rates, work rate.

    ``evaluation`` is ``batch.evaluate`` at ``y`` where already known.
    """
    lam = y[:, layout.lam]
    if evaluation is None:
        evaluation = evaluate_at(batch, stage, y, layout)
    tangent = tangent_at(evaluation, stage, lam)
    dinternal = batch.internal_rate(evaluation, tangent.dv, stage.secondary_state)
    dy = np.empty(y.shape)
    dy[:, layout.v] = tangent.dv
    dy[:, layout.lam] = tangent.dlam
    dy[:, layout.internal] = dinternal
    forces = evaluation.forces if evaluation.dF_dload is None else work_forces(evaluation, stage, lam)
    dy[:, layout.work] = batch.work_factor * np.sum(forces * tangent.du, axis=-1)
    return dy, Auxiliary(evaluation, tangent)


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
