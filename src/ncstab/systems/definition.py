"""A discrete system as a value: dofs, interaction families, loads, inertia, gaps.

docs/models.md.  A :class:`SystemDefinition` says, once and
symbolically (sympy expressions of the dof symbols and the system's
parameters):

* its degrees of freedom ``u`` and the generalized forces ``F`` conjugate to
  them (controlled per stage by the loading programme);
* its **interaction families**: per member, the interaction variables
  ``q(u)`` (``(l, alpha)`` for a granular contact, one relative angle for a
  rotational spring), the weight ``w`` of the family in the virtual work
  ``dW_int = sum w Q . dq`` (seed Eq. 5, 9, 16), law parameters fixed per
  member by the geometry (each contact's own ``alpha0``) and, for families
  with a law of their own (springs), that law;
* its **load** scaled by a load parameter (``P``): the generalized load
  ``Q_ext(u)`` per unit of the parameter, dead (from a potential) or
  follower (not), whose load stiffness ``-P dQ_ext/du`` enters K;
* its **mass and damping matrices** ``M(u)``, ``C`` (the linearised
  dynamics ``M s^2 + C s + K``);
* its **unilateral gaps** ``g(u)`` (new contacts where ``g`` reaches 0, each
  with its own contact-state bit) and its **admissible domain**.

Everything numeric -- J = dq/du, H = d2q/du2, the load stiffness, gap
gradients -- is derived from this description once
(:func:`ncstab.systems.compile.compile_system`), never written by hand per
system.  The value is frozen, hashable and picklable: a model built in Python
reaches every worker of a chunked or dask run as it is.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import sympy as sp

from ncstab.laws.definition import ParameterSpec

__all__ = [
    "DomainCondition",
    "FamilyNames",
    "GapDefinition",
    "InteractionFamily",
    "LoadDefinition",
    "SystemDefinition",
    "SystemUnits",
    "dof_symbols",
    "FAMILY_KINDS",
]

#: Interaction families a system may have: name of the kind -> (the dimension of
#: its members in a Dataset, the names of its variables, the names of its forces).
FAMILY_KINDS = {
    "contact": ("contact", ("l", "alpha"), ("N", "T")),
    "spring": ("spring", ("theta",), ("moment",)),
}


def dof_symbols(names: tuple[str, ...] | list[str]) -> tuple[sp.Symbol, ...]:
    """The sympy symbols of dofs ``names`` (real), as :class:`SystemDefinition` uses them."""
    return tuple(sp.Symbol(name, real=True) for name in names)


class FamilyNames:
    """What every layer reads of a family of members, from its ``kind``, ``members`` and
    ``member_parameters`` (shared by symbolic and assembled families)."""

    @property
    def size(self) -> int:
        return len(self.members)

    @property
    def dimension(self) -> str:
        """Name of the members' dimension in a Dataset (``contact``, ``spring``)."""
        return FAMILY_KINDS[self.kind][0]

    @property
    def variable_names(self) -> tuple[str, ...]:
        return FAMILY_KINDS[self.kind][1]

    @property
    def force_names(self) -> tuple[str, ...]:
        return FAMILY_KINDS[self.kind][2]

    @property
    def fixed_parameters(self) -> tuple[str, ...]:
        """Law parameters set per member by the geometry."""
        return tuple(name for name, _ in self.member_parameters)


