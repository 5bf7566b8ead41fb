"""Discrete systems (layer ``systems/``): kinematics, equilibrium, contact geometry."""

from ncstab.systems.diamond import DiamondChain
from ncstab.systems.protocol import DiscreteSystem, conjugate_forces

#: Every system ncstab knows, by name.
SYSTEMS = {"diamond": DiamondChain}

__all__ = ["SYSTEMS", "DiamondChain", "DiscreteSystem", "conjugate_forces"]
