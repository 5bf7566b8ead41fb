"""Granular chains as system definitions: the diamond (reduced and unreduced) and rings.

Dimensionless variables of the seed (Eq. 37): lengths in units of 2R, forces
in units of 2R k_n.  Every grain is free along its own axis (a radius of the
chain) and ``D_g`` is its displacement toward the centre.  A contact between
neighbour grains has the variables of seed Eq. (1), ``(l, alpha)``: its
branch length and the angle of the branch from the axis of one of its two
grains, so that the seed's laws apply to every contact unchanged.

* :func:`symmetric_diamond` -- the seed's two-dof reduction (Figs. 1-2,
  Eq. 1-4): one contact standing for the four (weight 2, seed Eq. 5).  The
  path engine follows it with a fused kernel written from the same
  kinematics (:class:`ncstab.systems.DiamondChain`); this definition is the
  symbolic statement of it, checked against that kernel in the tests.
* :func:`axes_diamond` -- the four grains each on its own axis, four
  contacts (top-left, top-right, bottom-left, bottom-right), each with its
  own internal variables: ``l cos(alpha) = cos(alpha0) - D_vertical``,
  ``l sin(alpha) = sin(alpha0) - D_side`` (seed Eq. 1 per contact).  On a
  symmetric path D_top = D_bottom = Delta_1, D_left = D_right = Delta_2 and
  F_top = F1.
* :func:`ring` -- n grains on a regular n-gon, grain 1 at the top, numbered
  clockwise; contact (i, i+1) has alpha measured counterclockwise from the
  axis of grain i, alpha0 = pi/2 - pi/n.  ``ring(4)`` is the axes diamond at
  alpha0 = pi/4 (its contacts measure alpha from the other grain's axis on
  two sides: the same mechanics for the seed's laws, which are odd in
  alpha - alpha0).

Secondary contacts: the gaps between non-neighbour grains (centre distance
minus 2R), each closing a frictionless spring of stiffness kappa k_n.
Inertia: grains of equal mass m, M = I in units of m (time in units of
sqrt(m / k_n)); each dof of the reduced diamond moves two grains, each force
acts on one (the per-contact virtual work of seed Eq. 5), so M = I there too.
"""

from __future__ import annotations

import sympy as sp

from ncstab.laws.definition import ALPHA0, ALPHA0_SPEC
from ncstab.systems.definition import (
    GapDefinition,
    InteractionFamily,
    SystemDefinition,
    SystemUnits,
    dof_symbols,
)

__all__ = ["GRANULAR_UNITS", "axes_diamond", "ring", "symmetric_diamond"]

GRANULAR_UNITS = SystemUnits(
    displacement="1",
    displacement_description="displacement of each grain toward the centre of the chain / 2R, seed Eq. (1), (37)",
    force="1",
    force_description="force on each grain toward the centre / (2R k_n), conjugate to its displacement, seed Eq. (4), (37)",
    work_description="work of the external forces per contact, in units of k_n (2R)^2 (seed Eq. 5)",
    force_unit="2R k_n",
)
#: The seed paper.
SEED = "Challamel, Nicot, Wautier, Darve & Lerbet (2022), J. Eng. Mech. 148(9) 04022053"


def _contact(vertical: sp.Expr, side: sp.Expr) -> tuple[sp.Expr, sp.Expr]:
    """(l, alpha) of a branch with components l cos(alpha) = vertical, l sin(alpha) = side."""
    return sp.sqrt(vertical**2 + side**2), sp.atan2(side, vertical)


def symmetric_diamond() -> SystemDefinition:
    """The seed's diamond reduced by symmetry to (Delta_1, Delta_2): Eq. (1)-(4)."""
    d1, d2 = dof_symbols(("D1", "D2"))
    c0, s0 = sp.cos(ALPHA0), sp.sin(ALPHA0)
    contact = InteractionFamily(
        name="contacts",
        kind="contact",
        members=("contact",),
        variables=(_contact(c0 - d1, s0 - d2),),
        weight=2.0,
        member_parameters=(("alpha0", (ALPHA0,)),),
    )
    return SystemDefinition(
        name="diamond",
        title="four-grain diamond reduced by symmetry (seed Figs. 1-2)",
        dofs=("D1", "D2"),
        forces=("F1", "F2"),
        families=(contact,),
        parameters=(ALPHA0_SPEC,),
        gaps=(
            GapDefinition("top_bottom", 2 * (c0 - d1) - 1, weight=0.5),
            GapDefinition("left_right", 2 * (s0 - d2) - 1, weight=0.5),
        ),
        mass=((1, 0), (0, 1)),
        work_factor=0.5,
        units=GRANULAR_UNITS,
        settings=(("reduction", "symmetric"),),
        reference=SEED,
    )


