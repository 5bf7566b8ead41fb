"""The accepted steps of one pass of the numpy stepper, and the indicators at their ends."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ncstab.paths.events import indicator_values
from ncstab.paths.rhs import Auxiliary, StateLayout
from ncstab.paths.tangent_field import StageArrays

__all__ = ["AcceptedSteps", "Piece", "indicators_at"]


def indicators_at(batch: Any, stage: StageArrays, y: np.ndarray, aux: Auxiliary, layout: StateLayout) -> np.ndarray:
    """Every indicator column of the batch at the states ``y`` (with ``aux`` there)."""
    return indicator_values(
        aux.evaluation, stage, y[:, layout.lam], aux.dlam, layout=batch.columns, branch=aux.tangent.branch
    )


@dataclass
class AcceptedSteps:
    """The accepted steps of one pass of the stepper, one row per case.

    Attributes
    ----------
    cases
        ``(A,)`` the rows' case indices in the batch.
    batch, stage
        The rows' cases and stage arrays (``stage`` is a copy, changed in place
        where contacts switch or turns close).
    y_start, h
        States at the start of the step and step lengths.
    y_raw, dop853_stages
        DOP853 end states before the Newton projection and the stage
        derivatives ``(stages, A, m)`` (for dense output).
    y_new
        States at the end of the step, then at the cut point where a step is cut.
    dy_new, aux
        dy/ds and the auxiliary quantities at ``y_new``.
    piece
        Where the rows are pieces of longer steps (:mod:`ncstab.paths.step_pieces`):
        their :class:`Piece` (``y_start``, ``h`` the piece's; ``y_raw`` and
        ``dop853_stages`` unused), else None.
    """

    cases: np.ndarray
    batch: Any
    stage: StageArrays
    y_start: np.ndarray
    h: np.ndarray
    y_raw: np.ndarray
    dop853_stages: np.ndarray
    y_new: np.ndarray
    dy_new: np.ndarray | None = None
    aux: Auxiliary | None = None
    piece: Piece | None = None

    def take(self, rows: np.ndarray) -> AcceptedSteps:
        return AcceptedSteps(
            self.cases[rows],
            self.batch.take(rows),
            self.stage.take(rows),
            self.y_start[rows],
            self.h[rows],
            None if self.y_raw is None else self.y_raw[rows],
            None if self.dop853_stages is None else self.dop853_stages[:, rows],
            self.y_new[rows],
            None if self.dy_new is None else self.dy_new[rows],
            None if self.aux is None else self.aux.take(rows),
            None if self.piece is None else self.piece.take(rows),
        )


@dataclass
class Piece:
    """Where rows of :class:`AcceptedSteps` are pieces of longer steps: the longer
    steps' interpolant coefficients ``dense`` ``(power, A, m)``
    (:func:`ncstab.paths.integrator.dense_output`), start states ``step_start``,
    lengths ``step_length``, and each piece's start ``offset`` in its step."""

    dense: np.ndarray
    step_start: np.ndarray
    step_length: np.ndarray
    offset: np.ndarray

    def take(self, rows: np.ndarray) -> Piece:
        return Piece(self.dense[:, rows], self.step_start[rows], self.step_length[rows], self.offset[rows])
