"""A law's response for arrays of members: forces, Q, D = dQ/dq and rates, derived once per law.

For any law of the interaction protocol (:mod:`ncstab.laws`: a contact law,
q = (l, alpha), stored forces (N, T), conjugates Q = (-N, l T), seed Eq. 9,
16; a rotational spring, q = theta, force and conjugate M), sympy derives once
per law (:func:`ncstab.symbolic.interaction.derive_interaction`) the total
forms, the conjugate tangent D along the law (seed Eq. 30-34 for a contact)
and the rate rows C of the forces that are internal variables (df = C dq,
Cundall-Strack's dT = gamma l dalpha, seed Eq. 13), and lambdifies them into
numpy functions of ``(q, f, parameters)`` that broadcast over members.  A
solver calls these functions only: sympy never runs in its loop.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Callable

import numpy as np
import sympy as sp

from ncstab.symbolic.compile import lambdify_broadcast
from ncstab.symbolic.interaction import derive_interaction

__all__ = ["LawResponse", "law_response"]


@dataclass(frozen=True, eq=False)
class LawResponse:
    """Numeric response of one law over arrays of members (see :func:`law_response`).

    Attributes
    ----------
    law
        The law.
    k, forces
        Number of interaction variables; number of stored forces.
    internal
        Indices of the stored forces that are internal variables (no total form).
    parameter_names
        The law's parameters, in the order the functions take them.
    """

    law: Any
    k: int
    forces: int
    internal: tuple[int, ...]
    parameter_names: tuple[str, ...]
    _totals: Callable[..., np.ndarray]
    _conjugates: Callable[..., np.ndarray]
    _tangent: Callable[..., np.ndarray]
    _rates: Callable[..., np.ndarray]

    def _arguments(self, q: np.ndarray, f: np.ndarray, parameters: dict[str, Any]) -> list[np.ndarray]:
        missing = [p for p in self.parameter_names if p not in parameters]
        if missing:
            raise ValueError(f"law {self.law.name!r} needs parameter(s) {', '.join(missing)}")
        return [*q.T, *f.T, *(np.asarray(parameters[p], dtype=float) for p in self.parameter_names)]

    def stored_forces(self, q: np.ndarray, internal: np.ndarray, parameters: dict[str, Any]) -> np.ndarray:
        """The stored forces ``(m, forces)``: total forms, and ``internal`` where there is none.

        ``internal`` is ``(m, forces)``; its columns of forces with a total form are ignored.
        """
        values = self._totals(*self._arguments(q, internal, parameters))
        values = np.broadcast_to(values, (q.shape[0], self.forces)).copy()
        for i in self.internal:
            values[:, i] = internal[:, i]
        return values

    def response(self, q: np.ndarray, f: np.ndarray, parameters: dict[str, Any]):
        """Q ``(m, k)``, D = dQ/dq along the law ``(m, k, k)`` and the rate rows C ``(m, forces, k)``.

        ``f`` are the stored forces (:meth:`stored_forces`).
        """
        arguments = self._arguments(q, f, parameters)
        m = q.shape[0]
        Q = np.broadcast_to(self._conjugates(*arguments), (m, self.k))
        D = np.broadcast_to(self._tangent(*arguments), (m, self.k * self.k)).reshape(m, self.k, self.k)
        C = np.broadcast_to(self._rates(*arguments), (m, self.forces * self.k)).reshape(m, self.forces, self.k)
        return Q, D, C


@functools.lru_cache(maxsize=None)
def law_response(law: Any) -> LawResponse:
    """The numeric response of ``law`` (derived and lambdified once per law and process)."""
    derivation = derive_interaction(law)
    variables = list(law.variables)
    forces = list(law.force_symbols)
    parameters = list(law.parameter_symbols)
    arguments = variables + forces + parameters
    substitutions = {f: t for f, t in zip(forces, derivation.totals) if t is not None}
    totals = [f if t is None else t for f, t in zip(forces, derivation.totals)]
    conjugates = [sp.sympify(e).subs(substitutions) for e in law.conjugate_expressions]
    tangent = [sp.sympify(e).subs(substitutions) for e in derivation.conjugate_tangent]
    rates = [sp.sympify(e).subs(substitutions) for e in derivation.rate_matrix]
    internal = tuple(i for i, t in enumerate(derivation.totals) if t is None)
    return LawResponse(
        law=law,
        k=len(variables),
        forces=len(forces),
        internal=internal,
        parameter_names=tuple(p.name for p in law.parameters),
        _totals=lambdify_broadcast(arguments, totals),
        _conjugates=lambdify_broadcast(arguments, conjugates),
        _tangent=lambdify_broadcast(arguments, tangent),
        _rates=lambdify_broadcast(arguments, rates),
    )
