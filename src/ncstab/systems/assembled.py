"""Systems as data: element arrays, dof maps, loads and masses, assembled numerically.

docs/models.md: a system is node coordinates, dof maps, element
connectivity, loads, masses, gaps and fixed dofs -- arrays, not one sympy
expression.  An :class:`AssembledSystem` holds

* its dofs and their conjugate forces (names, as a
  :class:`~ncstab.systems.SystemDefinition` has them);
* its granular contacts (:class:`~ncstab.elements.BranchElements`, or
  :class:`~ncstab.elements.GrainContacts` between rotating disks; each
  member's own ``alpha0``, and the stored forces they carry at u = 0)
  and/or its rotational springs between bars
  (:class:`~ncstab.elements.BarSprings`, with their own law), or springs whose
  rotation is linear in angle dofs (:class:`~ncstab.elements.LinearSprings`, Ziegler's chain);
* its grains' positions, affine in the dofs (``grain_origin + grain_matrix
  u[grain_dofs]``), from which the unilateral gaps between grains that are not
  in contact are found by a neighbour search (secondary contacts);
* an axial dead load on its bars (``P``, the work P sum (1 - cos theta_i)), or a
  follower or dead tip load on a chain of bars (:class:`~ncstab.elements.TipLoad`);
* the diagonal of its mass matrix, or a configuration-dependent mass matrix M(u) and a
  damping matrix C (``inertia``: :class:`~ncstab.systems.assembled_chain.ChainInertia`),
  or none.

It has the surface of a :class:`~ncstab.systems.SystemDefinition` that the
study, Dataset and figure layers read (``dofs``, ``forces``, ``families``,
``load``, ``mass``, ``gaps``, ``units``, ...), so that a study names it like
any system; the operators (:mod:`ncstab.operators.assembly`) assemble R and K
from its elements.  Nothing in it is symbolic: building a ring of 10,000
grains takes milliseconds.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ncstab.elements import BarSprings, BranchElements, GrainContacts, LinearSprings, TipLoad
from ncstab.systems.definition import FamilyNames, SystemUnits

__all__ = ["AssembledSystem", "AxialLoad", "ElementFamily", "GrainPositions", "is_assembled"]


@dataclass(frozen=True, eq=False)
class ElementFamily(FamilyNames):
    """What the study and Dataset layers read of an element family (as of an
    :class:`~ncstab.systems.definition.InteractionFamily`)."""

    name: str
    kind: str
    members: tuple[str, ...]
    weight: float = 1.0
    law: Any = None
    member_parameters: tuple[tuple[str, np.ndarray], ...] = ()


@dataclass(frozen=True, eq=False)
class AxialLoad:
    """An axial dead load P on bars whose rises are signed sums of dofs.

    ``rise_dofs``, ``rise_signs``: ``(bars, K)``; bar i rises by
    ``sum_k rise_signs[i, k] u[rise_dofs[i, k]]`` (the sine of its angle); the load does the
    work P sum_i L_i (1 - cos theta_i), L_i = ``lengths[i]`` (1 where ``lengths`` is None).
    """

    rise_dofs: np.ndarray
    rise_signs: np.ndarray
    parameter: str = "P"
    #: Each bar's length ``(bars,)`` in units of a, or ``None`` (every bar of length 1).
    lengths: np.ndarray | None = None
    kind: str = "dead"
    units: str = "C/a"
    description: str = "axial dead load P (units C/a)"


@dataclass(frozen=True, eq=False)
class GrainPositions:
    """Grain centres affine in the dofs: ``origin[g] + matrix[g] @ u[dofs[g]]`` (units 2R = 1).

    ``neighbours``: ``(pairs, 2)`` grains in contact through an element (not gaps).
    ``gap_weight``: weight of a secondary contact's spring in the internal work.
    """

    origin: np.ndarray
    dofs: np.ndarray
    matrix: np.ndarray
    neighbours: np.ndarray
    gap_weight: float = 1.0

    def at(self, u: np.ndarray) -> np.ndarray:
        """Grain centres ``(grains, 2)`` at the dofs ``u``."""
        return self.origin + np.einsum("gkl,gl->gk", self.matrix, u[self.dofs])


@dataclass(frozen=True, eq=False)
class AssembledSystem:
    """A discrete system as element arrays (see the module docstring).

    Attributes
    ----------
    name, title, dofs, forces, units, settings, reference, work_factor
        As for a :class:`~ncstab.systems.SystemDefinition`.
    contacts
        The granular contacts and their own ``alpha0`` (``(m,)``), or ``None``.
    springs
        Rotational springs between bars and their law, or ``None``.
    grains
        Grain centres (for the gaps of secondary contacts), or ``None``.
    axial_load
        The axial dead load, or ``None``.
    tip_load
        A follower or dead tip load on a chain of bars, or ``None`` (not with ``axial_load``).
    masses
        Diagonal of M ``(n,)``, or ``None``.
    inertia
        M(u) and C of a small system (``mass(u)``, ``damping()``, ``pencil(u, K)`` and
        ``for_values(values)``: :class:`~ncstab.systems.assembled_chain.ChainInertia`), or
        ``None``; :meth:`for_values` gives it the case's parameter values.
    system_parameters
        The system's own parameters (:class:`~ncstab.laws.ParameterSpec`), set per case.
    spring_rest
        ``values -> (m,)`` the springs' stress-free q for a case's parameter values, or
        ``None`` (stress-free straight); :meth:`for_values` applies it.
    contact_forces
        The contacts' stored forces at u = 0, ``(m, forces)`` in their law's units
        (a rate law's internal variables start there), or ``None``: zero.
    case_system
        ``(system, law, values) -> system``: the system of one case, whose contacts
        depend on the contact law and the case's parameters (a packing's rest lengths
        and alpha0 carry its forces, :mod:`ncstab.systems.packing_system`), or ``None``;
        :meth:`for_values` applies it.
    hold_other_forces
        A loading stage may leave dofs uncontrolled: their forces are held where they
        are when it starts (a packing's thousands of dofs), instead of an error.
    held
        ``((quantity, where), ...)``: the displacements and forces that the system holds and
        a stage cannot control, with the setting that holds them (a grain's held ``y1`` and
        ``Fy1``, a supported joint's ``w3`` and ``F3``); a stage naming one is refused.
    """

    name: str
    title: str
    dofs: tuple[str, ...]
    forces: tuple[str, ...]
    contacts: BranchElements | GrainContacts | None = None
    contact_alpha0: np.ndarray | None = None
    springs: BarSprings | LinearSprings | None = None
    spring_law: Any = None
    grains: GrainPositions | None = None
    axial_load: AxialLoad | None = None
    masses: np.ndarray | None = None
    tip_load: TipLoad | None = None
    inertia: Any = None
    units: SystemUnits = field(default_factory=SystemUnits)
    settings: tuple[tuple[str, Any], ...] = ()
    reference: str = ""
    work_factor: float = 1.0
    system_parameters: tuple = ()
    spring_rest: Callable[[dict[str, float]], np.ndarray] | None = None
    contact_forces: np.ndarray | None = None
    case_system: Callable[[AssembledSystem, Any, dict[str, float]], AssembledSystem] | None = None
    hold_other_forces: bool = False
    held: tuple[tuple[str, str], ...] = ()

    def for_values(self, values: dict[str, float], law: Any = None) -> AssembledSystem:
        """The system of one case: its springs stress-free where its parameters say, its
        contacts those of the contact ``law`` and ``values`` where :attr:`case_system` says."""
        system = self
        if self.case_system is not None and law is not None:
            system = self.case_system(self, law, values)
        if system.inertia is not None:
            system = dataclasses.replace(system, inertia=system.inertia.for_values(values))
        if system.spring_rest is None or system.springs is None:
            return system
        rest = system.spring_rest(values)
        if not np.any(rest):
            return system
        return dataclasses.replace(system, springs=dataclasses.replace(system.springs, rest=rest))

    def __post_init__(self) -> None:
        n = len(self.dofs)
        if n == 0 or len(self.forces) != n:
            raise ValueError(f"system {self.name!r}: give n >= 1 dofs and as many forces")
        if self.contacts is None and self.springs is None:
            raise ValueError(f"system {self.name!r}: give contacts or springs")
        if self.axial_load is not None and self.tip_load is not None:
            raise ValueError(f"system {self.name!r}: give an axial load or a tip load, not both")
        if self.masses is not None and self.inertia is not None:
            raise ValueError(f"system {self.name!r}: give the diagonal masses or the inertia, not both")
        for label, elements in (("contact", self.contacts), ("spring", self.springs)):
            if elements is not None and elements.size and (elements.dofs.min() < 0 or elements.dofs.max() >= n):
                bad = int(np.flatnonzero((elements.dofs < 0).any(1) | (elements.dofs >= n).any(1))[0])
                raise ValueError(
                    f"system {self.name!r}: {label} {elements.names[bad]!r} names a dof that does not exist "
                    f"(dofs are 0 .. {n - 1})"
                )

    # --- the surface of a SystemDefinition --------------------------------------------
    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    @property
    def families(self) -> tuple[ElementFamily, ...]:
        out = []
        if self.contacts is not None:
            weight = self.contacts.weight if np.ndim(self.contacts.weight) == 0 else 1.0  # else each member's own
            out.append(ElementFamily("contacts", "contact", self.contacts.names, weight, None,
                                     (("alpha0", self.contact_alpha0),)))
        if self.springs is not None:
            out.append(ElementFamily("springs", "spring", self.springs.names, self.springs.weight, self.spring_law))
        return tuple(out)

    def family(self, kind: str) -> ElementFamily | None:
        return next((f for f in self.families if f.kind == kind), None)

    @property
    def parameters(self) -> tuple:
        return self.system_parameters

    parameter_specs = parameters

    @property
    def load(self) -> AxialLoad | TipLoad | None:
        return self.axial_load if self.axial_load is not None else self.tip_load

    @property
    def load_parameter(self) -> str | None:
        return None if self.load is None else self.load.parameter

    @property
    def mass(self):
        """A marker: not ``None`` where the system has inertia (M = diag(:attr:`masses`), or
        :attr:`inertia`'s M(u))."""
        if self.inertia is not None:
            return ("matrix",)
        return None if self.masses is None else ("diagonal",)

    @property
    def damping(self):
        """A marker: not ``None`` where the system has a damping matrix (:attr:`inertia`'s C)."""
        return None if self.inertia is None else ("matrix",)

    @property
    def has_inertia(self) -> bool:
        return self.masses is not None or self.inertia is not None

    @property
    def gaps(self) -> tuple[str, ...]:
        """Non-empty where grains can meet in new (secondary) contacts."""
        return ("secondary contacts between grains",) if self.grains is not None else ()


def is_assembled(system: Any) -> bool:
    """Whether ``system`` is assembled from elements (followed by the sparse engine)."""
    return isinstance(system, AssembledSystem)
