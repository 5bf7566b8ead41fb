"""Numeric functions of a :class:`~ncstab.systems.SystemDefinition` besides its kernel, derived once.

The forces, tangent operator, internal rates, loads, gaps and domain of a model are
its compiled kernel's (:mod:`ncstab.operators.model_kernel`, one per system and
laws).  :func:`compile_system` lambdifies the rest of the system's symbolic
description (once per definition, cached) into broadcasting numpy functions
of the dofs ``u`` (shape ``(B, n)``) and the system's parameters (each
``(B,)`` or scalar): the mass and damping matrices.
"""

from __future__ import annotations

import functools
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ncstab.symbolic.compile import lambdify_broadcast
from ncstab.systems.definition import SystemDefinition

__all__ = ["CompiledSystem", "compile_system"]

ArrayFunction = Callable[..., np.ndarray]


@dataclass(frozen=True)
class CompiledSystem:
    """Numeric functions of one system definition (see :func:`compile_system`)."""

    definition: SystemDefinition
    mass_function: ArrayFunction | None
    damping_function: ArrayFunction | None

    @property
    def n(self) -> int:
        return self.definition.n_dof

    def _call(self, function: ArrayFunction, u: np.ndarray, parameters: tuple) -> np.ndarray:
        values = function(*u.T, *parameters)
        return np.broadcast_to(values, (u.shape[0], values.shape[-1]))

    def mass(self, u: np.ndarray, parameters: tuple) -> np.ndarray | None:
        """M(u) ``(B, n, n)``, or ``None`` for a system without inertia."""
        if self.mass_function is None:
            return None
        return self._call(self.mass_function, u, parameters).reshape(u.shape[0], self.n, self.n)

    def damping(self, u: np.ndarray, parameters: tuple) -> np.ndarray | None:
        """C ``(B, n, n)``, or ``None``."""
        if self.damping_function is None:
            return None
        return self._call(self.damping_function, u, parameters).reshape(u.shape[0], self.n, self.n)


@functools.cache
def compile_system(definition: SystemDefinition) -> CompiledSystem:
    """Lambdify (once) the mass and damping functions of a system (its domain conditions
    are printed into its compiled model kernel, :mod:`ncstab.operators.model_kernel`)."""
    dofs = definition.dof_symbols
    parameters = [p.symbol for p in definition.parameters]
    arguments = list(dofs) + parameters
    mass_function = (
        lambdify_broadcast(arguments, [e for row in definition.mass for e in row]) if definition.mass else None
    )
    damping_function = (
        lambdify_broadcast(arguments, [e for row in definition.damping for e in row]) if definition.damping else None
    )
    return CompiledSystem(definition, mass_function, damping_function)
