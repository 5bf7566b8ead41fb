"""The compiled stage loop: each case through its stage.

``run_cases`` takes each case from its state to the end of its stage (target,
stop event, failure, a full recorder, or a bifurcation point where the stage
switches branch), one case after the other, for any model: what depends on the
model is asked of it through :mod:`ncstab.paths.loop_dispatch`; a step, its
dense output and events are :mod:`ncstab.paths.loop_steps`', the domain's edge
and over steps :mod:`ncstab.paths.loop_step_limits`'; a stage starts in
:mod:`ncstab.paths.loop_start`.
"""

from __future__ import annotations

import numpy as np

from ncstab.jit import entry
from ncstab.paths.compiled import _EXTENDED, _POWER, _STAGES, Outcome
from ncstab.paths.contacts import ENTRY_NOISE, ENTRY_PROBE
from ncstab.paths.loop_dispatch import (
    aux_size, branch_size, cuts_always, domain_detail, ev_size, event_columns, indicators, motion, motion_product,
    motion_size, next_state, project, rhs, set_reference, set_state, state_size, store_event, store_record,
    switch_bit, tries_degenerate, turn_record,
)
from ncstab.paths.loop_numerics import (
    dense_value, first_column, next_degenerate_length, next_over_length, piece_count, sign,
)
from ncstab.paths.loop_records import Case, Evaluation, Goal, Interpolant, StateAt
from ncstab.paths.loop_step_limits import admissible_at, last_admissible, over_step
from ncstab.paths.loop_steps import dense_coefficients, dop853, drop_limit_at_bifurcation, locate

__all__ = ["run_cases"]

# How a case's call ends (compiled.Outcome), as constants the loop compiles
PAUSED, TARGET, STOPPED, BRANCH_SWITCH = Outcome.PAUSED, Outcome.TARGET, Outcome.STOPPED, Outcome.BRANCH_SWITCH
STEP_SIZE_UNDERFLOW, LEFT_DOMAIN, MAX_STEPS = Outcome.STEP_SIZE_UNDERFLOW, Outcome.LEFT_DOMAIN, Outcome.MAX_STEPS
SINGULAR_BRANCH = Outcome.SINGULAR_BRANCH


