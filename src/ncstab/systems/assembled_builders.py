"""The shipped granular and bar systems as element arrays (any size).

The same systems, dofs, orientations and units as the symbolic definitions of
:mod:`ncstab.systems.granular` and :mod:`ncstab.systems.bars` (checked against
them in the tests, K to 1e-12):

* :func:`assembled_ring` -- n grains on a regular n-gon, grain i at the polar
  angle 2 pi (i - 1)/n clockwise from the top, at r = 1/(2 sin(pi/n)) from the
  centre, moving by D_i toward it: X_i = (r - D_i) e_i, e_i = (sin, cos) of its
  angle.  Contact (i, i+1) measures its branch X_i - X_{i+1} in the frame of
  grain i's axis: c = e_i . b, s = e_i x b, alpha0 = pi/2 - pi/n.
* :func:`assembled_diamond` -- the seed's diamond: the two-dof reduction (one
  contact of weight 2, c = cos alpha0 - D1, s = sin alpha0 - D2, seed Eq. 1) or
  the four grains on their axes.
* :func:`assembled_column` -- Hencky's column of n links (bar i rises by
  w_i - w_{i-1}, springs C between neighbour bars, axial dead load P).
"""

from __future__ import annotations

import functools
import math

import numpy as np

from ncstab.elements import BarSprings, BranchElements
from ncstab.laws.spring import LINEAR_SPRING
from ncstab.systems.assembled import AssembledSystem, AxialLoad, GrainPositions
from ncstab.systems.bars import COLUMN_REFERENCE, COLUMN_UNITS, IMPERFECTION_SPEC, imperfect_rises
from ncstab.systems.granular import GRANULAR_UNITS, SEED

__all__ = ["assembled_column", "assembled_diamond", "assembled_ring"]


def assembled_ring(grains: int) -> AssembledSystem:
    """A ring of ``grains`` grains (n >= 3), each free along its radius."""
    if isinstance(grains, bool) or not isinstance(grains, int) or grains < 3:
        raise ValueError(f"a ring needs grains >= 3 (a whole number), got {grains!r}")
    n = grains
    angle = 2 * np.pi * np.arange(n) / n
    axis = np.stack([np.sin(angle), np.cos(angle)], axis=1)
    radius = 1 / (2 * math.sin(math.pi / n))
    i = np.arange(n)
    j = (i + 1) % n
    dot = np.einsum("mk,mk->m", axis[i], axis[j])
    cross = axis[i, 0] * axis[j, 1] - axis[i, 1] * axis[j, 0]
    matrix = np.zeros((n, 2, 2))
    matrix[:, 0, 0] = -1.0
    matrix[:, 0, 1] = dot
    matrix[:, 1, 1] = cross
    origin = np.stack([radius * (1 - dot), -radius * cross], axis=1)
    contacts = BranchElements(
        names=tuple(f"{a + 1}_{b + 1}" for a, b in zip(i, j)),
        dofs=np.stack([i, j], axis=1),
        matrix=matrix,
        origin=origin,
    )
    grain_positions = GrainPositions(
        origin=radius * axis,
        dofs=i[:, None],
        matrix=-axis[:, :, None],
        neighbours=np.stack([i, j], axis=1),
    )
    return AssembledSystem(
        name="ring",
        title=f"ring of {n} grains on a regular {n}-gon, each free along its radius",
        dofs=tuple(f"D{k}" for k in range(1, n + 1)),
        forces=tuple(f"F{k}" for k in range(1, n + 1)),
        contacts=contacts,
        contact_alpha0=np.full(n, np.pi / 2 - np.pi / n),
        grains=grain_positions,
        masses=np.ones(n),
        units=GRANULAR_UNITS,
        settings=(("grains", n),),
        reference=SEED + "; Nicot & Darve (2011), Mech. Mater. 43(12) 918-929 (the hexagonal ring)",
        work_factor=1.0 / n,
    )


