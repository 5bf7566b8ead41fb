"""Contact switching: where a gap or a normal contact crosses zero, the contact state flips.

Within a step every contact state is frozen, so the engine integrates a
smooth field; where a located crossing of a gap (a secondary contact with
``secondary_contacts = "activate"``) or of a no_tension law's normal overlap
cuts a step, the state's bit flips there and the next step integrates the
other smooth branch.

The branch is followed from the switch into its own side: the side of the
crossed indicator where the new state holds (a closed contact, its bit set:
the gap or overlap below zero; an open one: above).  Where the motion kept
through the switch would lead straight back across -- both branches' paths
run into the switching surface, a corner of the equilibrium path (McNamara,
gamma = 0.79, F2* = 0.58 held, D1* driven: F1* peaks where the left-right
pair opens) -- the orientation follows the branch's side instead (the contacts chattered at that corner before, a step of about
event_tol each, until ``max_steps``).  The side is the sign of the
indicator's central difference along the new tangent, +-:data:`ENTRY_PROBE`
in arclength; where it is below :data:`ENTRY_NOISE` (the path grazes the
surface, or the rigid limit's frozen gap), the motion decides alone.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.paths.rhs import Auxiliary, StateLayout, state_derivative
from ncstab.paths.tangent_field import StageArrays

__all__ = ["ENTRY_NOISE", "ENTRY_PROBE", "switch_contacts"]

#: Arclength either side of a switch at which the crossed indicator is read to
#: see which side the new branch's tangent enters.
ENTRY_PROBE = 1e-6
#: Differences of the crossed indicator over the probe below which its side is
#: not told (rounding of a gap is ~1e-16; a rate of 1e-7 gives 2e-13).
ENTRY_NOISE = 1e-13


def switch_contacts(
    batch: Any, stage: StageArrays, y: np.ndarray, bits: np.ndarray, columns: np.ndarray, layout: StateLayout
) -> tuple[np.ndarray, np.ndarray]:
    """Switch the contact-state ``bits`` (per case) where the indicator ``columns`` crossed
    zero (in ``stage``, in place).

    The batch switches its springs (or, in the pure-shear limit, its state
    coordinates).  The switch may flip the cofactor tangent: the new branch is
    followed into its own side, or where that side is not told, in the
    direction of motion in (u, F, lambda) kept (see the module docstring).
    Returns the new states and a mask of the cases whose orientation must
    flip.  The tangents are oriented by the stage only, not by continuity
    (``stage.reference`` is set aside).
    """
    from ncstab.paths.accepted_steps import indicators_at

    y = y.copy()
    reference = stage.reference
    stage.reference = np.full(reference.shape, np.nan)
    _, before = state_derivative(batch, stage, y, layout)
    batch.close_contact(y, stage.secondary_state, bits, layout)
    dy, after = state_derivative(batch, stage, y, layout)
    rows = np.arange(y.shape[0])
    read = []
    for side in (1.0, -1.0):
        probe = y + side * ENTRY_PROBE * dy
        _, at_probe = state_derivative(batch, stage, probe, layout)
        read.append(indicators_at(batch, stage, probe, at_probe, layout)[rows, columns])
    stage.reference = reference

    def motion(ax: Auxiliary) -> np.ndarray:
        df = (ax.evaluation.dF_dv @ ax.dv[:, :, None])[:, :, 0]
        return np.concatenate([ax.du, df, ax.dlam[:, None]], axis=-1)

    kept = np.sum(motion(after) * motion(before), axis=-1) < 0
    rate = read[0] - read[1]
    own_side = np.where((stage.secondary_state & bits) > 0, -1.0, 1.0)
    told = np.abs(rate) > ENTRY_NOISE
    return y, np.where(told, rate * own_side < 0, kept)