@dataclass(frozen=True)
class InteractionFamily(FamilyNames):
    """Members of one kind of interaction, each with its variables q(u).

    Attributes
    ----------
    name
        Family name (``"contacts"``, ``"springs"``).
    kind
        ``"contact"`` (variables ``(l, alpha)``, forces ``(N, T)``, a contact
        law of :mod:`ncstab.laws`) or ``"spring"`` (variable ``theta``, force
        ``moment``, a :class:`~ncstab.laws.spring.SpringLaw`).
    members
        Member names (``("top_left", "top_right", ...)``).
    variables
        Per member, its interaction variables as expressions of the dofs and
        the system's parameters (one tuple of k expressions per member).
    weight
        Weight w of every member in the internal virtual work.
    member_parameters
        ``(law parameter name, one expression per member)``: law parameters
        fixed by the geometry (each contact's own ``alpha0``); a study does
        not set them.
    law
        The family's own law (springs), or ``None``: the model's law applies.
    """

    name: str
    kind: str
    members: tuple[str, ...]
    variables: tuple[tuple[Any, ...], ...]
    weight: float = 1.0
    member_parameters: tuple[tuple[str, tuple[Any, ...]], ...] = ()
    law: Any = None

    def __post_init__(self) -> None:
        if self.kind not in FAMILY_KINDS:
            raise ValueError(f"family {self.name!r}: kind must be one of {', '.join(FAMILY_KINDS)}, got {self.kind!r}")
        if len(self.variables) != len(self.members) or not self.members:
            raise ValueError(f"family {self.name!r}: give one tuple of variables per member")
        width = len(FAMILY_KINDS[self.kind][1])
        if any(len(q) != width for q in self.variables):
            raise ValueError(f"family {self.name!r}: a {self.kind} has {width} interaction variable(s) per member")
        object.__setattr__(
            self, "variables", tuple(tuple(sp.sympify(e) for e in q) for q in self.variables)
        )
        object.__setattr__(
            self,
            "member_parameters",
            tuple((name, tuple(sp.sympify(e) for e in values)) for name, values in self.member_parameters),
        )
        for name, values in self.member_parameters:
            if len(values) != len(self.members):
                raise ValueError(f"family {self.name!r}: parameter {name!r} needs one value per member")
        if self.law is not None and self.law.kind != self.kind:
            raise ValueError(f"family {self.name!r} of {self.kind}s cannot take the {self.law.kind} law {self.law.name!r}")



@dataclass(frozen=True)
class LoadDefinition:
    """Loads scaled by a load parameter: F_ext(u, P) = P Q_ext(u).

    Attributes
    ----------
    parameter
        Name of the load parameter (``"P"``), a driven quantity of
        load-parameter stages.
    kind
        ``"dead"`` (Q_ext derives from a potential) or ``"follower"``.
    vector
        Q_ext(u), the generalized load per unit of the parameter (n expressions).
    units, description
        Of the parameter (``"k/l"``, ``"tip load"``).
    """

    parameter: str
    kind: str
    vector: tuple[Any, ...]
    units: str = "1"
    description: str = "load parameter"

    def __post_init__(self) -> None:
        if self.kind not in ("dead", "follower"):
            raise ValueError(f"load kind must be 'dead' or 'follower', got {self.kind!r}")
        object.__setattr__(self, "vector", tuple(sp.sympify(e) for e in self.vector))


@dataclass(frozen=True)
class GapDefinition:
    """A unilateral gap: a new contact closes where ``distance`` reaches 0.

    Attributes
    ----------
    name
        Gap name (``"top_bottom"``).
    distance
        g(u) (> 0 open, < 0 overlapping), e.g. centre distance minus 2R.
    weight
        Weight of the gap's unilateral spring in the internal virtual work
        (its energy ``w kappa g^2 / 2`` while closed, ``kappa`` the engine's
        secondary-contact stiffness ratio).
    """

    name: str
    distance: Any
    weight: float = 1.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "distance", sp.sympify(self.distance))


@dataclass(frozen=True)
class DomainCondition:
    """Where the model is defined: ``expression > 0``, with the reason it fails."""

    expression: Any
    reason: str

    def __post_init__(self) -> None:
        object.__setattr__(self, "expression", sp.sympify(self.expression))


@dataclass(frozen=True)
class SystemUnits:
    """Units and meanings of a system's dofs, forces and work (Dataset attributes)."""

    displacement: str = "1"
    displacement_description: str = "generalized displacements"
    force: str = "1"
    force_description: str = "generalized forces conjugate to the dofs"
    work_description: str = "work of the external forces"
    force_unit: str = "1"


