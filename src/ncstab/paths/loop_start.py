"""The compiled stage loop's start of a stage, and states settled onto equilibrium.

``start`` computes dy/ds and the indicators at each case's (set up) state,
stores it, and estimates the first step where it is still to be estimated
(called by :func:`ncstab.paths.stage_entry.enter`); ``settle`` projects states
onto equilibrium and gives the rate of lambda along the unoriented tangent
there (stage entry orients a stage by it; branch switching projects the state
it leaves to).  Any model: :mod:`ncstab.paths.loop_dispatch`.
"""

from __future__ import annotations

import numpy as np

from ncstab.jit import entry, njit
from ncstab.paths.loop_dispatch import (
    aux_size, ev_size, indicators, motion_size, project, rhs, set_state, state_size, store_record,
)
from ncstab.paths.loop_numerics import initial_step_size

__all__ = ["scratch", "settle", "start"]


@njit
def scratch(kind, y, geometry, cases):
    # a state's size M, the motion's size, and scratch for a state, an evaluation, the
    # tangent's auxiliaries and the orientation, sized by the first case's row
    first = geometry[cases[0]]
    M, n_motion = state_size(kind, y[cases[0]]), motion_size(kind, first)
    return M, n_motion, np.empty(M), np.empty(ev_size(kind, first)), np.empty(aux_size(kind, first)), np.empty(1 + n_motion)


@entry
def start(cases, rows, stage, records, model, probe, settings):
    """Cases ``cases`` start their (set up) stage: dy/ds, indicators, state stored;
    the first step where ``step_size`` is NaN (Hairer's estimate from a probe step,
    stage_entry.probe_step).  The arguments are records (:mod:`ncstab.paths.loop_records`):
    the stepper's rows, the stage's, what is stored, the model's rows and the options."""
    if cases.size == 0:
        return
    y, derivative, indicator_table, arclength, step_size = (
        rows.y, rows.derivative, rows.indicators, rows.arclength, rows.step_size
    )
    force_controlled, control_rows, lam_end, target_sign = (
        stage.force_controlled, stage.control, stage.lam_end, stage.target_sign
    )
    orientation, reference, secondary_state, cycles_done = (
        stage.orientation, stage.reference, stage.secondary_state, stage.cycles_done
    )
    kind, law, parameters, geometry = model
    recorded, record_count, stage_number = records
    M, n_motion, state, ev, aux, orient = scratch(kind, y, geometry, cases)
    f1 = np.empty(M)
    for i in cases:
        orient[0] = orientation[i]
        for k in range(n_motion):
            orient[1 + k] = reference[i, k]
        for j in range(M):
            state[j] = y[i, j]
        fc, ctl, geo = force_controlled[i], control_rows[i], geometry[i]
        turn_end = 2 * np.pi * (cycles_done[i] + 1) if ctl[0] > 0 else np.nan
        set_state(kind, parameters[i], geo, secondary_state[i])
        rhs(kind, state, fc, ctl, orient, law, parameters[i], geo, derivative[i], ev, aux)
        indicators(kind, ev, aux, state, fc, ctl, geo, lam_end[i], target_sign[i], turn_end, secondary_state[i],
                   indicator_table[i])
        store_record(kind, recorded, i, record_count[i], arclength[i], stage_number, state, ev, aux, geo)
        record_count[i] += 1
        if np.isnan(step_size[i]):
            for j in range(M):
                state[j] = y[i, j] + probe * derivative[i, j]
            rhs(kind, state, fc, ctl, orient, law, parameters[i], geo, f1, ev, aux)
            step_size[i] = initial_step_size(y[i], derivative[i], f1, probe, settings.rtol, settings.atol, state_size(kind, y[i]))


@entry
def settle(cases, y, force_controlled, control_rows, secondary_state, model, projected, newton_tol, newton_max_iter,
           rates):
    """Cases ``cases`` (row k of the stage arrays is case ``cases[k]``; ``parameters``,
    ``geometry`` and ``y`` are the batch's): where ``projected``, their states are
    first projected onto equilibrium under the stage's control (the loop's Newton
    projection, in place in ``y``; where it does not converge, the loop's next step
    fails or brings the state back); then
    ``rates[k]`` is dlambda/ds of the path tangent there, not oriented (the cofactor
    vector's own sign: stage entry orients the stage by it, and a control that is
    singular there gives 0 or NaN)."""
    if cases.size == 0:
        return
    kind, law, parameters, geometry = model
    _, n_motion, dy, ev, aux, orient = scratch(kind, y, geometry, cases)
    orient[:] = np.nan  # orientation 1, no reference
    orient[0] = 1.0
    lam = (n_motion - 1) // 2  # y = (v, lambda, ...), v of n = (n_motion - 1) / 2 coordinates
    for k in range(cases.size):
        i = cases[k]
        fc, ctl, geo = force_controlled[k], control_rows[k], geometry[i]
        set_state(kind, parameters[i], geo, secondary_state[k])
        if projected:
            project(kind, y[i], fc, ctl, law, parameters[i], geo, newton_tol, newton_max_iter, ev)
        rhs(kind, y[i], fc, ctl, orient, law, parameters[i], geo, dy, ev, aux)
        rates[k] = dy[lam]
