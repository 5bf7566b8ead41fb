"""The path engine: arclength continuation of the rate system, case by case on the compiled loop.

One formulation serves every law and every system: the unit tangent of the
constrained rate system (:mod:`ncstab.paths.tangent_field`) is integrated in
arclength s by DOP853, carrying y = (v, lambda, internal variables, work W)
(:mod:`ncstab.paths.rhs`).  For a law with a total form every accepted step is
projected onto the equilibrium manifold by Newton, so there is no drift; for a
strongly hypoelastic law (T an internal variable) the integration itself is the
path, at the integrator's accuracy.  Events are sign changes of indicators,
located to ``event_tol`` on the step's interpolant; contacts switch where a gap
crosses zero; a stage switching branch leaves a simple bifurcation point along
the bifurcating branch (:mod:`ncstab.paths.branch_switching`).

The steps are taken by the compiled loop (:mod:`ncstab.paths.compiled`, one
numba loop per case, the cases of a stage on every core,
:mod:`ncstab.paths.compiled_stages`).  :class:`BatchStepper` holds the batch's
state and does what happens once per stage or case, in numpy: the cases enter
their stages (:mod:`ncstab.paths.stage_entry`), end, fail or switch branch, and
the stored states, events and cycle tables are assembled into a
:class:`~ncstab.paths.case_result.CaseResult`.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from ncstab.paths import stage_entry
from ncstab.paths.case_ends import CaseEnds
from ncstab.paths.case_result import CaseResult, as_strings, empty_events
from ncstab.paths.cycle_turns import CycleTurns
from ncstab.paths.engine_choice import choose_engine
from ncstab.paths.events import event_tables
from ncstab.paths.options import AUTO, PathOptions
from ncstab.paths.over_steps import reset_over_steps
from ncstab.paths.programme import LoadingProgramme
from ncstab.paths.recorder import Recorder, state_limit
from ncstab.paths.rhs import StateLayout
from ncstab.paths.status import RUNNING
from ncstab.paths.tangent_field import StageArrays
from ncstab.plain_python import PLAIN_ERRORS
from ncstab.sizes import available_memory

__all__ = ["BatchStepper", "follow_cases"]


class BatchStepper(CaseEnds):
    """Arclength continuation of a batch of cases through a loading programme.

    Cases enter their stages here (:func:`ncstab.paths.stage_entry.enter`);
    the compiled loop (:attr:`compiled`) takes each case through its stage to
    the stage's target, a stop event, a branch switch or a failure, and the
    stepper does what the outcome asks.  Cases end when the programme is done,
    at a stop event or on a failure.

    Parameters
    ----------
    batch, programme, values, options, secondary_contacts, progress
        As for :func:`follow_cases`.

    Attributes
    ----------
    y
        ``(B, m)`` each case's current state y = (v, lambda, internal, W).
    derivative
        ``(B, m)`` dy/ds there (first same as last for the next step).
    indicators
        ``(B, columns)`` the event indicators there.
    stages, stage_index
        Each case's current stage (:class:`StageArrays`) and its index.
    status, message
        Per case: ``running``, then how it ended.
    step_size, arclength
        Next step length and arclength s reached.
    accepted, rejected, located
        Counters of steps and located events.
    recorder, events, turns
        Stored states, first occurrences of events, cycle turns.
    """

    def __init__(
        self,
        batch: Any,
        programme: LoadingProgramme,
        values: dict[str, np.ndarray],
        options: PathOptions,
        secondary_contacts: str,
        progress: Callable[[int], None] | None,
        plain: bool | None = None,
        study_cases: int | None = None,
    ) -> None:
        self.batch, self.programme, self.values, self.options = batch, programme, values, options
        self.progress = progress
        self.size = size = batch.size
        n = batch.n_dof
        self.layout = layout = StateLayout(n, batch.n_internal)
        self.dof_names, self.force_names = batch.dof_names, batch.force_names
        self.y = np.zeros((size, layout.size))
        self.y[:, layout.v] = batch.initial_state()
        self.derivative = np.full((size, layout.size), np.nan)
        self.stage_index = np.zeros(size, dtype=int)
        self.status = np.empty(size, dtype=object)  # (np.full is 20x slower for objects)
        self.status[:] = RUNNING
        self.message = np.empty(size, dtype=object)
        self.message[:] = ""
        auto = isinstance(options.initial_step, str) and options.initial_step == AUTO
        self.step_size = np.full(size, np.nan if auto else float(options.initial_step))
        self.arclength = np.zeros(size)
        self.accepted = np.zeros(size, dtype=int)
        self.rejected = np.zeros(size, dtype=int)
        self.located = np.zeros(size, dtype=int)
        self.columns = batch.columns
        self.indicators = np.full((size, self.columns.size), np.nan)
        self.stages = StageArrays.empty(size, n)
        self.stages.secondary_state[:] = batch.initial_secondary_state(self.y[:, layout.v])
        available = available_memory()
        self.recorder = Recorder(size, state_limit(size, self._bytes_per_state(), available), available)
        self.events = empty_events(size, n, self.interaction_shapes())
        self.event_column, self.stop_table, self.break_columns = event_tables(programme, secondary_contacts, self.columns)
        self.turns = CycleTurns(programme, size, n, batch.interaction_shapes.get("T", ()))
        #: Per case: 0 on the path followed from the start, +-1 once it has left along a
        #: bifurcating branch that way (stored with every state of a general model).
        self.branch_index = np.zeros(size, dtype=int)
        #: Per case: the size of the branch test at its state, the length of the over step
        #: it tries next (0: none) and whether that one is degenerate, and the length of the
        #: degenerate one it tries if that finds no reversal (:mod:`ncstab.paths.over_steps`).
        self.branch_size = np.full(size, np.nan)
        self.over_length = np.zeros(size)
        self.over_degenerate = np.zeros(size, dtype=bool)
        self.degenerate_length = np.zeros(size)
        self.compiled, self.engine = choose_engine(batch, programme, options, plain, study_cases)

    @property
    def probe_step(self) -> float:
        """The probe step of the first-step estimate: min(1e-3, max_step)."""
        return stage_entry.probe_step(self)

    def interaction_shapes(self) -> dict[str, tuple[int, ...]]:
        """Stored interaction fields (and ``load``) and their shapes after the case axis."""
        shapes = dict(self.batch.interaction_shapes)
        if self.batch.has_load:
            shapes["load"] = ()
        return shapes

    def run(self) -> CaseResult:
        """Follow every case to its end; the result."""
        stage_entry.enter(self, np.arange(self.size), 0)
        self.compiled.run(self)
        steps, counts = self.recorder.assemble()
        return CaseResult(
            steps=steps,
            n_steps=counts,
            status=as_strings(self.status),
            message=as_strings(self.message),
            events=self.events,
            counters={"accepted": self.accepted, "rejected": self.rejected, "located": self.located},
            cycles=self.turns.tables,
            engine=self.engine,
        )

    # --- stored states ----------------------------------------------------------------------------

    def _bytes_per_state(self) -> int:
        """Bytes one stored state of one case takes in the recorder."""
        return sum(int(np.prod(shape)) * dtype.itemsize for shape, dtype in self.record_fields().values())

    def record_fields(self) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
        """Shape (after the case and step axes) and dtype of each stored field, in order."""
        n, floating = self.batch.n_dof, np.dtype(float)
        shapes: dict[str, tuple[int, ...]] = {"s": (), "stage": (), "u": (n,), "lam": ()}
        if self.batch.has_load:
            shapes["load"] = ()
        shapes.update(internal=(self.layout.n_internal,), work=(), F=(n,))
        shapes.update(self.batch.interaction_shapes)
        shapes.update(K=(n, n), du=(n,), dlam=())
        if self.columns.general:
            shapes["branch_index"] = ()
        integers = ("stage", "branch_index")
        return {name: (shape, np.dtype(int) if name in integers else floating) for name, shape in shapes.items()}

    def next_step_lengths(self, cases: np.ndarray) -> np.ndarray:
        """The longest step each case may take next: its step size (at most ``max_step``),
        or its over step where longer (:mod:`ncstab.paths.over_steps`)."""
        return np.maximum(np.minimum(self.step_size[cases], self.options.max_step), self.over_length[cases])

    def enter_next_stage(self, cases: np.ndarray) -> None:
        """Cases ``cases`` reached their stage target: they enter the next stage."""
        if cases.size:
            # Stage indices before any case enters its next stage (enter() updates them).
            finished_index = self.stage_index[cases].copy()
            reset_over_steps(self, cases)  # a new control: no over step from the last one
            for k in np.unique(finished_index):
                stage_entry.enter(self, cases[finished_index == k], int(k) + 1)


def follow_cases(
    batch: Any,
    programme: LoadingProgramme,
    values: dict[str, np.ndarray],
    options: PathOptions,
    secondary_contacts: str = "activate",
    progress: Callable[[int], None] | None = None,
    study_cases: int | None = None,
) -> CaseResult:
    """Follow a loading programme for a batch of cases of one law.

    Parameters
    ----------
    batch
        The cases (system + law with parameter arrays of shape (B,)).
    programme
        Validated loading programme.
    values
        Every named parameter the programme refers to, as arrays ``(B,)``.
    options
        Engine options.
    secondary_contacts
        ``"activate"``, ``"ignore"`` or ``"stop"`` (see ``SystemSpec``).
    progress
        Called with the number of cases that just ended (progress bars).
    study_cases
        The cases of the whole study where ``batch`` is a chunk of it: the loop's route
        (:func:`ncstab.paths.engine_choice.choose_engine`) weighs the study's work, not the chunk's.

    Returns
    -------
    CaseResult
    """
    stepper = BatchStepper(batch, programme, values, options, secondary_contacts, progress, study_cases=study_cases)
    if not stepper.compiled.plain:
        return stepper.run()
    ended = []

    def counted(count: int) -> None:
        ended.append(count)
        if progress is not None:
            progress(count)

    stepper.progress = counted
    try:
        with np.errstate(all="ignore"):  # inf and NaN as in the machine code, no warnings
            return stepper.run()
    except PLAIN_ERRORS:
        # The plain text raised where the machine code gives inf or NaN (a division by
        # zero between two Python floats): the batch again, compiled.  The progress bar
        # is not told twice of the cases that ended before.
        already = sum(ended)

        def again(count: int) -> None:
            nonlocal already
            told = min(count, already)
            already -= told
            if progress is not None and count > told:
                progress(count - told)

        return BatchStepper(batch, programme, values, options, secondary_contacts, again, plain=False).run()
