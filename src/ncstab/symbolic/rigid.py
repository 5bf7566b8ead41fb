"""The pure-shear limit of a law: rigid normal contact (k_n -> infinity).

Seed Eq. (60)-(68).  With k_n -> infinity the normal overlap vanishes,
delta(l, alpha) = 0, which fixes the branch length l = lbar(alpha) (1 for the
rotational laws, cos(alpha - alpha0) for Turco et al., Eq. 63), and the normal
force becomes a reaction.  Forces are normalised by 2R k_t (Eq. 62): with
N* = delta (units 2R k_n) the reaction is Nhat = N*/gamma = delta/gamma, so the
tangential force in the new units is

    That(alpha, Nhat) = lim_{gamma -> 0} T*(lbar, alpha; delta = gamma Nhat) / gamma,

computed symbolically from the law's own expressions (nothing is declared).
For a rate law dT* = c_l dl + c_a dalpha the limit rate along the constraint is
dThat/dalpha = lim (c_l lbar' + c_a) / gamma.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ncstab.laws.definition import ALPHA, ALPHA0, DELTA, GAMMA, L, LawDefinition
from ncstab.symbolic.compile import lambdify_broadcast

__all__ = ["NHAT", "RigidLimit", "rigid_limit"]

#: Normal reaction in units of 2R k_t (the multiplier of the rigid normal constraint).
NHAT = sp.Symbol("Nhat", real=True)


@dataclass(frozen=True)
class RigidLimit:
    """Symbolic and compiled pure-shear limit of one law.

    Attributes
    ----------
    length
        lbar(alpha): the branch length imposed by delta = 0.
    tangential
        That(alpha, Nhat) for a law with a total form, else ``None``.
    tangential_rate
        dThat/dalpha along the constraint for a rate law, else ``None``.
    """

    definition: LawDefinition
    length: sp.Expr
    tangential: sp.Expr | None
    tangential_rate: sp.Expr | None

    @functools.cached_property
    def _length_functions(self):
        return lambdify_broadcast([ALPHA, ALPHA0], [self.length, sp.diff(self.length, ALPHA)])

    @functools.cached_property
    def _tangential_functions(self):
        if self.tangential is not None:
            return lambdify_broadcast(
                [ALPHA, NHAT, ALPHA0],
                [self.tangential, sp.diff(self.tangential, ALPHA), sp.diff(self.tangential, NHAT)],
            )
        assert self.tangential_rate is not None
        return lambdify_broadcast([ALPHA, NHAT, ALPHA0], [self.tangential_rate])

    def branch_length(self, alpha: np.ndarray, alpha0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lbar, dlbar/dalpha) at alpha."""
        values = self._length_functions(alpha, alpha0)
        return values[..., 0], values[..., 1]

    def tangential_force(
        self, alpha: np.ndarray, reaction: np.ndarray, alpha0: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(That, dThat/dalpha, dThat/dNhat) for a law with a total form."""
        values = self._tangential_functions(alpha, reaction, alpha0)
        return values[..., 0], values[..., 1], values[..., 2]

    def tangential_rate_along(self, alpha: np.ndarray, alpha0: np.ndarray) -> np.ndarray:
        """dThat/dalpha along the constraint for a rate law."""
        return self._tangential_functions(alpha, np.zeros_like(alpha), alpha0)[..., 0]


@functools.lru_cache(maxsize=None)
def rigid_limit(definition: LawDefinition) -> RigidLimit:
    """Derive the pure-shear limit of a law (seed Eq. 60-65).

    Raises
    ------
    ValueError
        For a law with the no-tension modifier (a rigid normal contact cannot
        open in this limit), or when delta = 0 has no positive root in l.
    """
    if definition.no_tension:
        raise ValueError(
            f"law {definition.name!r}: the no_tension modifier has no meaning with a rigid normal "
            "(normal = 'rigid'); use the law without it"
        )
    roots = [r for r in sp.solve(sp.Eq(definition.normal_overlap, 0), L) if r != 0]
    if len(roots) != 1:
        raise ValueError(f"law {definition.name!r}: cannot solve delta(l, alpha) = 0 for l uniquely: {roots}")
    length = sp.simplify(roots[0])
    if definition.tangential_force is not None:
        scaled = sp.expand(definition.tangential_force.subs(DELTA, GAMMA * NHAT) / GAMMA)
        tangential = sp.simplify(sp.limit(scaled, GAMMA, 0).subs(L, length))
        return RigidLimit(definition, length, tangential, None)
    assert definition.tangential_rate is not None
    c_l, c_alpha = (sp.sympify(c) for c in definition.tangential_rate)
    along = sp.expand((c_l * sp.diff(length, ALPHA) + c_alpha).subs(L, length) / GAMMA)
    rate = sp.simplify(sp.limit(along, GAMMA, 0))
    return RigidLimit(definition, length, None, rate)