@dataclass(frozen=True)
class SystemDefinition:
    """A discrete system, symbolically.  See the module docstring.

    Attributes
    ----------
    name, title
        Short name and one-line description.
    dofs, forces
        Names of the dofs and of their conjugate forces (same length n).
    families
        Interaction families.
    parameters
        The system's own parameters (sweepable), in order.
    load
        The load scaled by the load parameter, or ``None``.
    mass, damping
        n x n matrices (expressions), or ``None``.
    gaps
        Unilateral gaps (secondary contacts).
    domain
        Conditions ``expression > 0`` of the admissible domain.
    work_factor
        The recorded work is ``work_factor * int (F + P Q_ext) . du`` (1/2 for
        the symmetric diamond: the work per contact, seed Eq. 5).
    units
        Units and descriptions for the Dataset.
    settings
        ``(name, value)`` of the structural settings that built the system
        (``("grains", 6)``), kept for provenance.
    reference
        Where the system comes from (the Dataset's ``source``).
    """

    name: str
    title: str
    dofs: tuple[str, ...]
    forces: tuple[str, ...]
    families: tuple[InteractionFamily, ...]
    parameters: tuple[ParameterSpec, ...] = ()
    load: LoadDefinition | None = None
    mass: tuple[tuple[Any, ...], ...] | None = None
    damping: tuple[tuple[Any, ...], ...] | None = None
    gaps: tuple[GapDefinition, ...] = ()
    domain: tuple[DomainCondition, ...] = ()
    work_factor: float = 1.0
    units: SystemUnits = field(default_factory=SystemUnits)
    settings: tuple[tuple[str, Any], ...] = ()
    reference: str = ""

    def __post_init__(self) -> None:
        n = len(self.dofs)
        if n == 0 or len(self.forces) != n:
            raise ValueError(f"system {self.name!r}: give n >= 1 dofs and as many forces")
        names = list(self.dofs) + list(self.forces) + [p.name for p in self.parameters]
        if self.load is not None:
            names.append(self.load.parameter)
        duplicated = sorted({x for x in names if names.count(x) > 1})
        if duplicated:
            raise ValueError(f"system {self.name!r}: names used twice: {', '.join(duplicated)}")
        for label, matrix in (("mass", self.mass), ("damping", self.damping)):
            if matrix is not None:
                if len(matrix) != n or any(len(row) != n for row in matrix):
                    raise ValueError(f"system {self.name!r}: the {label} matrix must be {n} x {n}")
                object.__setattr__(self, label, tuple(tuple(sp.sympify(e) for e in row) for row in matrix))
        if self.load is not None and len(self.load.vector) != n:
            raise ValueError(f"system {self.name!r}: the load vector needs {n} entries")
        if not self.families:
            raise ValueError(f"system {self.name!r}: give at least one interaction family")
        allowed = set(self.dof_symbols) | {p.symbol for p in self.parameters}
        for expression, where in self._expressions():
            extra = sorted(s.name for s in sp.sympify(expression).free_symbols if s not in allowed)
            if extra:
                raise ValueError(
                    f"system {self.name!r}: {where} uses {', '.join(extra)}, which is neither a dof "
                    f"({', '.join(self.dofs)}) nor a system parameter"
                )
        if not math.isfinite(self.work_factor) or self.work_factor <= 0:
            raise ValueError(f"system {self.name!r}: work_factor must be positive")

    def _expressions(self):
        for family in self.families:
            for member, q in zip(family.members, family.variables):
                for e in q:
                    yield e, f"family {family.name!r}, member {member!r}"
            for name, values in family.member_parameters:
                for e in values:
                    yield e, f"family {family.name!r}, parameter {name!r}"
        if self.load is not None:
            for e in self.load.vector:
                yield e, "the load vector"
        for label, matrix in (("mass", self.mass), ("damping", self.damping)):
            for row in matrix or ():
                for e in row:
                    yield e, f"the {label} matrix"
        for gap in self.gaps:
            yield gap.distance, f"gap {gap.name!r}"
        for condition in self.domain:
            yield condition.expression, "the domain"

    @property
    def n_dof(self) -> int:
        return len(self.dofs)

    @property
    def dof_symbols(self) -> tuple[sp.Symbol, ...]:
        return dof_symbols(self.dofs)

    @property
    def parameter_specs(self) -> tuple[ParameterSpec, ...]:
        """The system's parameters (the name every layer uses)."""
        return self.parameters

    @property
    def load_parameter(self) -> str | None:
        return None if self.load is None else self.load.parameter

    @property
    def has_inertia(self) -> bool:
        return self.mass is not None

    def family(self, kind: str) -> InteractionFamily | None:
        """The first family of ``kind``, or ``None``."""
        return next((f for f in self.families if f.kind == kind), None)
