"""Per-turn results of the cycle stages of a programme (Green's paradox)."""

from __future__ import annotations

import numpy as np

from ncstab.paths.model import Evaluation
from ncstab.paths.programme import CycleStage, LoadingProgramme

__all__ = ["CycleTurns"]


class CycleTurns:
    """Per-turn results of the cycle stages of a programme (``CaseResult.cycles``).

    A turn starts where a case enters a stage or closes the previous turn, and
    closes where the cycle (or target) column of a cycle stage is cut.

    Attributes
    ----------
    turns
        ``(stages,)`` turns of each stage (0 for a linear stage).
    first
        ``(stages,)`` column of each stage's first turn in the tables.
    tables
        ``work`` ``(B, C)``: the work per contact over the turn (seed Eq. 5,
        from the integrated work W); ``force_gap`` ``(B, C, n)``: F at the end
        minus F at the start; ``tangential_drift`` ``(B, C)``: the same for T;
        ``stage`` ``(C,)``.
    start_work, start_forces, start_tangential
        W, F and T where each case's current turn started.
    """

    def __init__(self, programme: LoadingProgramme, size: int, n: int, members: tuple[int, ...] = ()) -> None:
        self.turns = np.array([st.turns if isinstance(st, CycleStage) else 0 for st in programme.stages])
        self.first = np.concatenate([[0], np.cumsum(self.turns)])[:-1].astype(int)
        n_cycles = int(self.turns.sum())
        self.tables = {
            "work": np.full((size, n_cycles), np.nan),
            "force_gap": np.full((size, n_cycles, n), np.nan),
            "tangential_drift": np.full((size, n_cycles, *members), np.nan),
            "stage": np.repeat(np.arange(len(programme)), self.turns).astype(int),
        }
        self.start_work = np.zeros(size)
        self.start_forces = np.zeros((size, n))
        self.start_tangential = np.zeros((size, *members))
        self.members = members

    def start(self, cases: np.ndarray, work: np.ndarray, evaluation: Evaluation) -> None:
        """A turn starts for ``cases`` at the work ``work`` and the state of ``evaluation``."""
        self.start_work[cases] = work
        self.start_forces[cases] = evaluation.forces
        self.start_tangential[cases] = self._tangential(evaluation)

    def close(
        self,
        cases: np.ndarray,
        stage_index: np.ndarray,
        turn: np.ndarray,
        work: np.ndarray,
        evaluation: Evaluation,
    ) -> None:
        """Turn ``turn`` of stage ``stage_index`` closes for ``cases``; the next turn starts."""
        slot = self.first[stage_index] + turn
        self.tables["work"][cases, slot] = work - self.start_work[cases]
        self.tables["force_gap"][cases, slot] = evaluation.forces - self.start_forces[cases]
        drift = self._tangential(evaluation) - self.start_tangential[cases]
        self.tables["tangential_drift"][cases, slot] = drift
        self.start(cases, work, evaluation)

    def _tangential(self, evaluation: Evaluation) -> np.ndarray:
        """T of the (first) contact family: ``(rows,)``, or ``(rows, m)`` for several members."""
        if evaluation.tangential is None:
            return np.full((evaluation.forces.shape[0], *self.members), np.nan)
        return evaluation.tangential if self.members else evaluation.tangential[:, 0]
