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

from typing import Any, Callable

import numpy as np

from ncstab.paths import stage_entry
from ncstab.paths.accepted_steps import AcceptedSteps, indicators_at
from ncstab.paths.case_ends import CaseEnds
from ncstab.paths.case_result import CaseResult, as_strings, empty_events
from ncstab.paths.crossings import event_tables, locate_crossings, store_first_events
from ncstab.paths.cut_points import cut_points, drop_limit_points_at_bifurcations, move_to_cut_points
from ncstab.paths.cycle_turns import CycleTurns
from ncstab.paths.engine_choice import choose_engine
from ncstab.paths.integrator import END_STAGE, step_factor
from ncstab.paths.over_steps import plan_over_steps, reset_over_steps, take_over_steps
from ncstab.paths.events import signs_kept
from ncstab.paths.options import AUTO, PathOptions
from ncstab.paths.programme import LoadingProgramme
from ncstab.paths.projection import advance
from ncstab.paths.recorder import Recorder, state_limit
from ncstab.paths.rhs import Auxiliary, StateLayout, state_derivative
from ncstab.paths.status import RUNNING
from ncstab.paths.step_pieces import complete_in_pieces
from ncstab.paths.tangent_field import StageArrays
from ncstab.sizes import available_memory

__all__ = ["BatchStepper", "follow_cases"]


class BatchStepper(CaseEnds):
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
        self.compiled, self.engine = choose_engine(batch, programme, options)

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

    # --- storing states --------------------------------------------------------------------------

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

    # --- one pass of the loop --------------------------------------------------------------------

    def step(self) -> bool:
        """Advance every running case by one step; False when none is running."""
        active = np.flatnonzero(self.status == RUNNING)
        if active.size == 0:
            return False
        # a case whose next step could store more states than the recorder's limit fails first
        pieces = self.options.pieces(self.next_step_lengths(active))
        fits = self.recorder.fits(active, pieces)
        if not fits.all():
            self.fail_memory(active[~fits])
            active = active[fits]
            if active.size == 0:
                return True
        over = active[self.over_length[active] > 0]
        if over.size:  # over steps across simple bifurcation points (the others: a regular step)
            crossed, again = take_over_steps(self, over)
            done = again if crossed is None else np.concatenate([crossed.cases, again])
            if crossed is not None:
                complete_in_pieces(self, crossed)
            active = active[~np.isin(active, done)]  # (again: a degenerate over step next pass)
            if active.size == 0:
                return True
        steps = self._take_steps(active)
        if steps is not None:
            complete_in_pieces(self, steps)  # (which fails the cases that left the domain)
        return True

    def next_step_lengths(self, cases: np.ndarray) -> np.ndarray:
        """The longest step each case may take next: its step size (at most ``max_step``),
        or its over step where longer (:mod:`ncstab.paths.over_steps`)."""
        return np.maximum(np.minimum(self.step_size[cases], self.options.max_step), self.over_length[cases])

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

    def _complete(
        self, steps: AcceptedSteps, counts_step: bool = True, ends_step: np.ndarray | bool = True
    ) -> np.ndarray:
        """Locate the steps' crossings, cut the steps, store events and states, end stages.

        Where ``steps`` are pieces of longer steps (:mod:`ncstab.paths.step_pieces`),
        ``counts_step`` says whether they are the first pieces (an accepted step
        counted) and ``ends_step`` which are the last (where ``max_steps`` applies,
        as at a cut).  Returns the mask of the steps cut short.
        """
        indicators = indicators_at(steps.batch, steps.stage, steps.y_new, steps.aux, self.layout)
        before = self.indicators[steps.cases]
        target = self.columns.target
        change = np.sign(before) * np.sign(indicators) < 0
        change[:, target] = (before[:, target] < 0) & (indicators[:, target] >= 0)
        crossings = locate_crossings(
            steps.batch, steps.stage, change, before, indicators, steps.y_start, steps.y_raw,
            steps.y_new, steps.h, steps.dop853_stages, self.layout, self.options, steps.piece,
        )
        self.located[steps.cases] += crossings.located
        drop_limit_points_at_bifurcations(self, crossings, steps.h)
        is_cut, cut_column, reach = cut_points(self, steps, change, crossings.sigma)
        store_first_events(
            self.events, self.event_column, steps.cases, crossings, reach + self.options.event_tol,
            self.arclength, self.stage_index, steps.batch, steps.stage, self.layout,
        )
        cut_rows = np.flatnonzero(is_cut)
        steps.y_new = steps.y_new.copy()
        if cut_rows.size:
            move_to_cut_points(self, steps, crossings, cut_rows, cut_column, indicators)
        self._commit(steps, reach, indicators, counts_step)
        self._end_stages(steps.cases, is_cut, cut_column, indicators, is_cut | ends_step)
        return is_cut

    def _commit(self, steps: AcceptedSteps, reach: np.ndarray, indicators: np.ndarray, counts_step: bool) -> None:
        """The cases move to ``steps.y_new`` (arclength + ``reach``) and store it."""
        cases = steps.cases
        self.y[cases] = steps.y_new
        self.derivative[cases] = steps.dy_new
        self.arclength[cases] += reach
        if counts_step:
            self.accepted[cases] += 1
        self.indicators[cases] = signs_kept(self.indicators[cases], indicators, self.columns.target)
        self.stages.reference[cases] = steps.aux.tangent.motion()
        branch = steps.aux.tangent.branch
        plan_over_steps(self, cases, np.full(cases.size, np.nan) if branch is None else np.abs(branch), reach)
        self.record(cases, steps.y_new, steps.aux, steps.stage)

    def _end_stages(
        self, cases: np.ndarray, is_cut: np.ndarray, cut_column: np.ndarray, indicators: np.ndarray,
        ends_step: np.ndarray | bool = True,
    ) -> None:
        """End the stage of ``cases`` at a stop event or its target; fail cases out of steps
        (where their step ends, ``ends_step``).

        A case cut at a contact switch onto a branch whose control is singular
        fails there (its state stored), before its target is looked at.  A case
        that reached its target enters the next stage (and stores its state
        there again, see :func:`ncstab.paths.stage_entry.enter`).
        """
        target = self.columns.target
        stops = self.stop_table[self.stage_index[cases], cut_column]
        stop_hit = is_cut & (cut_column != target) & stops
        # A cut at (or a rounding error past) the target ends the stage too.
        at_target = (cut_column == target) | (indicators[:, target] >= 0)
        target_hit = is_cut & ~stop_hit & at_target
        self.stop(cases[stop_hit], cut_column[stop_hit])
        too_many = (self.accepted[cases] >= self.options.max_steps) & ~target_hit & ~stop_hit & ends_step
        self.fail_max_steps(cases[too_many])
        control = self.columns.events.index("controllability_loss")
        singular = is_cut & self.break_columns[cut_column] & (indicators[:, control] == 0) & ~stop_hit & ~too_many
        self.fail_singular_branch(cases[singular])
        self.enter_next_stage(cases[target_hit & ~singular])

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
