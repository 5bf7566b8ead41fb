"""Contact switching: where a gap or a normal contact crosses zero, the contact state flips.

Within a step every contact state is frozen, so the engine integrates a
smooth field; where a located crossing of a gap (a secondary contact with
``secondary_contacts = "activate"``) or of a no_tension law's normal overlap
cuts a step, the state's bit flips there and the next step integrates the
other smooth branch.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from ncstab.paths.rhs import Auxiliary, StateLayout, state_derivative
from ncstab.paths.tangent_field import StageArrays

__all__ = ["switch_contacts"]


def switch_contacts(
    batch: Any, stage: StageArrays, y: np.ndarray, bits: np.ndarray, layout: StateLayout
) -> tuple[np.ndarray, np.ndarray]:
    """Switch the contact-state ``bits`` (per case) where a gap crossed zero (in ``stage``, in place).

    The batch switches its springs (or, in the pure-shear limit, its state
    coordinates).  The switch may flip the cofactor tangent, so the direction of
    motion in (u, F, lambda) is kept: returns the new states and a mask of the
    cases whose orientation must flip.  The tangents compared are oriented by
    the stage only, not by continuity (``stage.reference`` is set aside).
    """
    y = y.copy()
    reference = stage.reference
    stage.reference = np.full(reference.shape, np.nan)
    _, before = state_derivative(batch, stage, y, layout)
    batch.close_contact(y, stage.secondary_state, bits, layout)
    _, after = state_derivative(batch, stage, y, layout)
    stage.reference = reference

    def motion(ax: Auxiliary) -> np.ndarray:
        df = (ax.evaluation.dF_dv @ ax.dv[:, :, None])[:, :, 0]
        return np.concatenate([ax.du, df, ax.dlam[:, None]], axis=-1)

    return y, np.sum(motion(after) * motion(before), axis=-1) < 0
