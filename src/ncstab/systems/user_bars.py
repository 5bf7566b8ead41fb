"""A chain of rigid bars given by its joints in the study file: ``[system] name = "bars"``.

The joints are given by their heights along the chain's axis, from the base up; the
bars join consecutive joints; some joints are supported (held on the axis); each
internal joint carries a linear rotational spring; an axial dead load P acts at the
top, which slides along the axis (docs/study-files.md)::

    [system]
    name = "bars"
    joints = [0.0, 1.0, 2.5, 3.0]   # heights z_0 < z_1 < ... (units a, the reference length)
    supports = [0, 3]               # joints held on the axis (default "ends": the first and the last)
    springs = [1.0, 2.0]            # stiffness of each internal joint's spring (units C), or one number

Hencky's column of n links is ``joints = [0, 1, ..., n]`` with the defaults.  Joint j
(0-based) that is not supported has the dof ``w<j>``, its lateral displacement in units
of a, conjugate to the force ``F<j>``; bar i (1-based, from joint i - 1 to joint i, of
length L_i = z_i - z_{i-1}) is at the angle theta_i = asin((w_i - w_{i-1}) / L_i) from the
axis; the spring at joint j has the moment C_j (theta_{j+1} - theta_j); P does the work
P sum_i L_i (1 - cos theta_i) (:func:`ncstab.elements.shortening`).  For two bars of
lengths L_1, L_2 and a spring C between them, P_cr = C (1/L_1 + 1/L_2).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["MOST_JOINTS", "assembled_bars", "bars_problems"]

#: The most joints of a study file's list (a longer column is ``name = "column"``).
MOST_JOINTS = 100_000


def _number(value: Any) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def bars_problems(joints: Any, supports: Any = None, springs: Any = 1.0) -> list[tuple[str, str]]:
    """Every problem of a chain's joints, supports and springs, as ``(field, message)``."""
    if not isinstance(joints, (list, tuple)) or len(joints) < 3:
        return [("joints", "expected a list of at least 3 joint heights (two bars), from the base up, "
                           f"got {joints!r}")]
    if len(joints) > MOST_JOINTS:
        return [("joints", f"{len(joints):,} joints: give at most {MOST_JOINTS:,} here; a longer uniform "
                           "chain is name = \"column\" (links = n)")]
    for j, z in enumerate(joints):
        if not _number(z):
            return [(f"joints[{j}]", f"expected a finite number (a height, units a), got {z!r}")]
        if j and z <= joints[j - 1]:
            return [(f"joints[{j}]", f"{z!r} is not above joints[{j - 1}] = {joints[j - 1]!r}: give the "
                                     "heights from the base up, each above the last (bars of positive length)")]
    n = len(joints)
    supports = [0, n - 1] if supports in (None, "ends") else supports
    if not isinstance(supports, (list, tuple)):
        return [("supports", f"expected a list of joint indices, got {supports!r}")]
    for k, j in enumerate(supports):
        if not isinstance(j, int) or isinstance(j, bool) or not 0 <= j < n:
            return [(f"supports[{k}]", f"{j!r} names a joint that does not exist (joints are 0 .. {n - 1})")]
        if j in supports[:k]:
            return [(f"supports[{k}]", f"joint {j} is supported twice")]
    if len(set(supports)) == n:
        return [("supports", "every joint is supported: the chain has no dof")]
    if _number(springs):
        if springs <= 0:
            return [("springs", f"expected a stiffness > 0, got {springs!r}")]
    elif not isinstance(springs, (list, tuple)) or len(springs) != n - 2:
        return [("springs", f"expected one stiffness (units C) or a list of {n - 2}, one per internal joint "
                            f"(joints 1 .. {n - 2}), got {springs!r}")]
    else:
        for k, c in enumerate(springs):
            if not _number(c) or c < 0:
                return [(f"springs[{k}]", f"expected a stiffness >= 0 (units C), got {c!r}")]
    return []


def assembled_bars(joints: tuple, supports: Any = "ends", springs: Any = 1.0):
    """The :class:`~ncstab.systems.assembled.AssembledSystem` of a chain (see the module docstring)."""
    from ncstab.elements import BarSprings
    from ncstab.laws.spring import LINEAR_SPRING
    from ncstab.systems.assembled import AssembledSystem, AxialLoad
    from ncstab.systems.bars import COLUMN_UNITS

    z = np.asarray(joints, dtype=float)
    n = len(z) - 1  # bars
    held = np.zeros(n + 1, dtype=bool)
    held[list((0, n) if supports in (None, "ends") else supports)] = True
    index = np.full(n + 1, -1, dtype=np.intp)
    index[~held] = np.arange(int(np.count_nonzero(~held)))
    lengths = np.diff(z)
    # bar i (1..n) rises by (w_i - w_{i-1}) / L_i; a supported joint's term is absent (sign 0, dof 0)
    upper, lower = index[1:], index[:-1]
    rise_dofs = np.stack([np.maximum(upper, 0), np.maximum(lower, 0)], axis=1)
    rise_signs = np.stack([(upper >= 0) / lengths, -1.0 * (lower >= 0) / lengths], axis=1)
    # spring j (1..n-1) between bars j and j+1, on w_{j-1}, w_j, w_{j+1}
    joint = np.arange(1, n)
    local = np.stack([index[joint - 1], index[joint], index[joint + 1]], axis=1)
    present = local >= 0
    rises = np.zeros((n - 1, 2, 3))
    rises[:, 0, 0], rises[:, 0, 1] = -1.0 / lengths[joint - 1], 1.0 / lengths[joint - 1]
    rises[:, 1, 1], rises[:, 1, 2] = -1.0 / lengths[joint], 1.0 / lengths[joint]
    rises *= present[:, None, :]
    stiffness = np.broadcast_to(np.asarray(springs, dtype=float), (n - 1,)).copy()
    springs_elements = BarSprings(tuple(f"joint{j}" for j in joint), np.where(present, local, 0), rises,
                                  weight=stiffness)
    dofs = tuple(f"w{j}" for j in np.flatnonzero(~held))
    where = f"[system] supports = {list(np.flatnonzero(held))}"
    return AssembledSystem(
        name="bars",
        title=f"chain of {n} rigid bars given by its joints, {int(held.sum())} supported, axial dead load",
        dofs=dofs,
        forces=tuple(f"F{j}" for j in np.flatnonzero(~held)),
        springs=springs_elements,
        spring_law=LINEAR_SPRING,
        axial_load=AxialLoad(rise_dofs, rise_signs, lengths=lengths),
        units=COLUMN_UNITS,
        settings=(("joints", tuple(joints)), ("springs", springs), ("supports", supports)),
        reference="Hencky (1921), Eisenbau 12 437-452 (the bar chain); docs/study-files.md",
        held=tuple((f"{q}{j}", where) for j in np.flatnonzero(held).tolist() for q in ("w", "F")),
    )
