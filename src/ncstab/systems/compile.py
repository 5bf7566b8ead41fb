"""Numeric functions of a :class:`~ncstab.systems.SystemDefinition`, derived once.

:func:`compile_system` differentiates the system's symbolic description with
sympy (once per definition, cached) and lambdifies the results into
broadcasting numpy functions of the dofs ``u`` (shape ``(B, n)``) and the
system's parameters (each ``(B,)`` or scalar):

* per interaction family, the variables q, their Jacobian J = dq/du and
  Hessian H = d2q/du2 *on the member's own dofs* (a contact of a ring moves
  with two grains, not n): ``q (B, m, k)``, ``J (B, m, k, L)``,
  ``H (B, m, k, L, L)`` with ``L`` the largest number of dofs a member
  depends on, and the one-hot ``incidence (m L, n)`` that scatters local
  rows into the n dofs;
* the load vector Q_ext and its Jacobian, the gaps with their gradients and
  Hessians, the domain conditions, the mass and damping matrices.

sympy never runs again after this: every numeric layer calls these functions.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Callable

import numpy as np
import sympy as sp

from ncstab.symbolic.compile import lambdify_broadcast
from ncstab.systems.definition import InteractionFamily, SystemDefinition

__all__ = ["CompiledFamily", "CompiledSystem", "compile_system"]

ArrayFunction = Callable[..., np.ndarray]


def _local_dofs(expressions: list[sp.Expr], dofs: tuple[sp.Symbol, ...]) -> list[int]:
    free = set().union(*(sp.sympify(e).free_symbols for e in expressions)) if expressions else set()
    return [i for i, symbol in enumerate(dofs) if symbol in free]


@dataclass(frozen=True)
class CompiledFamily:
    """Numeric kinematics of one interaction family.

    Attributes
    ----------
    family
        The symbolic family.
    local
        ``(m, L)`` global index of each member's local dofs (padding: 0, with
        zero derivatives).
    incidence
        ``(m L, n)`` one-hot matrix: local row (member, slot) -> dof (zero rows
        for padding slots).
    function
        ``(*dofs, *parameters) -> (B, m k + m k L + m k L L)`` values of q, J, H.
    parameter_function
        ``(*parameters) -> (B, m p)`` the member parameters, or ``None``.
    """

    family: InteractionFamily
    local: np.ndarray
    incidence: np.ndarray
    function: ArrayFunction
    parameter_function: ArrayFunction | None

    @property
    def width(self) -> int:
        """L, the number of local dofs per member."""
        return self.local.shape[1]

    def kinematics(self, u: np.ndarray, parameters: tuple) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, J, H) at dofs ``u`` (B, n): ``(B, m, k)``, ``(B, m, k, L)``, ``(B, m, k, L, L)``."""
        size = u.shape[0]
        m, k, width = self.family.size, len(self.family.variable_names), self.width
        values = self.function(*u.T, *parameters)
        values = np.broadcast_to(values, (size, values.shape[-1]))
        a, b = m * k, m * k * width
        q = values[:, :a].reshape(size, m, k)
        jacobian = values[:, a : a + b].reshape(size, m, k, width)
        hessian = values[:, a + b :].reshape(size, m, k, width, width)
        return q, jacobian, hessian

    def member_parameters(self, parameters: tuple, size: int) -> dict[str, np.ndarray]:
        """Law parameters fixed per member: name -> ``(B, m)``."""
        if self.parameter_function is None:
            return {}
        m = self.family.size
        values = np.broadcast_to(self.parameter_function(*parameters), (size, m * len(self.family.member_parameters)))
        return {
            name: values[:, j * m : (j + 1) * m] for j, (name, _) in enumerate(self.family.member_parameters)
        }


def _compile_family(family: InteractionFamily, dofs: tuple[sp.Symbol, ...], parameters: list[sp.Symbol]) -> CompiledFamily:
    locals_ = [_local_dofs(list(q), dofs) for q in family.variables]
    width = max(1, max(len(x) for x in locals_))
    local = np.zeros((family.size, width), dtype=int)
    incidence = np.zeros((family.size * width, len(dofs)))
    q_entries, j_entries, h_entries = [], [], []
    for member, (q, indices) in enumerate(zip(family.variables, locals_)):
        local[member, : len(indices)] = indices
        for slot, index in enumerate(indices):
            incidence[member * width + slot, index] = 1.0
        symbols = [dofs[i] for i in indices]
        q_entries += list(q)
        for expression in q:
            gradient = [sp.diff(expression, s) for s in symbols] + [sp.Integer(0)] * (width - len(symbols))
            j_entries += gradient
            for a in range(width):
                for b in range(width):
                    if a < len(symbols) and b < len(symbols):
                        h_entries.append(sp.diff(gradient[a], symbols[b]))
                    else:
                        h_entries.append(sp.Integer(0))
    function = lambdify_broadcast(list(dofs) + parameters, q_entries + j_entries + h_entries)
    parameter_function = None
    if family.member_parameters:
        entries = [e for _, values in family.member_parameters for e in values]
        parameter_function = lambdify_broadcast(parameters, entries) if parameters else _constant(entries)
    return CompiledFamily(family, local, incidence, function, parameter_function)