#: Contacts of the unreduced diamond: (name, vertical grain, side grain).
AXES_CONTACTS = (
    ("top_left", "top", "left"),
    ("top_right", "top", "right"),
    ("bottom_left", "bottom", "left"),
    ("bottom_right", "bottom", "right"),
)


def axes_diamond() -> SystemDefinition:
    """The four grains of the diamond, each free along its own axis (4 dofs, 4 contacts)."""
    grains = ("top", "bottom", "left", "right")
    dofs = tuple(f"D_{g}" for g in grains)
    symbol = dict(zip(grains, dof_symbols(dofs)))
    c0, s0 = sp.cos(ALPHA0), sp.sin(ALPHA0)
    contacts = InteractionFamily(
        name="contacts",
        kind="contact",
        members=tuple(name for name, _, _ in AXES_CONTACTS),
        variables=tuple(_contact(c0 - symbol[v], s0 - symbol[h]) for _, v, h in AXES_CONTACTS),
        weight=1.0,
        member_parameters=(("alpha0", (ALPHA0,) * 4),),
    )
    return SystemDefinition(
        name="diamond",
        title="four-grain diamond, each grain free along its own axis",
        dofs=dofs,
        forces=tuple(f"F_{g}" for g in grains),
        families=(contacts,),
        parameters=(ALPHA0_SPEC,),
        gaps=(
            GapDefinition("top_bottom", 2 * c0 - symbol["top"] - symbol["bottom"] - 1),
            GapDefinition("left_right", 2 * s0 - symbol["left"] - symbol["right"] - 1),
        ),
        mass=tuple(tuple(int(i == j) for j in range(4)) for i in range(4)),
        work_factor=0.25,
        units=GRANULAR_UNITS,
        settings=(("reduction", "axes"),),
        reference=SEED,
    )


def ring(grains: int) -> SystemDefinition:
    """n equal grains on a regular n-gon, each free along its radius (n >= 3).

    Grain i sits at the polar angle phi_i = 2 pi (i - 1)/n clockwise from the
    top, at the distance r = 1 / (2 sin(pi/n)) from the centre (neighbours
    touch), and moves by D_i toward the centre.
    """
    if isinstance(grains, bool) or not isinstance(grains, int) or grains < 3:
        raise ValueError(f"a ring needs grains >= 3 (a whole number), got {grains!r}")
    n = grains
    dofs = tuple(f"D{i}" for i in range(1, n + 1))
    u = dof_symbols(dofs)
    radius = 1 / (2 * sp.sin(sp.pi / n))
    axes = [sp.Matrix([sp.sin(2 * sp.pi * i / n), sp.cos(2 * sp.pi * i / n)]) for i in range(n)]
    positions = [(radius - u[i]) * axes[i] for i in range(n)]
    members, variables = [], []
    for i in range(n):
        j = (i + 1) % n
        branch = positions[i] - positions[j]
        cross = axes[i][0] * branch[1] - axes[i][1] * branch[0]
        dot = axes[i][0] * branch[0] + axes[i][1] * branch[1]
        members.append(f"{i + 1}_{j + 1}")
        variables.append((sp.sqrt(branch[0] ** 2 + branch[1] ** 2), sp.atan2(cross, dot)))
    contacts = InteractionFamily(
        name="contacts",
        kind="contact",
        members=tuple(members),
        variables=tuple(variables),
        weight=1.0,
        member_parameters=(("alpha0", (sp.pi / 2 - sp.pi / n,) * n),),
    )
    gaps = []
    for i in range(n):
        for j in range(i + 2, n):
            if i == 0 and j == n - 1:
                continue  # neighbours across the start of the numbering
            difference = positions[i] - positions[j]
            distance = sp.sqrt(difference[0] ** 2 + difference[1] ** 2)
            gaps.append(GapDefinition(f"{i + 1}_{j + 1}", distance - 1))
    return SystemDefinition(
        name="ring",
        title=f"ring of {n} grains on a regular {n}-gon, each free along its radius",
        dofs=dofs,
        forces=tuple(f"F{i}" for i in range(1, n + 1)),
        families=(contacts,),
        gaps=tuple(gaps),
        mass=tuple(tuple(int(i == j) for j in range(n)) for i in range(n)),
        work_factor=1.0 / n,
        units=GRANULAR_UNITS,
        settings=(("grains", n),),
        reference=SEED + "; Nicot & Darve (2011), Mech. Mater. 43(12) 918-929 (the hexagonal ring)",
    )