def assembled_diamond(reduction: str = "symmetric", alpha0: float = math.pi / 4) -> AssembledSystem:
    """The seed's diamond, ``reduction`` ``"symmetric"`` (D1, D2) or ``"axes"`` (four grains)."""
    c0, s0 = math.cos(alpha0), math.sin(alpha0)
    # grains top, bottom, left, right, each moving toward the centre along its axis; the four
    # contacts join the vertical grains to the side ones (secondary contacts: top-bottom, left-right)
    origin = np.array([[0.0, c0], [0.0, -c0], [-s0, 0.0], [s0, 0.0]])
    toward_centre = np.array([[[0.0], [-1.0]], [[0.0], [1.0]], [[1.0], [0.0]], [[-1.0], [0.0]]])
    neighbours = np.array([[0, 2], [0, 3], [1, 2], [1, 3]])
    if reduction == "symmetric":
        contacts = BranchElements(("contact",), np.array([[0, 1]]), -np.eye(2)[None], np.array([[c0, s0]]), weight=2.0)
        grains = GrainPositions(origin, np.array([[0], [0], [1], [1]]), toward_centre, neighbours, gap_weight=0.5)
        return AssembledSystem(
            name="diamond", title="four-grain diamond reduced by symmetry (seed Figs. 1-2)",
            dofs=("D1", "D2"), forces=("F1", "F2"), contacts=contacts, contact_alpha0=np.array([alpha0]),
            grains=grains, masses=np.ones(2), units=GRANULAR_UNITS, settings=(("reduction", "symmetric"),),
            reference=SEED, work_factor=0.5,
        )
    if reduction != "axes":
        raise ValueError(f"reduction = {reduction!r} is not allowed; allowed: symmetric, axes")
    # dofs: D_top, D_bottom, D_left, D_right; contacts (vertical grain, side grain)
    pairs = np.array([[0, 2], [0, 3], [1, 2], [1, 3]])
    contacts = BranchElements(
        ("top_left", "top_right", "bottom_left", "bottom_right"), pairs,
        np.repeat(-np.eye(2)[None], 4, axis=0), np.tile([c0, s0], (4, 1)),
    )
    return AssembledSystem(
        name="diamond", title="four-grain diamond, each grain free along its own axis",
        dofs=("D_top", "D_bottom", "D_left", "D_right"), forces=("F_top", "F_bottom", "F_left", "F_right"),
        contacts=contacts, contact_alpha0=np.full(4, alpha0),
        grains=GrainPositions(origin, np.arange(4)[:, None], toward_centre, neighbours),
        masses=np.ones(4), units=GRANULAR_UNITS,
        settings=(("reduction", "axes"),), reference=SEED, work_factor=0.25,
    )


def assembled_column(links: int) -> AssembledSystem:
    """Hencky's column of ``links`` rigid links (n >= 2) under an axial dead load P."""
    if isinstance(links, bool) or not isinstance(links, int) or links < 2:
        raise ValueError(f"a column needs links >= 2 (a whole number), got {links!r}")
    n = links
    # bar i (1..n) rises by w_i - w_{i-1}; w_k is dof k - 1, w_0 = w_n = 0 are absent
    bars = np.arange(1, n + 1)
    upper, lower = bars - 1, bars - 2  # dof indices of w_i and w_{i-1}
    rise_dofs = np.stack([np.where(bars < n, upper, 0), np.where(bars > 1, lower, 0)], axis=1)
    rise_signs = np.stack([(bars < n).astype(float), -(bars > 1).astype(float)], axis=1)
    # spring j (1..n-1) between bars j and j+1, on w_{j-1}, w_j, w_{j+1}
    joints = np.arange(1, n)
    local = np.stack([joints - 2, joints - 1, joints], axis=1)
    present = (local >= 0) & (local <= n - 2)
    rises = np.zeros((n - 1, 2, 3))
    rises[:, 0, 0], rises[:, 0, 1] = -1.0, 1.0  # bar j: w_j - w_{j-1}
    rises[:, 1, 1], rises[:, 1, 2] = -1.0, 1.0  # bar j+1: w_{j+1} - w_j
    rises *= present[:, None, :]
    springs = BarSprings(tuple(f"joint{j}" for j in joints), np.where(present, local, 0), rises)
    return AssembledSystem(
        name="column",
        title=f"Hencky column of {n} rigid links with rotational springs, axial dead load",
        dofs=tuple(f"w{i}" for i in range(1, n)),
        forces=tuple(f"F{i}" for i in range(1, n)),
        springs=springs,
        spring_law=LINEAR_SPRING,
        axial_load=AxialLoad(rise_dofs, rise_signs),
        units=COLUMN_UNITS,
        settings=(("links", n),),
        reference=COLUMN_REFERENCE,
        system_parameters=(IMPERFECTION_SPEC,),
        spring_rest=functools.partial(_column_rest, imperfect_rises(n)),
    )


def _column_rest(unit_rises: np.ndarray, values: dict[str, float]) -> np.ndarray:
    """Spring j's stress-free rotation asin(e r_{j+1}) - asin(e r_j) in the imperfect shape
    w0_i = e sin(pi i / n), e = ``values["imperfection"]`` (the derived column's, :func:`column`)."""
    angles = np.arcsin(float(values.get("imperfection", 0.0)) * unit_rises)
    return np.diff(angles)
