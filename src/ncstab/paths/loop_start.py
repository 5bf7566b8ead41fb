"""Template, part 3b of the compiled stage loop: a stage's start.

Pasted before :mod:`ncstab.paths.loop_cases` (see :mod:`ncstab.paths.loop_model`):
``start`` computes dy/ds and the indicators at each case's (set up) state,
stores it, and estimates the first step where it is still to be estimated
(called by :func:`ncstab.paths.stage_entry.enter`).  The parameters of
:func:`start_part` are the names it uses from the parts before it (it is never
called).
"""

from __future__ import annotations

import numba
import numpy as np

__all__ = ["start_part"]


def start_part(
    aux_size, ev_size, indicators, initial_step_size, motion_size, rhs, set_state, state_size, store_record,
) -> None:
    """Define ``start`` (a template: see the module docstring)."""

    @numba.njit(cache=False, error_model="numpy")
    def start(cases, y, derivative, indicator_table, arclength, force_controlled, control_rows, lam_end,
              target_sign, orientation, reference, secondary_state, cycles_done, law, parameters, geometry,
              stage_number, recorded, record_count, step_size, probe, rtol, atol):
        """Cases ``cases`` start their (set up) stage: dy/ds, indicators, state stored
        (stage_entry._start_stage); the first step where ``step_size`` is NaN
        (Hairer's estimate from a probe step, stage_entry.probe_step)."""
        if cases.size == 0:
            return
        first = geometry[cases[0]]
        M, n_motion = state_size(y[cases[0]]), motion_size(first)
        state = np.empty(M)
        ev = np.empty(ev_size(first))
        aux = np.empty(aux_size(first))
        f1 = np.empty(M)
        orient = np.empty(1 + n_motion)
        for i in cases:
            orient[0] = orientation[i]
            for k in range(n_motion):
                orient[1 + k] = reference[i, k]
            for j in range(M):
                state[j] = y[i, j]
            fc, ctl, geo = force_controlled[i], control_rows[i], geometry[i]
            turn_end = 2 * np.pi * (cycles_done[i] + 1) if ctl[0] > 0 else np.nan
            set_state(parameters[i], geo, secondary_state[i])
            rhs(state, fc, ctl, orient, law, parameters[i], geo, derivative[i], ev, aux)
            indicators(ev, aux, state, fc, ctl, geo, lam_end[i], target_sign[i], turn_end, secondary_state[i],
                       indicator_table[i])
            store_record(recorded, i, record_count[i], arclength[i], stage_number, state, ev, aux, geo)
            record_count[i] += 1
            if np.isnan(step_size[i]):
                for j in range(M):
                    state[j] = y[i, j] + probe * derivative[i, j]
                rhs(state, fc, ctl, orient, law, parameters[i], geo, f1, ev, aux)
                step_size[i] = initial_step_size(y[i], derivative[i], f1, probe, rtol, atol)

