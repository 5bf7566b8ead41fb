"""Compile derived law expressions into broadcasting numpy functions.

``compile_law`` runs sympy once per law definition (cached); the functions it
returns are plain numpy and are what every numeric layer calls.  Argument order
is always ``(l, alpha, [N, T,] *parameters)`` with parameters in the order of
``definition.parameters``.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ncstab.laws.definition import ALPHA, L, LawDefinition, N, T
from ncstab.laws.registry import Law
from ncstab.symbolic.derivation import derive_law

__all__ = ["CompiledLaw", "compile_law", "lambdify_broadcast"]

ArrayFunction = Callable[..., np.ndarray]


def lambdify_broadcast(arguments: Sequence[sp.Symbol], expressions: Sequence[sp.Expr]) -> ArrayFunction:
    """Lambdify expressions into one function returning a stacked array.

    The result has shape ``broadcast(*arguments) + (len(expressions),)``: a
    constant entry (``dN/dl = -1``) is broadcast like the others.  Dirac deltas
    (second derivatives of Macaulay brackets) are dropped: they vanish off the
    kink and the kink itself has measure zero on any path.
    """
    cleaned = [
        sp.sympify(e).replace(sp.DiracDelta, lambda *args: sp.Integer(0)) for e in expressions
    ]
    raw = sp.lambdify(list(arguments), cleaned, modules="numpy", cse=True)

    count = len(cleaned)

    def evaluate(*values: np.ndarray) -> np.ndarray:
        arrays = [np.asarray(v, dtype=float) for v in values]
        shape = np.broadcast_shapes(*(a.shape for a in arrays))
        out = np.empty(shape + (count,))
        for k, value in enumerate(raw(*arrays)):  # a constant entry broadcasts in the assignment
            out[..., k] = value
        return out

    return evaluate


@dataclass(frozen=True)
class CompiledLaw:
    """Numeric functions of one law definition, compiled once.

    Attributes
    ----------
    definition
        The source definition.
    normal
        ``(l, alpha, *params) -> N`` (shape of the broadcast inputs).
    tangential
        ``(l, alpha, *params) -> T``, or ``None`` for a strongly hypoelastic law.
    rate_matrix_function
        ``(l, alpha, N, T, *params) -> C`` of shape ``(..., 2, 2)`` with
        [dN, dT] = C [dl, dalpha].
    energy_function
        ``(l, alpha, *params) -> W``, or ``None``.
    overlap_function
        ``(l, alpha, *params) -> delta``, the normal overlap.
    """

    definition: LawDefinition
    normal_function: ArrayFunction
    tangential_function: ArrayFunction | None
    rate_matrix_function: ArrayFunction
    energy_function: ArrayFunction | None
    overlap_function: ArrayFunction | None = None

    # Convenience wrappers taking a validated Law for its parameter values.
    def normal_force(self, law: Law, l: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """N(l, alpha), seed Eq. (14)/(18)/(27)/(28)."""
        return self.normal_function(l, alpha, *law.parameter_values())[..., 0]

    def tangential_force(self, law: Law, l: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """T(l, alpha) in total form; raises for a law without one."""
        if self.tangential_function is None:
            raise ValueError(
                f"law {law.name!r} has no total tangential force: T is an internal "
                "variable, integrate its rate along a path"
            )
        return self.tangential_function(l, alpha, *law.parameter_values())[..., 0]

    def rate_matrix(
        self, law: Law, l: np.ndarray, alpha: np.ndarray, normal: np.ndarray, tangential: np.ndarray
    ) -> np.ndarray:
        """C with [dN, dT] = C [dl, dalpha], shape ``(..., 2, 2)``."""
        flat = self.rate_matrix_function(l, alpha, normal, tangential, *law.parameter_values())
        return flat.reshape(flat.shape[:-1] + (2, 2))

    def normal_overlap(self, law: Law, l: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """The normal overlap delta(l, alpha) (before any Macaulay bracket)."""
        assert self.overlap_function is not None
        return self.overlap_function(l, alpha, *law.parameter_values())[..., 0]

    def energy(self, law: Law, l: np.ndarray, alpha: np.ndarray) -> np.ndarray:
        """Stored energy per contact W(l, alpha) in units of k_n (2R)^2."""
        if self.energy_function is None:
            raise ValueError(f"law {law.name!r} derives from no potential: it has no energy")
        return self.energy_function(l, alpha, *law.parameter_values())[..., 0]


@functools.cache
def compile_law(definition: LawDefinition) -> CompiledLaw:
    """Derive (sympy, once) and lambdify (once) the numeric forms of a law."""
    derivation = derive_law(definition)
    params = list(definition.parameter_symbols)
    contact = [L, ALPHA]
    normal = lambdify_broadcast(contact + params, [derivation.normal])
    tangential = (
        lambdify_broadcast(contact + params, [derivation.tangential])
        if derivation.tangential is not None
        else None
    )
    rate = lambdify_broadcast(contact + [N, T] + params, list(derivation.rate_matrix))
    energy = (
        lambdify_broadcast(contact + params, [derivation.energy])
        if derivation.energy is not None
        and derivation.rate_integrability.holds
        and derivation.hyperelasticity.holds
        else None
    )
    overlap = lambdify_broadcast(contact + params, [definition.normal_overlap])
    return CompiledLaw(definition, normal, tangential, rate, energy, overlap)