def _constant(entries: list[sp.Expr]) -> ArrayFunction:
    values = np.array([float(e) for e in entries])

    def evaluate(*_: np.ndarray) -> np.ndarray:
        return values[None, :]

    return evaluate


@dataclass(frozen=True)
class CompiledSystem:
    """Numeric functions of one system definition (see :func:`compile_system`)."""

    definition: SystemDefinition
    families: tuple[CompiledFamily, ...]
    load_function: ArrayFunction | None
    gap_function: ArrayFunction | None
    gap_derivatives_function: ArrayFunction | None
    domain_function: ArrayFunction | None
    mass_function: ArrayFunction | None
    damping_function: ArrayFunction | None

    @property
    def n(self) -> int:
        return self.definition.n_dof

    def _call(self, function: ArrayFunction, u: np.ndarray, parameters: tuple) -> np.ndarray:
        values = function(*u.T, *parameters)
        return np.broadcast_to(values, (u.shape[0], values.shape[-1]))

    def load(self, u: np.ndarray, parameters: tuple) -> tuple[np.ndarray, np.ndarray]:
        """(Q_ext ``(B, n)``, dQ_ext/du ``(B, n, n)``): the load per unit of the load parameter."""
        n, size = self.n, u.shape[0]
        if self.load_function is None:
            return np.zeros((size, n)), np.zeros((size, n, n))
        values = self._call(self.load_function, u, parameters)
        return values[:, :n], values[:, n:].reshape(size, n, n)

    def gaps(self, u: np.ndarray, parameters: tuple, derivatives: bool = True) -> tuple[np.ndarray, ...]:
        """(g ``(B, G)``, dg/du ``(B, G, n)``, d2g/du2 ``(B, G, n, n)``) of the gaps."""
        n, size, count = self.n, u.shape[0], len(self.definition.gaps)
        if self.gap_function is None:
            empty = (np.zeros((size, 0)), np.zeros((size, 0, n)), np.zeros((size, 0, n, n)))
            return empty if derivatives else empty[:1]
        g = self._call(self.gap_function, u, parameters)
        if not derivatives:
            return (g,)
        values = self._call(self.gap_derivatives_function, u, parameters)
        gradient = values[:, : count * n].reshape(size, count, n)
        hessian = values[:, count * n :].reshape(size, count, n, n)
        return g, gradient, hessian

    def domain(self, u: np.ndarray, parameters: tuple) -> np.ndarray:
        """Domain conditions ``(B, D)``: the model is defined where every one is > 0."""
        if self.domain_function is None:
            return np.ones((u.shape[0], 0))
        return self._call(self.domain_function, u, parameters)

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


@functools.lru_cache(maxsize=None)
def compile_system(definition: SystemDefinition) -> CompiledSystem:
    """Derive (sympy, once) and lambdify (once) the numeric functions of a system."""
    dofs = definition.dof_symbols
    parameters = [p.symbol for p in definition.parameters]
    arguments = list(dofs) + parameters
    families = tuple(_compile_family(f, dofs, parameters) for f in definition.families)
    load_function = None
    if definition.load is not None:
        vector = sp.Matrix(definition.load.vector)
        load_function = lambdify_broadcast(arguments, list(vector) + list(vector.jacobian(sp.Matrix(dofs))))
    gap_function = gap_derivatives_function = None
    if definition.gaps:
        entries = [g.distance for g in definition.gaps]
        gradients = [sp.diff(g.distance, u) for g in definition.gaps for u in dofs]
        hessians = [sp.diff(g.distance, u, v) for g in definition.gaps for u in dofs for v in dofs]
        gap_function = lambdify_broadcast(arguments, entries)
        gap_derivatives_function = lambdify_broadcast(arguments, gradients + hessians)
    domain_function = (
        lambdify_broadcast(arguments, [c.expression for c in definition.domain]) if definition.domain else None
    )
    mass_function = (
        lambdify_broadcast(arguments, [e for row in definition.mass for e in row]) if definition.mass else None
    )
    damping_function = (
        lambdify_broadcast(arguments, [e for row in definition.damping for e in row]) if definition.damping else None
    )
    return CompiledSystem(
        definition, families, load_function, gap_function, gap_derivatives_function, domain_function,
        mass_function, damping_function,
    )
