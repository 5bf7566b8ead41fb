"""Discrete systems (layer ``systems/``): a system as a value, and the systems ncstab ships.

* :class:`SystemDefinition` -- any discrete system, symbolically (dofs,
  interaction families, load, inertia, gaps, domain), derived once by
  :func:`compile_system`;
* :data:`SYSTEMS` -- the shipped systems by name (diamond, ring, column,
  ziegler), :func:`system_definition` to build one;
* :class:`DiamondChain` -- the seed's reduced diamond in numpy (the fused
  fast path of the engine), with its closed forms in
  :mod:`ncstab.systems.closed_forms`.
"""

from ncstab.systems.compile import CompiledSystem, compile_system
from ncstab.systems.definition import (
    DomainCondition,
    GapDefinition,
    InteractionFamily,
    LoadDefinition,
    SystemDefinition,
    SystemUnits,
    dof_symbols,
)
from ncstab.systems.diamond import DiamondChain
from ncstab.systems.protocol import DiscreteSystem, conjugate_forces
from ncstab.systems.registry import SYSTEMS, SystemKind, system_definition

__all__ = [
    "SYSTEMS",
    "CompiledSystem",
    "DiamondChain",
    "DiscreteSystem",
    "DomainCondition",
    "GapDefinition",
    "InteractionFamily",
    "LoadDefinition",
    "SystemDefinition",
    "SystemKind",
    "SystemUnits",
    "compile_system",
    "conjugate_forces",
    "dof_symbols",
    "system_definition",
]