@entry
def run_cases(cases, rows, stage, turns, events, records, outcomes, model, settings):
    """Run cases ``cases`` through their current stage (linear or cycle), one after the
    other; see :class:`Outcome`.  The arguments are records
    (:mod:`ncstab.paths.loop_records`): the stepper's rows, the stage's (its control
    path per case: see ``control``), its turns, its event tables, what is stored, each
    case's outcome, the model's rows and the options.  A turn of a cycle stage that
    closes sets ``turns.closed[i, turns.first + turn]`` and stores (W, F1, F2, T) there
    in ``turns.values`` for the stepper's tables
    (:class:`~ncstab.paths.cycle_turns.CycleTurns`).  A case with
    ``stage.switch_pending`` (its stage switches branch at a simple bifurcation point,
    not done yet) cuts its step where the bifurcation column changes sign and returns
    there, unstored, for the stepper to leave along the bifurcating branch
    (:mod:`ncstab.paths.branch_switching`).

    Per step: a DOP853 step (projected), the step-size control, the domain
    check, the step in pieces of ``sample_step``, crossings located, the cut,
    the first events, the commit and the end of the stage.  A case reads and
    writes its own rows only, so cases may run on any thread in any order
    (the loop releases the GIL: :mod:`ncstab.paths.compiled_stages` runs
    shares of the cases on Python threads side by side).
    """
    if cases.size == 0:
        return
    y, derivative, indicator_table, step_size, arclength, accepted, rejected, located = rows[:8]
    branch_sizes, over_length, over_degenerate, degenerate_length = rows[8:]
    force_controlled, control_rows, lam_end, target_sign, orientation, reference = stage[:6]
    secondary_state, cycles_done, switch_pending = stage[6:]
    turns_count, first_turn, turn_closed, turn_values = turns
    stop_row, break_row, columns_of_event, event_found, event_values, event_stage = events
    recorded, record_count, stage_number = records
    code, detail = outcomes
    kind, law, parameters, geometry = model
    min_step, max_step, max_steps = settings.min_step, settings.max_step, settings.max_steps
    sample_step, max_pieces = settings.sample_step, settings.max_pieces
    capacity = recorded[0].shape[1]
    first = geometry[cases[0]]  # (the sizes are those of every case)
    M = state_size(kind, y[cases[0]])
    columns, n_motion = event_columns(kind, first), motion_size(kind, first)
    n_columns, target_column, cycle_column = columns.count, columns.target, columns.cycle
    bifurcation_column, control_column = columns.bifurcation, columns.control
    stages = np.empty((_EXTENDED, M))
    y0 = np.empty(M)
    y_raw = np.empty(M)
    y_new = np.empty(M)
    dy_new = np.empty(M)
    work = np.empty((3, M))
    coefficients = np.empty((_POWER, M))
    located_states = np.empty((n_columns, M))
    ev = np.empty(ev_size(kind, first))
    aux = np.empty(aux_size(kind, first))
    ev_new = np.empty(ev.size)
    aux_new = np.empty(aux.size)
    orient = np.empty(1 + n_motion)  # the orientation, then the reference (the motion at the step's start)
    plain = np.full(1 + n_motion, np.nan)  # the orientation alone (a contact switch sets the reference aside)
    values = np.empty(n_columns)
    after = np.empty(n_columns)
    before = np.empty(n_columns)
    sigma = np.empty(n_columns)
    lower = np.empty(n_columns)
    upper = np.empty(n_columns)
    change = np.zeros(n_columns, dtype=np.bool_)
    motion_before = np.empty(n_motion)
    samples = np.empty((max(max_pieces - 1, 1), M))  # the pieces' ends inside a step
    y_end = np.empty(M)
    dy_end = np.empty(M)
    ev_end = np.empty(ev.size)
    aux_end = np.empty(aux.size)
    y_half = np.empty(M)
    step_end = StateAt(y_new, dy_new, ev_new, aux_new)
    for i in cases:
        fc = force_controlled[i]
        ctl = control_rows[i]
        done = cycles_done[i]
        turn_end = 2 * np.pi * (done + 1) if ctl[0] > 0 else np.nan  # events: the cycle column
        p = parameters[i]
        sec = secondary_state[i]
        geo = geometry[i]
        set_state(kind, p, geo, sec)
        case = Case(kind, fc, ctl, orient, law, p, geo)
        orient[0] = orientation[i]
        for k in range(n_motion):
            orient[1 + k] = reference[i, k]
        code[i] = PAUSED
        while record_count[i] + piece_count(max(min(step_size[i], max_step), over_length[i]), sample_step,
                                            max_pieces) <= capacity:
            h = min(step_size[i], max_step)
            for j in range(M):
                y0[j] = y[i, j]
            over = False
            if not kind.rate_form and over_length[i] > 0:  # an over step (over_steps)
                arc = over_step(over_length[i], y0, derivative[i], case, settings, y_raw, step_end, y_half, ev,
                                coefficients, over_degenerate[i], degenerate_length[i] > 0)
                over_length[i] = 0.0
                over_degenerate[i] = False
                if arc < 0:  # aligned, not reversed: a degenerate over step next
                    over_length[i] = degenerate_length[i]
                    over_degenerate[i] = True
                    degenerate_length[i] = 0.0
                    continue
                degenerate_length[i] = 0.0
                over = arc > 0
                if over:
                    h = arc
            if not over:
                err = dop853(y0, derivative[i], h, case, settings, stages, y_raw, work, ev_new, aux_new)
                for j in range(M):
                    y_new[j] = y_raw[j]
                if not kind.rate_form and np.isfinite(err) and not project(kind, 
                    y_new, fc, ctl, law, p, geo, settings.newton_tol, settings.newton_max_iter, ev_new
                ):
                    err = np.inf
                accept = err <= 1.0
                if err == 0:
                    factor = 10.0
                elif np.isfinite(err):
                    factor = min(max(0.9 / np.sqrt(np.sqrt(np.sqrt(err))), 0.2), 10.0)  # scipy's DOP853 step factor: 0.9 err^(-1/8) in [0.2, 10]
                else:
                    factor = 0.25
                if not accept:
                    factor = min(factor, 0.9)
                step_size[i] = min(max(h * factor, 0.0), max_step)
                if not accept:
                    rejected[i] += 1
                    if step_size[i] < min_step:
                        code[i] = STEP_SIZE_UNDERFLOW
                        break
                    continue
                if kind.rate_form:  # the last DOP853 stage was evaluated at the end state
                    for j in range(M):
                        dy_new[j] = stages[_STAGES, j]
                else:
                    rhs(kind, y_new, fc, ctl, orient, law, p, geo, dy_new, ev_new, aux_new)
            # --- the step's pieces (options.sample_step): the ends of all but the
            # last on the step's interpolant, projected for a total form
            pieces = piece_count(h, sample_step, max_pieces)
            have_dense = over  # (an over step has its interpolant already)
            if pieces > 1:
                if not have_dense:
                    dense_coefficients(y0, y_raw, h, case, stages, coefficients, work, ev, aux)
                have_dense = True
                projected = True
                for k in range(pieces - 1):
                    dense_value(y0, coefficients, (k + 1) / pieces, samples[k])
                    if not kind.rate_form and not project(kind, 
                        samples[k], fc, ctl, law, p, geo, settings.newton_tol, settings.newton_max_iter, ev
                    ):
                        projected = False
                        break
                if not projected:  # a piece's end off equilibrium: the step is retried shorter
                    step_size[i] = 0.5 * h
                    rejected[i] += 1
                    if step_size[i] < min_step:
                        code[i] = STEP_SIZE_UNDERFLOW
                        break
                    continue
            offset = 0.0
            ended = False
            for piece in range(1, pieces + 1):
                if piece < pieces:
                    end_at = h * piece / pieces
                    for j in range(M):
                        y_end[j] = samples[piece - 1, j]
                    rhs(kind, y_end, fc, ctl, orient, law, p, geo, dy_end, ev_end, aux_end)
                else:  # the step's end, once the pieces before it are done
                    end_at = h
                    for j in range(M):
                        y_end[j] = y_new[j]
                        dy_end[j] = dy_new[j]
                    for j in range(ev_new.size):
                        ev_end[j] = ev_new[j]
                    for j in range(aux_new.size):
                        aux_end[j] = aux_new[j]
                reason = domain_detail(kind, y_end, ev_end, geo)  # --- the domain's edge (domain_edge): bisection
                if reason >= 0:
                    if not have_dense:
                        dense_coefficients(y0, y_raw, h, case, stages, coefficients, work, ev, aux)
                        have_dense = True
                    lo = last_admissible(offset, end_at, Interpolant(y0, coefficients, h), case, settings,
                                         work, ev, aux)
                    if not (lo > offset):  # nothing admissible beyond the piece's start
                        code[i], detail[i], ended = LEFT_DOMAIN, reason, True
                        break
                    admissible_at(lo, Interpolant(y0, coefficients, h), case, settings, y_end, dy_end, ev_end,
                                  aux_end)
                    end_at = lo
                span = end_at - offset
                # --- the piece's end: indicators, crossings located, cut, events, commit
                indicators(kind, ev_end, aux_end, y_end, fc, ctl, geo, lam_end[i], target_sign[i], turn_end, sec, after)
                any_change = False
                for c in range(n_columns):
                    before[c] = indicator_table[i, c]
                    change[c] = sign(before[c]) * sign(after[c]) < 0
                change[target_column] = before[target_column] < 0 and after[target_column] >= 0
                for c in range(n_columns):
                    sigma[c] = np.inf
                    lower[c] = np.nan
                    upper[c] = np.nan
                    any_change = any_change or change[c]
                exact_target = change[target_column] and after[target_column] == 0
                if any_change:
                    searched = False
                    for c in range(n_columns):
                        searched = searched or (change[c] and not (c == target_column and exact_target))
                    if searched and not have_dense:
                        dense_coefficients(y0, y_raw, h, case, stages, coefficients, work, ev, aux)
                        have_dense = True
                    for c in range(n_columns):
                        if not change[c] or (c == target_column and exact_target):
                            continue
                        sigma[c], lower[c], upper[c] = locate(
                            c, offset, span, before[c], after[c], Interpolant(y0, coefficients, h), case,
                            Goal(lam_end[i], target_sign[i], turn_end, sec), settings, Evaluation(ev, aux),
                            values, located_states[c],
                        )
                        located[i] += 1
                    drop_limit_at_bifurcation(kind, sigma, span, geo)
                    if exact_target:
                        sigma[target_column] = lower[target_column] = upper[target_column] = span
                        for j in range(M):
                            located_states[target_column, j] = y_end[j]
                # where the piece is cut: the target, the end of a turn, stop events, contact switches
                cut_column = 0
                cut_sigma = np.inf
                for c in range(n_columns):
                    cutting = change[c] and (stop_row[c] or cuts_always(kind, geo, c) or break_row[c]
                                             or (switch_pending[i] and c == bifurcation_column))
                    if cutting and sigma[c] < cut_sigma:
                        cut_sigma = sigma[c]
                        cut_column = c
                is_cut = np.isfinite(cut_sigma)
                reach = cut_sigma if is_cut else span
                switched = False
                for e in range(columns_of_event.shape[0]):  # _store_first_events
                    c = first_column(columns_of_event[e], sigma)
                    if c >= 0 and np.isfinite(sigma[c]) and sigma[c] <= reach + settings.event_tol and not event_found[e, i]:
                        rhs(kind, located_states[c], fc, ctl, orient, law, p, geo, work[2], ev, aux)
                        event_found[e, i], event_stage[e, i] = True, stage_number
                        store_event(kind, event_values[e, i], arclength[i], sigma[c], lower[c], upper[c], located_states[c],
                                    ev, geo)
                if is_cut:  # move to the cut point
                    for j in range(M):
                        y_end[j] = located_states[cut_column, j]
                    switching = break_row[cut_column]
                    switched = switching
                    kept = 0.0
                    if switching:  # a contact switch (contacts)
                        plain[0] = orient[0]
                        rhs(kind, y_end, fc, ctl, plain, law, p, geo, work[2], ev, aux)
                        motion(kind, ev, aux, motion_before)
                        sec = next_state(kind, geo, sec, switch_bit(kind, geo, cut_column), y_end)
                        set_state(kind, p, geo, sec)
                        secondary_state[i] = sec
                        rhs(kind, y_end, fc, ctl, plain, law, p, geo, work[2], ev, aux)
                        flip = motion_product(kind, motion_before, ev, aux) < 0  # the motion kept
                        # the new branch into its own side: the crossed indicator's central
                        # difference along the new tangent, where it tells
                        rate = 0.0
                        for side in (1.0, -1.0):
                            for j in range(M):
                                work[0, j] = y_end[j] + side * ENTRY_PROBE * work[2, j]
                            rhs(kind, work[0], fc, ctl, plain, law, p, geo, work[1], ev, aux)
                            indicators(kind, ev, aux, work[0], fc, ctl, geo, lam_end[i], target_sign[i], turn_end, sec,
                                       values)
                            rate += side * values[cut_column]
                        if abs(rate) > ENTRY_NOISE:
                            own_side = -1.0 if (sec & switch_bit(kind, geo, cut_column)) > 0 else 1.0
                            flip = rate * own_side < 0
                        if flip:
                            orient[0] = -orient[0]
                            orientation[i] = orient[0]
                        for k in range(n_motion):  # the motion continues from the switch: no reference across it
                            orient[1 + k] = np.nan
                        kept = after[cut_column]
                    rhs(kind, y_end, fc, ctl, orient, law, p, geo, dy_end, ev_end, aux_end)
                    closes_turn = cut_column == cycle_column or cut_column == target_column
                    if ctl[0] > 0 and closes_turn and done < turns_count:  # a turn closes: W, F, T there
                        slot = first_turn + done
                        turn_closed[i, slot] = True
                        turn_record(kind, y_end, ev_end, turn_values[i, slot], geo)
                        done += 1
                        cycles_done[i] = done
                        turn_end = 2 * np.pi * (done + 1)
                    indicators(kind, ev_end, aux_end, y_end, fc, ctl, geo, lam_end[i], target_sign[i], turn_end, sec,
                               after)
                    for c in range(n_columns):  # a crossing at the cut point itself
                        if c != cut_column and break_row[c] and sign(after[c]) * sign(before[c]) < 0:
                            after[c] = before[c]  # is seen in the next piece, and switched there
                    if switching:  # the post-crossing sign, so the crossing is not found twice
                        after[cut_column] = kept
                # commit (a case leaving for a bifurcating branch keeps dy/ds of the step's end:
                # at the point itself the tangent is undetermined; branch_switching)
                stop_hit = is_cut and cut_column != target_column and stop_row[cut_column]
                leaving = is_cut and not stop_hit and switch_pending[i] and cut_column == bifurcation_column
                for j in range(M):
                    y[i, j] = y_end[j]
                    derivative[i, j] = dy_new[j] if leaving else dy_end[j]
                arclength[i] += reach
                if piece == 1:
                    accepted[i] += 1
                size = branch_size(kind, aux_end, orient)  # the next over step
                if not kind.rate_form:  # plan it (over_steps)
                    over_length[i] = next_over_length(branch_sizes[i], size, reach, settings.newton_tol)
                    if tries_degenerate(kind, geo):
                        degenerate = next_degenerate_length(branch_sizes[i], size, reach)
                        degenerate_length[i] = degenerate if over_length[i] > 0 else 0.0
                branch_sizes[i] = size
                set_reference(kind, aux_end, orient)  # the motion at the next piece's start
                for k in range(n_motion):
                    reference[i, k] = orient[1 + k]
                for c in range(n_columns):  # a value without a sign keeps the last (events)
                    if after[c] != 0 or c == target_column:
                        indicator_table[i, c] = after[c]
                if leaving:  # the stepper leaves along the bifurcating branch, and stores that state
                    code[i] = BRANCH_SWITCH
                    ended = True
                    break
                store_record(kind, recorded, i, record_count[i], arclength[i], stage_number, y_end, ev_end, aux_end, geo)
                record_count[i] += 1
                # the end of the stage: its target, a stop event, max_steps, a singular branch
                at_target = cut_column == target_column or after[target_column] >= 0
                target_hit = is_cut and not stop_hit and at_target
                if stop_hit:
                    code[i] = STOPPED
                    detail[i] = cut_column
                    ended = True
                    break
                if (is_cut or piece == pieces) and accepted[i] >= max_steps and not target_hit:
                    code[i] = MAX_STEPS
                    ended = True
                    break
                if switched and after[control_column] == 0:  # onto a singular branch: failed
                    code[i] = SINGULAR_BRANCH
                    ended = True
                    break
                if target_hit:
                    code[i] = TARGET
                    ended = True
                    break
                if is_cut:  # the rest of the step is dropped: the next one starts here
                    break
                if reason >= 0:  # completed to the domain's edge, nothing cut it before: it fails there
                    code[i], detail[i], ended = LEFT_DOMAIN, reason, True
                    break
                offset = end_at
            if ended:
                break

