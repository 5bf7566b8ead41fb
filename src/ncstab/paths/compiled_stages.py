"""Drive the compiled stage loop from the engine's stepper.

:class:`CompiledStages` hands every running case of a
:class:`ncstab.paths.stepper.BatchStepper` to the compiled loop of
:mod:`ncstab.paths.compiled` for the rest of its current stage, then does
with the outcome what it asks: stores the steps, ends or fails the case,
leaves a bifurcation point along a branch, or enters its next stage (stage
entry stays with the stepper).
The cases of a stage run side by side on threads
(:func:`ncstab.paths.threads.thread_count`: every core unless
``NUMBA_NUM_THREADS``, :func:`ncstab.paths.threads.using_threads` or ``ncstab
run --threads`` says fewer): thread t runs every t-th case through the
compiled loop, which releases the GIL.
"""

from __future__ import annotations

import functools
from typing import TYPE_CHECKING, Any, NamedTuple

import numpy as np

from ncstab.paths.compiled import EVENT_FIELDS, Outcome, StageLoop
from ncstab.paths.loop_records import (
    CaseRows, EventTables, ModelRows, Outcomes, Records, StageRows, StepSettings, TurnTables,
)
from ncstab.paths.over_steps import reset_over_steps
from ncstab.paths.programme import EVENTS
from ncstab.paths.threads import side_by_side, thread_count

if TYPE_CHECKING:
    from ncstab.paths.model import CaseBatch
    from ncstab.paths.stepper import BatchStepper

__all__ = ["SHARE_BLOCK", "STEPS_PER_CALL", "CompiledStages", "control_rows"]

#: Room the recorder must have per case before a call, in steps (each storing
#: ``options.pieces`` of its length: the next step's, estimated from the step
#: size): a case whose steps would overfill the recorder pauses, the recorder
#: grows and the next call goes on from there.
STEPS_PER_CALL = 1
#: Least growth of the recorder where it grows to an estimate of what the paused cases
#: still need (:meth:`CompiledStages._reserve_for_the_rest`).
ESTIMATED_GROWTH = 1.25
#: The margin on the estimate of the states a paused case still needs from the path's
#: present slope (:meth:`CompiledStages._reserve_for_the_rest`).
TANGENT_MARGIN = 1.2
#: Consecutive cases that go to the same thread (:meth:`CompiledStages._run_shared`).
#: Dealt one by one, neighbouring cases' counters and states (8 to 40 bytes each) shared
#: cache lines across the two threads: on 65,536 cases the loop ran 1.82-1.88x faster on
#: 2 threads than on 1; in blocks of 64, 1.88-2.05x (docs/paths.md).
SHARE_BLOCK = 64


class _TurnEnd(NamedTuple):
    """What :class:`~ncstab.paths.cycle_turns.CycleTurns` reads of the state where a turn
    closes: F ``(B, 2)`` and T ``(B, 1)``."""

    forces: np.ndarray
    tangential: np.ndarray


def control_rows(stages: Any) -> np.ndarray:
    """Each case's control path as the loop reads it (``control`` of
    :mod:`ncstab.paths.loop_diamond_model`): is_cycle, the offset and slope of g (two dofs),
    then a cycle's centre, radius, theta0 and direction (``StageArrays.control_path``)."""
    return np.ascontiguousarray(np.column_stack([
        stages.is_cycle.astype(float), stages.offset, stages.slope, stages.center, stages.radius, stages.theta0,
        stages.turn_direction.astype(float),
    ]))


