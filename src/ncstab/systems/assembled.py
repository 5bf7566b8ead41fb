"""Systems as data: element arrays, dof maps, loads and masses, assembled numerically.

docs/models.md: a system is node coordinates, dof maps, element
connectivity, loads, masses, gaps and fixed dofs -- arrays, not one sympy
expression.  An :class:`AssembledSystem` holds

* its dofs and their conjugate forces (names, as a
  :class:`~ncstab.systems.SystemDefinition` has them);
* its granular contacts (:class:`~ncstab.elements.BranchElements`, each
  member's own ``alpha0``) and/or its rotational springs between bars
  (:class:`~ncstab.elements.BarSprings`, with their own law);
* its grains' positions, affine in the dofs (``grain_origin + grain_matrix
  u[grain_dofs]``), from which the unilateral gaps between grains that are not
  in contact are found by a neighbour search (secondary contacts);
* an axial dead load on its bars (``P``, the work P sum (1 - cos theta_i));
* the diagonal of its mass matrix, or none.

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

from ncstab.elements import BarSprings, BranchElements
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
    ``sum_k rise_signs[i, k] u[rise_dofs[i, k]]`` (the sine of its angle).
    """

    rise_dofs: np.ndarray
    rise_signs: np.ndarray
    parameter: str = "P"
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
    masses
        Diagonal of M ``(n,)``, or ``None``.
    system_parameters
        The system's own parameters (:class:`~ncstab.laws.ParameterSpec`), set per case.
    spring_rest
        ``values -> (m,)`` the springs' stress-free q for a case's parameter values, or
        ``None`` (stress-free straight); :meth:`for_values` applies it.
    """

    name: str
    title: str
    dofs: tuple[str, ...]
    forces: tuple[str, ...]
    contacts: BranchElements | None = None
    contact_alpha0: np.ndarray | None = None
    springs: BarSprings | None = None
    spring_law: Any = None
    grains: GrainPositions | None = None
    axial_load: AxialLoad | None = None
    masses: np.ndarray | None = None
    units: SystemUnits = field(default_factory=SystemUnits)
    settings: tuple[tuple[str, Any], ...] = ()
    reference: str = ""
    work_factor: float = 1.0
    system_parameters: tuple = ()
    spring_rest: Callable[[dict[str, float]], np.ndarray] | None = None

    def for_values(self, values: dict[str, float]) -> AssembledSystem:
        """The system of one case: its springs stress-free where its parameters say."""
        if self.spring_rest is None or self.springs is None:
            return self
        rest = self.spring_rest(values)
        if not np.any(rest):
            return self
        return dataclasses.replace(self, springs=dataclasses.replace(self.springs, rest=rest))

    def __post_init__(self) -> None:
        n = len(self.dofs)
        if n == 0 or len(self.forces) != n:
            raise ValueError(f"system {self.name!r}: give n >= 1 dofs and as many forces")
        if self.contacts is None and self.springs is None:
            raise ValueError(f"system {self.name!r}: give contacts or springs")
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
            out.append(ElementFamily("contacts", "contact", self.contacts.names, self.contacts.weight, None,
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
    def load(self) -> AxialLoad | None:
        return self.axial_load

    @property
    def load_parameter(self) -> str | None:
        return None if self.axial_load is None else self.axial_load.parameter

    @property
    def mass(self):
        """A marker: not ``None`` where the system has inertia (M = diag(:attr:`masses`))."""
        return None if self.masses is None else ("diagonal",)

    damping = None

    @property
    def has_inertia(self) -> bool:
        return self.masses is not None

    @property
    def gaps(self) -> tuple[str, ...]:
        """Non-empty where grains can meet in new (secondary) contacts."""
        return ("secondary contacts between grains",) if self.grains is not None else ()


def is_assembled(system: Any) -> bool:
    """Whether ``system`` is assembled from elements (followed by the sparse engine)."""
    return isinstance(system, AssembledSystem)
