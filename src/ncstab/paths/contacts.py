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

The compiled loop implements it (the contact switch in :mod:`ncstab.paths.loop_cases`,
the state's next contact bits in the model parts' ``next_state``); this module
holds its constants.
"""

from __future__ import annotations

__all__ = ["ENTRY_NOISE", "ENTRY_PROBE"]

#: Arclength either side of a switch at which the crossed indicator is read to
#: see which side the new branch's tangent enters.
ENTRY_PROBE = 1e-6
#: Differences of the crossed indicator over the probe below which its side is
#: not told (rounding of a gap is ~1e-16; a rate of 1e-7 gives 2e-13).
ENTRY_NOISE = 1e-13
