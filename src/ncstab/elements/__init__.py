"""Interaction elements: the kinematics of one kind of member, for arrays of members.

A system assembled from elements (:mod:`ncstab.systems.assembled`) is data:
per element kind, the members' dof maps and the affine maps from their dofs
to the quantities their kinematics start from.  This layer computes, for every
member at once (numpy, no per-member Python), the interaction variables q, their
Jacobian J = dq/du_e and Hessian H = d2q/du_e2 on the member's own dofs, and
(:mod:`ncstab.elements.law_response`) each law's response Q, D = dQ/dq and
internal-variable rates, derived once per law with sympy and then evaluated over
arrays.  Nothing here is derived per system.

* :mod:`ncstab.elements.branch` -- a granular contact (or a gap) whose branch,
  in the frame of one of its grains, is affine in the dofs: q = (l, alpha).
* :mod:`ncstab.elements.grain_contact` -- a contact between two rotating disks:
  q = (l, beta), beta = alpha minus the grains' rotations weighted by their radii.
* :mod:`ncstab.elements.bar_spring` -- a rotational spring between two rigid
  bars whose rise (sine of the bar angle) is linear in the dofs:
  q = asin(rise_b) - asin(rise_a); and the axial dead load of such bars.
* :mod:`ncstab.elements.linear_spring` -- a rotational spring whose rotation is linear
  in the dofs (the dofs are angles): q = c . u_e, J = c, H = 0.
* :mod:`ncstab.elements.tip_load` -- a follower or dead load P at the tip of a chain of
  bars given by their absolute angles (Ziegler's pendulum, Beck's column).

Every kind offers the same element protocol to the assembly
(:mod:`ncstab.operators.assembly`): ``names``, ``dofs`` ``(m, L)``, ``size``,
``weight`` (one number, or one per member) and ``kinematics(u, second) -> q, J, H``.
"""

from ncstab.elements.bar_spring import BarSprings, bar_angles, shortening
from ncstab.elements.branch import BranchElements, branch_kinematics
from ncstab.elements.grain_contact import GrainContacts, grain_contact_kinematics
from ncstab.elements.law_response import LawResponse, law_response
from ncstab.elements.linear_spring import LinearSprings
from ncstab.elements.tip_load import TIP_LOADS, TipLoad, tip_load_terms

__all__ = [
    "BarSprings",
    "BranchElements",
    "GrainContacts",
    "LawResponse",
    "LinearSprings",
    "TIP_LOADS",
    "TipLoad",
    "bar_angles",
    "branch_kinematics",
    "grain_contact_kinematics",
    "law_response",
    "shortening",
    "tip_load_terms",
]