class CompiledStages:
    """The compiled stage loop bound to one batch.

    Parameters
    ----------
    batch
        The stepper's cases (one law, fused kernel).
    loop
        :func:`ncstab.paths.compiled.stage_runner` for that law.
    """

    #: Whether the loop runs as plain Python (:mod:`ncstab.plain_python`; set by
    #: :func:`ncstab.paths.engine_choice.choose_engine`).
    plain = False

    def __init__(self, batch: CaseBatch, loop: StageLoop) -> None:
        size = batch.size
        self.runner = loop.run
        self.starter = loop.start
        self.settler = loop.settle
        self.law = loop.law
        self.kind = loop.kind
        # Per case (compiled.KAPPA_SLOT, ...): kappa, whether the secondary-contact springs act,
        # the contact-state bits (kept in step with the stepper's around each call), whether
        # the law reads alpha, then the law's parameters.
        values = [
            np.broadcast_to(np.asarray(batch.kappa, dtype=float), (size,)),
            np.full(size, 1.0 if batch.activate_secondary else 0.0),
            np.zeros(size),
            np.full(size, 1.0 if loop.uses_alpha else 0.0),
        ]
        values += [np.broadcast_to(np.asarray(v, dtype=float), (size,)) for v in batch.law.parameter_values()]
        self.parameters = np.ascontiguousarray(np.stack(values, axis=-1))
        cos0, sin0 = batch._alpha0_trig
        # each case's geometry row as the loop reads it: (cos alpha0, sin alpha0)
        self.geometry = np.column_stack([np.broadcast_to(cos0, (size,)), np.broadcast_to(sin0, (size,))]).astype(float)
        self.code = np.zeros(size, dtype=np.int64)
        self.detail = np.zeros(size, dtype=np.int64)
        #: Width of a located event's row (:func:`ncstab.paths.loop_diamond` ``store_event``).
        self.event_width = len(EVENT_FIELDS)
        #: Width of a closed turn's row: W, F1, F2, T (``turn_record``).
        self.turn_width = 4

    @staticmethod
    def turn_end(row: np.ndarray) -> _TurnEnd:
        """F and T where turns close, from the loop's rows (W, F1, F2, T)."""
        return _TurnEnd(forces=row[:, 1:3], tangential=row[:, 3:4])

    def control_rows(self, stages: Any) -> np.ndarray:
        """Each case's control path as the loop's model part reads it."""
        return control_rows(stages)

    def recorded(self, stepper: BatchStepper) -> tuple:
        """The arrays the loop's ``store_record`` writes: the recorder's, in the order of
        ``stepper.record_fields()``."""
        return tuple(stepper.recorder.arrays[name] for name in stepper.record_fields())

    def after_call(self, stepper: BatchStepper, cases: np.ndarray, count_before: np.ndarray) -> None:
        """What the states a call stored still need (nothing: the diamond's loop stores every field)."""

    def start(self, stepper: BatchStepper, cases: np.ndarray) -> None:
        """Cases ``cases`` start their (set up) stage: dy/ds, indicators and the state stored;
        the first step length where it is still to be estimated."""
        self._store_start(stepper, cases)
        stages = stepper.stages
        cycling = cases[stages.is_cycle[cases]]
        if cycling.size:  # stage_entry._start_stage: a turn starts (W, F and T there)
            from ncstab.paths.rhs import evaluate_at

            evaluation = evaluate_at(stepper.batch.take(cycling), stages.take(cycling), stepper.y[cycling], stepper.layout)
            stepper.turns.start(cycling, stepper.y[cycling, stepper.layout.work], evaluation)

    def settle(self, stepper: BatchStepper, cases: np.ndarray, stage: Any, projected: bool) -> np.ndarray:
        """The loop's ``settle`` (:mod:`ncstab.paths.loop_start`) for cases ``cases`` in
        ``stage`` (their stage arrays, row k for case ``cases[k]``): where ``projected``,
        their states ``stepper.y`` projected onto equilibrium in place by the loop's Newton
        projection; dlambda/ds of the unoriented path tangent there."""
        rates = np.full(cases.size, np.nan)
        options = stepper.options
        self.settler(
            cases.astype(np.int64), stepper.y, np.ascontiguousarray(stage.force_controlled), self.control_rows(stage),
            np.ascontiguousarray(stage.secondary_state, dtype=np.int64), self._model_rows(), projected,
            options.newton_tol, options.newton_max_iter, rates,
        )
        return rates

    def _store_start(self, stepper: BatchStepper, cases: np.ndarray) -> None:
        """dy/ds and the indicators at the states of ``cases``, and the states stored (the
        first step length where it is still to be estimated)."""
        recorder = stepper.recorder
        recorder.create(stepper.record_fields())
        recorder.reserve(int(recorder.count[cases].max()) + 1 if cases.size else 0)
        stages = stepper.stages
        count_before = recorder.count[cases].copy()
        stage_number = int(stepper.stage_index[cases[0]]) if cases.size else 0
        self._run_shared(self.starter, cases.astype(np.int64), (
            self._case_rows(stepper), self._stage_rows(stages, np.ascontiguousarray(stages.secondary_state, dtype=np.int64)),
            Records(self.recorded(stepper), recorder.count, stage_number), self._model_rows(),
            stepper.probe_step, self._settings(stepper.options),
        ))
        self.after_call(stepper, cases, count_before)

    def run(self, stepper: BatchStepper) -> None:
        """Run every running case of ``stepper`` to its end, stage by stage."""
        from ncstab.paths.status import RUNNING

        size = stepper.size
        columns = max(len(c) for c in stepper.event_column.values())
        event_columns = np.full((len(EVENTS), columns), -1, dtype=np.int64)
        for e, name in enumerate(EVENTS):
            event_columns[e, : len(stepper.event_column[name])] = stepper.event_column[name]
        found = np.ascontiguousarray(np.stack([stepper.events[name]["found"] for name in EVENTS]))
        values = np.empty((len(EVENTS), size, self.event_width))  # read where found only
        stage = np.stack([stepper.events[name]["stage"] for name in EVENTS]).astype(np.int64)
        n_turns = int(stepper.turns.turns.sum())
        turn_closed = np.zeros((size, n_turns), dtype=bool)
        turn_values = np.empty((size, n_turns, self.turn_width))  # W, F, T where a turn closes
        while True:
            active = np.flatnonzero(stepper.status == RUNNING)
            if active.size == 0:
                break
            for k in np.unique(stepper.stage_index[active]):
                stages = stepper.stages  # (entering a stage may replace it)
                # (a case that ended, or failed entering its next stage, earlier in this pass stays out)
                cases = active[(stepper.stage_index[active] == k) & (stepper.status[active] == RUNNING)]
                if cases.size == 0:
                    continue
                recorder = stepper.recorder
                # room for the next step's pieces of every case
                pieces = stepper.options.pieces(stepper.next_step_lengths(cases))
                recorder.reserve_within_limit(int((recorder.count[cases] + STEPS_PER_CALL * pieces).max()))
                lam_before, count_before = stepper.y[cases, stepper.layout.lam], recorder.count[cases]
                secondary_state = np.ascontiguousarray(stages.secondary_state, dtype=np.int64)
                arguments = (
                    self._case_rows(stepper), self._stage_rows(stages, secondary_state),
                    TurnTables(int(stepper.turns.turns[k]), int(stepper.turns.first[k]), turn_closed, turn_values),
                    EventTables(stepper.stop_table[k], stepper.break_columns, event_columns, found, values, stage),
                    Records(self.recorded(stepper), recorder.count, int(k)), Outcomes(self.code, self.detail),
                    self._model_rows(), self._settings(stepper.options),
                )
                self._run_shared(self.runner, cases.astype(np.int64), arguments)
                self.after_call(stepper, cases, count_before)
                self._close_turns(stepper, int(k), turn_closed, turn_values)
                self._reserve_for_the_rest(stepper, cases, lam_before, count_before)
                self._fail_beyond_the_limit(stepper, cases)
                stages.secondary_state[cases] = secondary_state[cases]  # contacts switched in the loop
                self._end(stepper, cases)
        self._store_events(stepper, found, values, stage)

    def _reserve_for_the_rest(
        self, stepper: BatchStepper, cases: np.ndarray, lam_before: np.ndarray, count_before: np.ndarray
    ) -> None:
        """Grow the recorder once for what the paused cases of a call still need.

        A case pauses when the recorder is full.  What it still needs is estimated
        two ways, and the smaller is taken: its states per unit of the stage
        parameter lambda so far, times what is left to the stage's end
        (``lam_end``), which counts the short first steps of a case again and so
        overestimates (1.1 to 2.1 times on the 4,096-case Cundall-Strack sweep);
        and the arclength left at the path's present slope dlambda/ds, over the
        spacing of stored states (``stored_spacing``, or the step where it is
        shorter), times :data:`TANGENT_MARGIN` (0.88 to 1.07 times there, before
        the margin).  The recorder grows once to the largest of the cases' counts
        plus their estimates (and a tenth more, and the pieces of one more step, the
        room a call asks for before it runs), by a factor of at least
        :data:`ESTIMATED_GROWTH` rather than doubling, so that an estimate that
        falls short costs a few more growths, not twice the memory.  Only the
        memory depends on it, not a number stored.
        """
        paused = self.code[cases] == Outcome.PAUSED
        if not paused.any():
            return
        cases, lam_before, count_before = cases[paused], lam_before[paused], count_before[paused]
        count = stepper.recorder.count[cases]
        lam, lam_end = stepper.y[cases, stepper.layout.lam], stepper.stages.lam_end[cases]
        spacing = np.fmin(stepper.options.stored_spacing, stepper.step_size[cases])
        with np.errstate(divide="ignore", invalid="ignore"):
            by_progress = (count - count_before) * np.abs((lam_end - lam) / (lam - lam_before))
            slope = np.abs(stepper.derivative[cases, stepper.layout.lam])
            by_tangent = TANGENT_MARGIN * np.abs(lam_end - lam) / (slope * spacing)
        rest = np.fmin(by_progress, by_tangent)  # (either where the other is NaN)
        known = np.isfinite(rest)
        if known.any():
            # and room for one more step's pieces, which a call asks for before it runs
            room = STEPS_PER_CALL * stepper.options.pieces(stepper.next_step_lengths(cases[known]))
            rest = np.minimum(1.1 * rest[known] + room, 16 * stepper.recorder.capacity)
            stepper.recorder.reserve_within_limit(int((count[known] + rest).max()), growth=ESTIMATED_GROWTH)

    def _fail_beyond_the_limit(self, stepper: BatchStepper, cases: np.ndarray) -> None:
        """Fail the paused cases whose next step could store more states than the
        recorder's limit (``failed:memory``: a case pauses where its next step would
        overfill the recorder, which grows up to the limit)."""
        if stepper.recorder.limit is None:
            return
        paused = cases[self.code[cases] == Outcome.PAUSED]
        pieces = stepper.options.pieces(stepper.next_step_lengths(paused))
        fits = stepper.recorder.fits(paused, pieces)
        stepper.fail_memory(paused[~fits])

    @staticmethod
    def _case_rows(stepper: BatchStepper) -> CaseRows:
        """The stepper's per-case arrays the loop reads and writes."""
        return CaseRows(
            stepper.y, stepper.derivative, stepper.indicators, stepper.step_size, stepper.arclength, stepper.accepted,
            stepper.rejected, stepper.located, stepper.branch_size, stepper.over_length, stepper.over_degenerate,
            stepper.degenerate_length,
        )

    def _stage_rows(self, stages: Any, secondary_state: np.ndarray) -> StageRows:
        """The stage's per-case arrays, its contact states ``secondary_state`` (int64, which
        the loop switches in place)."""
        return StageRows(
            stages.force_controlled, self.control_rows(stages), stages.lam_end, stages.target_sign,
            stages.orientation, stages.reference, secondary_state, stages.cycles_done,
            (stages.switch != 0) & ~stages.switched,
        )

    def _model_rows(self) -> ModelRows:
        """The model's record, the law's callback and each case's parameters and geometry."""
        return ModelRows(self.kind, self.law, self.parameters, self.geometry)

    @staticmethod
    def _settings(options: Any) -> StepSettings:
        """The options the loop reads, typed as it compiles them."""
        return StepSettings(
            float(options.rtol), float(options.atol), float(options.newton_tol), int(options.newton_max_iter),
            float(options.min_step), float(options.max_step), int(options.max_steps), float(options.event_tol),
            float(options.stored_spacing), int(options.max_pieces),
        )

    def _close_turns(self, stepper: BatchStepper, k: int, closed: np.ndarray, values: np.ndarray) -> None:
        """The turns of stage ``k`` the loop closed go into the stepper's cycle tables, in
        order (:meth:`ncstab.paths.cycle_turns.CycleTurns.close`)."""
        first = int(stepper.turns.first[k])
        for turn in range(int(stepper.turns.turns[k])):
            cases = np.flatnonzero(closed[:, first + turn])
            if cases.size == 0:
                continue
            row = values[cases, first + turn]
            where = self.turn_end(row)
            stepper.turns.close(cases, np.full(cases.size, k), np.full(cases.size, turn), row[:, 0], where)
            closed[cases, first + turn] = False

    def _run_shared(self, function: Any, cases: np.ndarray, arguments: tuple) -> None:
        """Run ``cases`` through ``function`` (the compiled loop's ``run_cases`` or
        ``start``: ``function(cases, *arguments)``, each case on its own rows), in shares on
        :func:`~ncstab.paths.threads.thread_count` threads: blocks of
        :data:`SHARE_BLOCK` consecutive cases dealt out in turn (costly cases of a
        sweep sit side by side, so dealing shares them out; whole blocks keep
        each thread's per-case writes off the other's cache lines).  A case's
        arithmetic does not depend on its thread or share: the results are bit
        for bit those of one thread."""
        threads = max(1, min(thread_count(), -(-cases.size // SHARE_BLOCK)))  # a block at least each
        if threads == 1:
            function(cases, *arguments)
            return
        dealt = np.arange(cases.size) // SHARE_BLOCK % threads
        # contiguous shares: one compiled signature whatever the count
        shares = [np.ascontiguousarray(cases[dealt == t]) for t in range(threads)]
        side_by_side([functools.partial(function, share, *arguments) for share in shares], "stepper")

    def _end(self, stepper: BatchStepper, cases: np.ndarray) -> None:
        """Do what each case's outcome asks (:class:`~ncstab.paths.case_ends.CaseEnds`' texts and statuses)."""
        code, detail = self.code[cases], self.detail[cases]
        stopped = code == Outcome.STOPPED
        stepper.stop(cases[stopped], detail[stopped])
        stepper.fail_step_size_underflow(cases[code == Outcome.STEP_SIZE_UNDERFLOW])
        outside = code == Outcome.LEFT_DOMAIN
        stepper.fail_outside_domain(cases[outside], np.asarray(stepper.batch.domain_reasons)[detail[outside]])
        stepper.fail_max_steps(cases[code == Outcome.MAX_STEPS])
        stepper.fail_singular_branch(cases[code == Outcome.SINGULAR_BRANCH])
        self._switch_branches(stepper, cases[code == Outcome.BRANCH_SWITCH])
        stepper.enter_next_stage(cases[code == Outcome.TARGET])

    def _switch_branches(self, stepper: BatchStepper, cases: np.ndarray) -> None:
        """Cases the loop returned at a simple bifurcation point of a stage that switches
        branch leave along the bifurcating branch
        (:func:`ncstab.paths.branch_switching.leave_along_branch`); their new
        state is stored, and the loop goes on from it with the motion there as reference."""
        if cases.size == 0:
            return
        from ncstab.paths.branch_switching import branch_motion, leave_along_branch

        layout, stages = stepper.layout, stepper.stages
        stage = stages.take(cases)
        batch = stepper.batch.take(cases)
        incoming = np.concatenate([stepper.derivative[cases][:, layout.v], stepper.derivative[cases, layout.lam, None]],
                                  axis=-1)
        stepper.y[cases], direction = leave_along_branch(batch, stage, stepper.y[cases], incoming, layout)
        if batch.has_total_form:  # back onto equilibrium, by the loop's projection
            self.settle(stepper, cases, stage, projected=True)
        stages.reference[cases] = branch_motion(batch, stage, stepper.y[cases], direction, layout)
        stages.switched[cases] = True
        stepper.branch_index[cases] = stage.switch
        reset_over_steps(stepper, cases)  # none planned from the bifurcation point (its branch test is ~0 there)
        self._store_start(stepper, cases)

    def _store_events(
        self, stepper: BatchStepper, found: np.ndarray, values: np.ndarray, stage: np.ndarray
    ) -> None:
        """Copy the first events the loop located into the stepper's event tables."""
        for e, name in enumerate(EVENTS):
            table = stepper.events[name]
            rows = np.flatnonzero(found[e] & ~table["found"])
            if rows.size == 0:
                continue
            table["found"][rows] = True
            table["stage"][rows] = stage[e, rows]
            self.event_fields(stepper, table, rows, values[e, rows])

    @staticmethod
    def event_fields(stepper: BatchStepper, table: dict, rows: np.ndarray, row_values: np.ndarray) -> None:
        """An event table's fields at ``rows`` from the loop's event rows (:data:`EVENT_FIELDS`)."""
        for key in ("s", "s_lower", "s_upper", "lam", "l", "alpha", "N", "T"):
            table[key][rows] = row_values[:, EVENT_FIELDS.index(key)]
        for key, first in (("u", "u0"), ("F", "F0"), ("K", "K00")):
            start = EVENT_FIELDS.index(first)
            shape = table[key].shape[1:]
            table[key][rows] = row_values[:, start : start + int(np.prod(shape))].reshape((-1, *shape))
