"""A system of grains given in the study file: ``[system] name = "grains"`` (docs/study-files.md).

Each grain is given by its centre and radius, and the dofs it does not have;
the contacts are index pairs::

    [system]
    name = "grains"
    grain = [
      { x = 0.0, y = 0.7071067811865476, radius = 0.5, held = ["x"] },
      ...
    ]
    contacts = [[0, 2], [0, 3], [1, 2], [1, 3]]
    rotations = false

Lengths are in units of the mean grain diameter d, as in a packing file
(docs/packings.md), and the grains are those of a packing: each has the dofs
``x<i>``, ``y<i>``, ``theta<i>`` (i its 0-based index) except those it holds,
with the forces ``Fx<i>``, ``Fy<i>``, ``M<i>``; ``rotations = false`` holds every
``theta`` (grains that slide without rolling, as the seed's diamond).  The
grains are at rest: contacts touch (centre distance = the sum of the radii, to
:data:`TOUCH_TOLERANCE`) and carry no force, and no two grains overlap.  The
system built is the packing's (:func:`~ncstab.systems.packing_system.assembled_packing`):
contacts between rotating disks, followed by the sparse engine.

Every check names the field and its first bad entry (``system.grain[2].radius``,
``system.contacts[1]``) before anything is built: an index out of range, a
grain in contact with itself or listed twice, a negative radius, grains that
overlap or a contact whose grains do not touch, a held dof that is not x, y or
theta.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["COMPONENTS", "TOUCH_TOLERANCE", "freeze_contacts", "freeze_grains", "grains_problems",
           "grains_system", "held_quantities"]

#: A grain's dofs, in order, and their forces.
COMPONENTS = ("x", "y", "theta")
FORCES = ("Fx", "Fy", "M")
#: The keys of a grain's table.
GRAIN_KEYS = ("x", "y", "radius", "held")
#: Grains touch where their centre distance is the sum of their radii to this part of the mean
#: diameter; two grains not in contact overlap where closer than that sum by more than it.
TOUCH_TOLERANCE = 1e-9
#: The most grains of a study file's list (a larger system is a packing file, docs/packings.md).
MOST_GRAINS = 10_000


def _number(value: Any) -> bool:
    """A finite number that is not a boolean (TOML's ``true`` is no radius)."""
    return isinstance(value, (int, float)) and not isinstance(value, bool) and math.isfinite(value)


def _table(grain: Any) -> Any:
    """A grain as its table: a frozen grain ``(x, y, radius, held)`` back as ``{x, y, radius, held}``."""
    if isinstance(grain, tuple) and len(grain) == 4:
        return {"x": grain[0], "y": grain[1], "radius": grain[2], "held": list(grain[3])}
    return grain


def _grain_problem(index: int, grain: Any) -> tuple[str, str] | None:
    where = f"grain[{index}]"
    if not isinstance(grain, dict):
        return where, f"expected a table {{ x = ..., y = ..., radius = ... }}, got {grain!r}"
    unknown = sorted(set(grain) - set(GRAIN_KEYS))
    if unknown:
        return f"{where}.{unknown[0]}", f"unknown key {unknown[0]!r}; a grain takes {', '.join(GRAIN_KEYS)}"
    for key in ("x", "y", "radius"):
        if key not in grain:
            return f"{where}.{key}", f"missing: give the grain's {key} (units of the mean grain diameter)"
        if not _number(grain[key]):
            return f"{where}.{key}", f"expected a finite number, got {grain[key]!r}"
    if grain["radius"] <= 0:
        return f"{where}.radius", f"expected a radius > 0, got {grain['radius']!r}"
    held = grain.get("held", [])
    if not isinstance(held, list) or any(c not in COMPONENTS for c in held) or len(set(held)) != len(held):
        return f"{where}.held", f"expected a list of distinct dofs among {', '.join(COMPONENTS)}, got {held!r}"
    return None


def grains_problems(grain: Any, contacts: Any, rotations: Any = True) -> list[tuple[str, str]]:
    """Every problem of a grain list and its contacts, as ``(field, message)`` (fields under ``system.``).

    ``grain`` and ``contacts`` as a study file gives them (lists of tables and pairs) or frozen
    (:func:`freeze_grains`, :func:`freeze_contacts`).  The geometry is checked only where each
    grain and contact is well formed: contacts whose grains do not touch, then pairs of grains
    that overlap (a k-d tree, not all pairs).
    """
    if isinstance(grain, tuple):
        grain = [_table(g) for g in grain]
    if isinstance(contacts, tuple):
        contacts = [list(pair) for pair in contacts]
    if not isinstance(grain, list) or not grain:
        return [("grain", "expected a list of grain tables { x = ..., y = ..., radius = ..., held = [...] }")]
    if len(grain) > MOST_GRAINS:
        return [("grain", f"{len(grain):,} grains: give at most {MOST_GRAINS:,} here; a larger system is a "
                          "packing file ([system] name = \"packing\")")]
    if not isinstance(rotations, bool):
        return [("rotations", f"expected true or false, got {rotations!r}")]
    problems = [p for p in (_grain_problem(i, g) for i, g in enumerate(grain)) if p is not None]
    if not isinstance(contacts, list):
        return [*problems, ("contacts", f"expected a list of grain index pairs such as [[0, 1], [1, 2]], got {contacts!r}")]
    n = len(grain)
    seen: dict[tuple[int, int], int] = {}
    for k, pair in enumerate(contacts):
        where = f"contacts[{k}]"
        if (not isinstance(pair, list) or len(pair) != 2
                or not all(isinstance(i, int) and not isinstance(i, bool) for i in pair)):
            problems.append((where, f"expected a pair of grain indices [a, b], got {pair!r}"))
        elif not all(0 <= i < n for i in pair):
            problems.append((where, f"{pair!r} names a grain that does not exist (grains are 0 .. {n - 1})"))
        elif pair[0] == pair[1]:
            problems.append((where, f"{pair!r}: a grain cannot be in contact with itself"))
        elif tuple(sorted(pair)) in seen:
            problems.append((where, f"{pair!r} is the contact of contacts[{seen[tuple(sorted(pair))]}] again"))
        else:
            seen[tuple(sorted(pair))] = k
    if problems:
        return problems
    return _geometry_problems(grain, contacts)


def _geometry_problems(grain: list[dict], contacts: list[list[int]]) -> list[tuple[str, str]]:
    from scipy.spatial import cKDTree

    x = np.array([[g["x"], g["y"]] for g in grain], dtype=float)
    r = np.array([g["radius"] for g in grain], dtype=float)
    problems = []
    for k, (a, b) in enumerate(contacts):
        distance, touching = float(np.linalg.norm(x[b] - x[a])), float(r[a] + r[b])
        if abs(distance - touching) > TOUCH_TOLERANCE:
            problems.append((f"contacts[{k}]", f"grains {a} and {b} do not touch at rest: their centres are "
                                               f"{distance:.12g} apart, their radii sum to {touching:.12g}"))
    listed = {tuple(sorted(p)) for p in contacts}
    for a, b in sorted(cKDTree(x).query_pairs(2 * float(r.max()))):
        if (a, b) in listed:
            continue
        distance = float(np.linalg.norm(x[b] - x[a]))
        if distance < r[a] + r[b] - TOUCH_TOLERANCE:
            problems.append(("grain", f"grains {a} and {b} overlap at rest (centres {distance:.12g} apart, radii "
                                      f"summing to {r[a] + r[b]:.12g}) and are not in contact: move them apart"))
            break
    return problems


def freeze_grains(grain: list[dict] | tuple) -> tuple[tuple[float, float, float, tuple[str, ...]], ...]:
    """A grain list as a hashable value: ``((x, y, radius, held), ...)`` (a frozen one as it is)."""
    tables = [_table(g) for g in grain]
    return tuple((float(g["x"]), float(g["y"]), float(g["radius"]), tuple(g.get("held", ()))) for g in tables)


def freeze_contacts(contacts: list[list[int]]) -> tuple[tuple[int, int], ...]:
    """Contacts as a hashable value."""
    return tuple((int(a), int(b)) for a, b in contacts)


def _held_mask(grains: tuple, rotations: bool) -> np.ndarray:
    held = np.array([[c in g[3] for c in COMPONENTS] for g in grains], dtype=bool)
    if not rotations:
        held[:, 2] = True
    return held


def held_quantities(grains: tuple, rotations: bool = True) -> tuple[tuple[str, str], ...]:
    """Each held dof and its force (``y1`` and ``Fy1``, ``theta0`` and ``M0``) with where it is held:
    what a stage cannot control (:attr:`~ncstab.systems.assembled.AssembledSystem.held`)."""
    held = _held_mask(grains, rotations)
    out = []
    for i, j in zip(*np.nonzero(held)):
        where = ("[system] rotations = false" if j == 2 and not rotations
                 else f"[system] grain[{i}].held = {list(grains[i][3])}")
        for name in (f"{COMPONENTS[j]}{i}", f"{FORCES[j]}{i}"):
            out.append((name, where))
    return tuple(out)


def grains_system(grain: tuple, contacts: tuple, rotations: bool = True):
    """The system of frozen grains and contacts: the :class:`~ncstab.systems.packing.Packing` of
    grains at rest (no contact forces; a grain with its three dofs held is ``fixed``, the others
    hold theirs, ``held``), followed as a packing
    (:func:`~ncstab.systems.packing_system.assembled_packing`)."""
    import dataclasses

    from ncstab.systems.packing import Packing
    from ncstab.systems.packing_system import assembled_packing

    held = _held_mask(grain, rotations)
    values = np.array([g[:3] for g in grain], dtype=float)
    zero = np.zeros(len(contacts))
    packing = Packing(values[:, 0], values[:, 1], values[:, 2], held.all(axis=1),
                      np.array(contacts, dtype=np.intp).reshape(-1, 2), zero, zero.copy(),
                      source="[system] grain", held=held)
    system = assembled_packing(packing)
    return dataclasses.replace(
        system, name="grains", title=f"{len(grain)} grains given in the study file ({system.n_dof} dofs, "
        f"{len(contacts)} contacts)", settings=(("contacts", contacts), ("grain", grain), ("rotations", rotations)),
        held=held_quantities(grain, rotations))
