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

from __future__ import annotations

from ncstab.lazy_imports import lazy_attributes

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

#: Imported on first use, so that a submodule without sympy (the closed forms, which
#: ``ncstab plot`` draws) does not import the symbolic layer with its package.
__getattr__, __dir__ = lazy_attributes(
    __name__,
    {
        "CompiledSystem": "ncstab.systems.compile",
        "compile_system": "ncstab.systems.compile",
        **{
            name: "ncstab.systems.definition"
            for name in (
                "DomainCondition", "GapDefinition", "InteractionFamily", "LoadDefinition",
                "SystemDefinition", "SystemUnits", "dof_symbols",
            )
        },
        "DiamondChain": "ncstab.systems.diamond",
        "DiscreteSystem": "ncstab.systems.protocol",
        "conjugate_forces": "ncstab.systems.protocol",
        "SYSTEMS": "ncstab.systems.registry",
        "SystemKind": "ncstab.systems.registry",
        "system_definition": "ncstab.systems.registry",
    },
    globals(),
)
