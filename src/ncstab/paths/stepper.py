"""The batched path engine: arclength continuation of the rate system.

All cases of one law advance together as arrays (B cases, per-case step sizes,
masks for finished cases).  One formulation serves every law and every
system: the unit tangent of the constrained rate system
(:mod:`ncstab.paths.tangent_field`) is integrated in arclength s with a
batched DOP853 step (:mod:`ncstab.paths.projection`), carrying
y = (u, lambda, internal variables, work W) (:mod:`ncstab.paths.rhs`).  For
a law with a total form every accepted step is then projected onto the
equilibrium manifold by Newton, so there is no drift; for a strongly
hypoelastic law (T an internal variable) the integration itself is the path,
at the integrator's accuracy.  Events are sign changes of indicators over an
accepted step, located by root finding on the step length
(:mod:`ncstab.paths.crossings`); contacts switch where a gap crosses zero
(:mod:`ncstab.paths.contacts`); cases enter their stages in
:mod:`ncstab.paths.stage_entry`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Callable

import numpy as np

from ncstab.paths import stage_entry
from ncstab.paths.case_result import NUMPY_ENGINE, CaseResult, as_strings, empty_events
from ncstab.paths.contacts import switch_contacts
from ncstab.paths.crossings import event_tables, locate_crossings, store_first_events
from ncstab.paths.cycle_turns import CycleTurns
from ncstab.paths.events import indicator_values
from ncstab.paths.integrator import END_STAGE, step_factor
from ncstab.paths.options import AUTO, PathOptions
from ncstab.paths.programme import LoadingProgramme
from ncstab.paths.projection import advance
from ncstab.paths.recorder import Recorder
from ncstab.paths.rhs import Auxiliary, StateLayout, evaluate_at, state_derivative
from ncstab.paths.status import FINISHED, RUNNING, failed, stopped
from ncstab.paths.tangent_field import StageArrays

if TYPE_CHECKING:
    from ncstab.paths.compiled_stages import CompiledStages

__all__ = ["BatchStepper", "follow_cases"]


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

    def take(self, rows: np.ndarray) -> AcceptedSteps:
        return AcceptedSteps(
            self.cases[rows],
            self.batch.take(rows),
            self.stage.take(rows),
            self.y_start[rows],
            self.h[rows],
            self.y_raw[rows],
            self.dop853_stages[:, rows],
            self.y_new[rows],
            None if self.dy_new is None else self.dy_new[rows],
            None if self.aux is None else self.aux.take(rows),
        )


class BatchStepper:
    """Arclength continuation of a batch of cases through a loading programme.

    Every running case advances by one DOP853 step per pass (:meth:`step`),
    all cases as arrays.  Sign changes of the indicators over an accepted step
    are located; the first crossing that ends the stage, stops the case or
    switches a contact cuts the step there.  Cases enter their next stage at
    the target (:func:`ncstab.paths.stage_entry.enter`) and end when the
    programme is done, at a stop event or on a failure.

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
        self.recorder = Recorder(size)
        self.events = empty_events(size, n, self.interaction_shapes())
        self.event_column, self.stop_table, self.break_columns = event_tables(programme, secondary_contacts, self.columns)
        self.turns = CycleTurns(programme, size, n, batch.interaction_shapes.get("T", ()))
        #: Per case: 0 on the path followed from the start, +-1 once it has left along a
        #: bifurcating branch that way (stored with every state of a general model).
        self.branch_index = np.zeros(size, dtype=int)
        self.compiled, self.engine = _compiled_stepper(batch, programme, options)

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
        if self.compiled is not None:
            self.compiled.run(self)
        while self.step():
            pass
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

    # --- ending cases and storing states ---------------------------------------------------------

    def end(self, index: np.ndarray, state: str, text: str | np.ndarray) -> None:
        """Cases ``index`` end with status ``state`` and message ``text``."""
        if index.size:
            self.status[index] = state
            self.message[index] = text
            if self.progress:
                self.progress(index.size)

    def fail(self, index: np.ndarray, reason: str, text: str | np.ndarray) -> None:
        """Cases ``index`` fail (status ``failed:<reason>``)."""
        self.end(index, failed(reason), text)

    def finish(self, index: np.ndarray) -> None:
        """Cases ``index`` have done every stage."""
        self.end(index, FINISHED, f"finished all {len(self.programme)} loading stage(s)")

    def record(self, index: np.ndarray, y: np.ndarray, aux: Auxiliary, stage: StageArrays) -> None:
        """Store the states ``y`` of cases ``index`` (with ``aux`` there, in ``stage``)."""
        ev = aux.evaluation
        lam = y[:, self.layout.lam]
        fields = dict(s=self.arclength[index], stage=self.stage_index[index], u=ev.displacements, lam=lam)
        if self.batch.has_load:
            fields["load"] = stage.load(lam)
        fields.update(internal=y[:, self.layout.internal], work=y[:, self.layout.work], F=ev.forces)
        fields.update(self.batch.record_interactions(ev))
        fields.update(K=ev.stiffness, du=aux.du, dlam=aux.dlam)
        if self.columns.general:
            fields["branch_index"] = self.branch_index[index]
        self.recorder.add(index, **fields)

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

    # --- one pass of the loop --------------------------------------------------------------------

    def step(self) -> bool:
        """Advance every running case by one step; False when none is running."""
        active = np.flatnonzero(self.status == RUNNING)
        if active.size == 0:
            return False
        steps = self._take_steps(active)
        if steps is not None:
            steps = self._fail_outside_domain(steps)
        if steps is not None:
            self._complete(steps)
        return True

    def _take_steps(self, active: np.ndarray) -> AcceptedSteps | None:
        """One DOP853 step (Newton-projected for total forms) of the cases ``active``.

        Returns the accepted steps (None if none) with dy/ds and the auxiliary
        quantities at their ends, reusing what the step already evaluated there.
        """
        batch = self.batch.take(active) if active.size < self.size else self.batch
        stage = self.stages.take(active)
        y0 = self.y[active]
        h0 = np.minimum(self.step_size[active], self.options.max_step)
        y1, err, y_raw, dop853_stages, end_aux = advance(
            batch, stage, y0, h0, self.layout, self.options, self.derivative[active]
        )
        local = np.flatnonzero(self._control_step_size(active, h0, err))
        if local.size == 0:
            return None
        steps = AcceptedSteps(active, batch, stage, y0, h0, y_raw, dop853_stages, y1)
        every = local.size == active.size  # no copies then (stage is a copy of self.stages already)
        if not every:
            steps = steps.take(local)
        if isinstance(end_aux, Auxiliary):  # the last DOP853 stage was evaluated at the end state
            if every:
                steps.dy_new, steps.aux = dop853_stages[END_STAGE].copy(), end_aux
            else:
                steps.dy_new, steps.aux = dop853_stages[END_STAGE][local], end_aux.take(local)
        else:  # the Newton projection's last evaluation, where it covers every case
            known = end_aux if every or end_aux is None else end_aux.take(local)
            steps.dy_new, steps.aux = state_derivative(steps.batch, steps.stage, steps.y_new, self.layout, known)
        return steps

    def _control_step_size(self, active: np.ndarray, h0: np.ndarray, err: np.ndarray) -> np.ndarray:
        """Next step sizes from the error norms ``err`` of steps ``h0``; the mask of accepted steps.

        Counts the rejected steps and fails the cases whose step size fell
        below ``min_step``.
        """
        accept = err <= 1.0
        factor = np.where(np.isfinite(err), step_factor(err), 0.25)
        factor = np.where(accept, factor, np.minimum(factor, 0.9))
        self.step_size[active] = np.clip(h0 * factor, 0.0, self.options.max_step)
        self.rejected[active[~accept]] += 1
        underflow = ~accept & (self.step_size[active] < self.options.min_step)
        self.fail_step_size_underflow(active[underflow])
        return accept

    def fail_step_size_underflow(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: their step size fell below ``min_step``."""
        self.fail(
            cases,
            "step_size_underflow",
            "the step size fell below min_step: the path cannot be continued "
            "(non-convergent Newton projection, a kink or a singular point)",
        )

    def fail_outside_domain(self, cases: np.ndarray, why: np.ndarray) -> None:
        """Cases ``cases`` fail: they left the admissible domain (``why``, per case)."""
        for reason in np.unique(why):
            which = cases[why == reason]
            self.fail(
                which,
                "left_domain",
                f"the path left the admissible domain ({reason}) in stage "
                f"{self.stage_index[which[0]] + 1}",
            )

    def _fail_outside_domain(self, steps: AcceptedSteps) -> AcceptedSteps | None:
        """Fail the cases whose new state left the admissible domain (finite numbers,
        and the batch's own conditions: l* > 0 and |alpha| < pi/2 at every contact...).

        Returns the other cases' steps (None if none).
        """
        evaluation = steps.aux.evaluation
        finite = np.isfinite(steps.y_new).all(-1) & np.isfinite(evaluation.forces).all(-1)
        codes = np.where(finite, steps.batch.domain_codes(evaluation), 0)
        outside = codes >= 0
        if outside.any():
            why = np.asarray(steps.batch.domain_reasons)[np.maximum(codes, 0)]
            self.fail_outside_domain(steps.cases[outside], why[outside])
        keep = np.flatnonzero(~outside)
        if keep.size == 0:
            return None
        return steps.take(keep) if keep.size < steps.cases.size else steps

    def _complete(self, steps: AcceptedSteps) -> None:
        """Locate the steps' crossings, cut the steps, store events and states, end stages."""
        indicators = indicators_at(steps.batch, steps.stage, steps.y_new, steps.aux, self.layout)
        before = self.indicators[steps.cases]
        target = self.columns.target
        change = np.sign(before) * np.sign(indicators) < 0
        change[:, target] = (before[:, target] < 0) & (indicators[:, target] >= 0)
        crossings = locate_crossings(
            steps.batch, steps.stage, change, before, indicators, steps.y_start, steps.y_raw,
            steps.y_new, steps.h, steps.dop853_stages, self.layout, self.options,
        )
        self.located[steps.cases] += crossings.located
        self._not_a_limit_point(crossings, steps.h)
        is_cut, cut_column, reach = self._cut_points(steps, change, crossings.sigma)
        store_first_events(
            self.events, self.event_column, steps.cases, crossings, reach + self.options.event_tol,
            self.arclength, self.stage_index, steps.batch, steps.stage, self.layout,
        )
        cut_rows = np.flatnonzero(is_cut)
        steps.y_new = steps.y_new.copy()
        if cut_rows.size:
            self._move_to_cut_points(steps, crossings, cut_rows, cut_column, indicators)
        self._commit(steps, reach, indicators)
        self._end_stages(steps.cases, is_cut, cut_column, indicators)

    def _not_a_limit_point(self, crossings: Any, h: np.ndarray) -> None:
        """A zero of det K where the branch test also changes sign is a simple bifurcation
        point, not a limit point: its det K crossing is dropped (in ``crossings``).

        The two roots are located independently to event_tol; they count as one
        point within 1e-6 of the step (a limit point that close to a
        bifurcation is not generic).
        """
        column = self.columns.bifurcation
        if column is None:
            return
        branch = crossings.sigma[:, column]
        for limit in self.event_column["limit_point"]:
            with np.errstate(invalid="ignore"):
                same = np.isfinite(branch) & (np.abs(crossings.sigma[:, limit] - branch) <= 1e-6 * h)
            crossings.sigma[same, limit] = np.inf

    def _cut_points(
        self, steps: AcceptedSteps, change: np.ndarray, sigma: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Where each step is cut: at its first crossing that ends the stage or the case.

        The crossings that cut are those of the target and cycle columns, of
        stop events and of contact switches.  Returns the mask of the cut
        steps, the column that cuts each step and the step length kept (to the
        cut point, else the whole step).
        """
        stops = self.stop_table[self.stage_index[steps.cases]]
        cutting = change & (stops | self.break_columns[None, :])
        if self.columns.bifurcation is not None:  # a pending branch switch cuts the step there
            pending = (steps.stage.switch != 0) & ~steps.stage.switched
            cutting[:, self.columns.bifurcation] |= change[:, self.columns.bifurcation] & pending
        cutting[:, self.columns.target] = change[:, self.columns.target]
        cutting[:, self.columns.cycle] = change[:, self.columns.cycle]
        cut_sigma = np.where(cutting, sigma, np.inf)
        cut_column = np.argmin(cut_sigma, axis=1)
        rows = np.arange(steps.cases.size)
        is_cut = np.isfinite(cut_sigma[rows, cut_column])
        reach = np.where(is_cut, cut_sigma[rows, cut_column], steps.h)
        return is_cut, cut_column, reach

    def _move_to_cut_points(
        self,
        steps: AcceptedSteps,
        crossings: Any,
        cut_rows: np.ndarray,
        cut_column: np.ndarray,
        indicators: np.ndarray,
    ) -> None:
        """The steps ``cut_rows`` end at their located cut points instead (in ``steps``).

        Contacts switch and cycle turns close there; dy/ds, the auxiliary
        quantities and the ``indicators`` are updated to the cut states.
        """
        steps.y_new[cut_rows] = crossings.located_y(cut_rows, cut_column[cut_rows])
        closing = cut_rows[self.break_columns[cut_column[cut_rows]]]
        if closing.size:
            self._switch_contacts_at(steps, closing, cut_column)
        if self.columns.bifurcation is not None:
            leaving = cut_rows[(cut_column[cut_rows] == self.columns.bifurcation) & (steps.stage.switch[cut_rows] != 0)]
            if leaving.size:
                self._switch_branches_at(steps, leaving)
        self._close_turns(steps, cut_rows, cut_column)
        batch, stage = steps.batch.take(cut_rows), steps.stage.take(cut_rows)
        dy_cut, aux_cut = state_derivative(batch, stage, steps.y_new[cut_rows], self.layout)
        steps.dy_new[cut_rows] = dy_cut
        indicators_cut = indicators_at(batch, stage, steps.y_new[cut_rows], aux_cut, self.layout)
        # Keep the post-crossing sign of a break column (secondary contact)
        # so the same crossing is not detected twice.
        column_cut = cut_column[cut_rows]
        brk = np.flatnonzero(self.break_columns[column_cut])
        indicators_cut[brk, column_cut[brk]] = indicators[cut_rows[brk], column_cut[brk]]
        indicators[cut_rows] = indicators_cut
        # Writable copies (fields may be read-only views).
        steps.aux = steps.aux.take(np.arange(steps.cases.size))
        steps.aux.put(cut_rows, aux_cut)

    def _switch_contacts_at(self, steps: AcceptedSteps, closing: np.ndarray, cut_column: np.ndarray) -> None:
        """Switch the contact state of rows ``closing``, cut at a break column.

        The direction of motion is kept: the orientation flips where the
        switch flips the cofactor tangent.
        """
        bits = np.asarray(self.columns.switch_bits)[cut_column[closing]]
        switched = steps.stage.take(closing)
        steps.y_new[closing], flip = switch_contacts(
            steps.batch.take(closing), switched, steps.y_new[closing], bits, self.layout
        )
        steps.stage.secondary_state[closing] = switched.secondary_state
        self.stages.secondary_state[steps.cases[closing]] = switched.secondary_state
        steps.stage.orientation[closing[flip]] *= -1
        self.stages.orientation[steps.cases[closing[flip]]] *= -1
        # The motion continues from the switch: no reference across it.
        steps.stage.reference[closing] = np.nan

    def _switch_branches_at(self, steps: AcceptedSteps, rows: np.ndarray) -> None:
        """Rows ``rows`` are cut at a simple bifurcation point with a switch pending: they
        leave along the bifurcating branch (:func:`ncstab.paths.branch_switching.switch_branch`),
        the motion there becoming the reference the next tangents continue."""
        from ncstab.paths.branch_switching import switch_branch

        batch, stage = steps.batch.take(rows), steps.stage.take(rows)
        incoming = np.concatenate([steps.aux.dv[rows], steps.aux.dlam[rows, None]], axis=-1)
        sense = stage.switch.astype(float)
        moved, direction = switch_branch(batch, stage, steps.y_new[rows], incoming, sense, self.layout, self.options)
        steps.y_new[rows] = moved
        evaluation = evaluate_at(batch, stage, moved, self.layout)
        dv, dlam = direction[:, :-1], direction[:, -1]
        du = np.einsum("bij,bj->bi", evaluation.du_dv, dv)
        dF = np.einsum("bij,bj->bi", evaluation.dF_dv, dv)
        if evaluation.dF_dload is not None:
            dF = dF + evaluation.dF_dload * (stage.load_slope * dlam)[:, None]
        motion = np.concatenate([du, dF, dlam[:, None]], axis=-1)
        steps.stage.reference[rows] = motion
        steps.stage.switched[rows] = True
        self.stages.switched[steps.cases[rows]] = True
        self.branch_index[steps.cases[rows]] = stage.switch

    def _close_turns(self, steps: AcceptedSteps, cut_rows: np.ndarray, cut_column: np.ndarray) -> None:
        """Close a turn where a cycle stage's step is cut at its cycle (or target) column.

        Stores the work over the turn, the force gap and the drift of T, and
        counts the turn.
        """
        column_cut = cut_column[cut_rows]
        turns_here = self.turns.turns[self.stage_index[steps.cases[cut_rows]]]
        ends_turn = (
            ((column_cut == self.columns.cycle) | (column_cut == self.columns.target))
            & steps.stage.is_cycle[cut_rows]
            & (steps.stage.cycles_done[cut_rows] < turns_here)
        )
        rows = cut_rows[ends_turn]
        if rows.size == 0:
            return
        _, aux = state_derivative(steps.batch.take(rows), steps.stage.take(rows), steps.y_new[rows], self.layout)
        cases = steps.cases[rows]
        turn = steps.stage.cycles_done[rows]
        work = steps.y_new[rows, self.layout.work]
        self.turns.close(cases, self.stage_index[cases], turn, work, aux.evaluation)
        steps.stage.cycles_done[rows] += 1
        self.stages.cycles_done[cases] += 1

    def _commit(self, steps: AcceptedSteps, reach: np.ndarray, indicators: np.ndarray) -> None:
        """The cases move to ``steps.y_new`` (arclength + ``reach``) and store it."""
        cases = steps.cases
        self.y[cases] = steps.y_new
        self.derivative[cases] = steps.dy_new
        self.arclength[cases] += reach
        self.accepted[cases] += 1
        self.indicators[cases] = indicators
        self.stages.reference[cases] = steps.aux.tangent.motion()
        self.record(cases, steps.y_new, steps.aux, steps.stage)

    def _end_stages(
        self, cases: np.ndarray, is_cut: np.ndarray, cut_column: np.ndarray, indicators: np.ndarray
    ) -> None:
        """End the stage of ``cases`` at a stop event or its target; fail cases out of steps.

        A case that reached its target enters the next stage (and stores its
        state there again, see :func:`ncstab.paths.stage_entry.enter`).
        """
        target = self.columns.target
        stops = self.stop_table[self.stage_index[cases], cut_column]
        stop_hit = is_cut & (cut_column != target) & stops
        # A cut at (or a rounding error past) the target ends the stage too.
        at_target = (cut_column == target) | (indicators[:, target] >= 0)
        target_hit = is_cut & ~stop_hit & at_target
        self.stop(cases[stop_hit], cut_column[stop_hit])
        too_many = (self.accepted[cases] >= self.options.max_steps) & ~target_hit & ~stop_hit
        self.fail_max_steps(cases[too_many])
        self.enter_next_stage(cases[target_hit])

    def stop(self, cases: np.ndarray, columns: np.ndarray) -> None:
        """Cases ``cases`` stop at the stop event of indicator column ``columns`` (per case)."""
        for column in np.unique(columns):
            which = cases[columns == column]
            name = self.columns.events[column]
            number = self.stage_index[which[0]] + 1
            self.end(which, stopped(name), f"stopped at {name} in stage {number}")

    def fail_max_steps(self, cases: np.ndarray) -> None:
        """Cases ``cases`` fail: ``max_steps`` accepted steps before the end of the programme."""
        self.fail(
            cases,
            "max_steps",
            f"reached max_steps = {self.options.max_steps} accepted steps before the end of the "
            "programme",
        )

    def enter_next_stage(self, cases: np.ndarray) -> None:
        """Cases ``cases`` reached their stage target: they enter the next stage."""
        if cases.size:
            # Stage indices before any case enters its next stage (enter() updates them).
            finished_index = self.stage_index[cases].copy()
            for k in np.unique(finished_index):
                stage_entry.enter(self, cases[finished_index == k], int(k) + 1)



def _compiled_stepper(
    batch: Any, programme: LoadingProgramme, options: PathOptions
) -> tuple[CompiledStages | None, str]:
    """The compiled stage loop where ``options.backend`` asks for it and it applies,
    and the engine that runs the batch, in words (the archive's ``engine`` attribute).

    Raises RuntimeError (from :func:`ncstab.paths.compiled.stage_runner`) when
    the compiled backend is asked for and numba is missing.
    """
    if options.backend == "numpy":
        return None, NUMPY_ENGINE
    from ncstab.paths import compiled

    asked = options.backend == "compiled"
    if not compiled.NUMBA_AVAILABLE:
        if asked:
            compiled.stage_runner(batch)  # raises, naming what to install
        return None, f"{NUMPY_ENGINE} (numba is not installed)"
    reason = compiled.unsupported_reason(batch, programme)
    if reason is not None:
        because = "backend = 'compiled' asked" if asked else "the compiled stepper does not cover this"
        return None, f"{NUMPY_ENGINE} ({because}: {reason})"
    from ncstab.paths.compiled_stages import CompiledStages

    engine = f"compiled stepper (numba {compiled.numba.__version__}), numpy stepper for what it leaves"
    return CompiledStages(batch, compiled.stage_runner(batch)), engine


def follow_cases(
    batch: Any,
    programme: LoadingProgramme,
    values: dict[str, np.ndarray],
    options: PathOptions,
    secondary_contacts: str = "activate",
    progress: Callable[[int], None] | None = None,
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

    Returns
    -------
    CaseResult
    """
    return BatchStepper(batch, programme, values, options, secondary_contacts, progress).run()
