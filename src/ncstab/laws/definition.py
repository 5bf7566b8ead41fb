"""What a contact interaction law is: symbolic forms and parameter specifications.

A law is described once, with sympy expressions in the dimensionless contact
variables of the seed (Eq. 37): the branch length ``l`` (l* = l / 2R) and the
branch orientation ``alpha`` (from the vertical axis), the normal force ``N`` and
the tangential force ``T`` (both in units of 2R k_n).

The normal part of every law is written through the *normal overlap* ``delta``
(the compression of the normal spring, so that N = delta for the four seed laws);
the ``no_tension`` modifier (seed Eq. 59) replaces ``delta`` by its Macaulay
bracket wherever it appears, in the forces and in the energy alike.

Nothing here is derived or classified: that is the job of :mod:`ncstab.symbolic`,
which works on these definitions and never on a declared class.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import ClassVar

import numpy as np
import sympy as sp

__all__ = [
    "L",
    "ALPHA",
    "N",
    "T",
    "DELTA",
    "GAMMA",
    "ALPHA0",
    "ParameterSpec",
    "LawDefinition",
]

#: Dimensionless branch length l* = l / (2R).
L = sp.Symbol("l", positive=True)
#: Branch orientation alpha from the vertical axis (rad).
ALPHA = sp.Symbol("alpha", real=True)
#: Normal contact force N* = N / (2R k_n) (positive in compression).
N = sp.Symbol("N", real=True)
#: Tangential contact force T* = T / (2R k_n).
T = sp.Symbol("T", real=True)
#: Normal overlap (compression of the normal spring); placeholder substituted on use.
DELTA = sp.Symbol("delta", real=True)
#: Stiffness ratio gamma = k_t / k_n.
GAMMA = sp.Symbol("gamma", nonnegative=True)
#: Initial (reference) orientation alpha_0 of the branch (rad).
ALPHA0 = sp.Symbol("alpha0", real=True)


@dataclass(frozen=True)
class ParameterSpec:
    """A named, bounded, dimensionless parameter.

    Parameters
    ----------
    name
        Name used in code, study files and datasets (``"gamma"``).
    symbol
        The sympy symbol that stands for it in law expressions.
    description
        One line for error messages and dataset attributes.
    lower, upper
        Bounds of the admissible interval (``-inf``/``inf`` for none).
    lower_inclusive, upper_inclusive
        Whether the bound itself is admissible.
    units
        CF units string (``"1"`` or ``"rad"``).
    """

    name: str
    symbol: sp.Symbol
    description: str
    lower: float = -math.inf
    upper: float = math.inf
    lower_inclusive: bool = True
    upper_inclusive: bool = True
    units: str = "1"
    default: float | None = None

    @property
    def allowed(self) -> str:
        """Human-readable admissible range, e.g. ``"finite and >= 0"``."""
        low_open = "[" if self.lower_inclusive else "("
        high_open = "]" if self.upper_inclusive else ")"
        if math.isinf(self.lower) and math.isinf(self.upper):
            return "finite"
        if math.isinf(self.upper):
            return f"finite and {'>=' if self.lower_inclusive else '>'} {self.lower:g}"
        if math.isinf(self.lower):
            return f"finite and {'<=' if self.upper_inclusive else '<'} {self.upper:g}"
        high = "pi/2" if math.isclose(self.upper, math.pi / 2) else f"{self.upper:g}"
        return f"in {low_open}{self.lower:g}, {high}{high_open}"

    def validate(self, value: object) -> np.ndarray:
        """Return ``value`` as a float array, or raise naming the parameter.

        Raises
        ------
        ValueError
            If any element is non-finite or outside the admissible interval; the
            message names the parameter, the offending value and the allowed range.
        """
        try:
            array = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(
                f"parameter {self.name!r} ({self.description}) must be a number, "
                f"got {value!r}; allowed: {self.allowed}"
            ) from None
        bad = ~np.isfinite(array)
        if self.lower_inclusive:
            bad |= array < self.lower
        else:
            bad |= array <= self.lower
        if self.upper_inclusive:
            bad |= array > self.upper
        else:
            bad |= array >= self.upper
        if np.any(bad):
            offending = array[bad].ravel()
            count = offending.size
            shown = ", ".join(f"{v:g}" for v in offending[:3])
            more = f" (and {count - 3} more)" if count > 3 else ""
            raise ValueError(
                f"parameter {self.name!r} ({self.description}) = {shown}{more} is not "
                f"allowed: it must be {self.allowed}"
            )
        return array


GAMMA_SPEC = ParameterSpec(
    "gamma",
    GAMMA,
    "stiffness ratio k_t/k_n",
    lower=0.0,
    lower_inclusive=True,
)
ALPHA0_SPEC = ParameterSpec(
    "alpha0",
    ALPHA0,
    "initial branch orientation from the vertical axis, rad",
    lower=0.0,
    upper=math.pi / 2,
    lower_inclusive=False,
    upper_inclusive=False,
    units="rad",
    default=math.pi / 4,
)


@dataclass(frozen=True)
class LawDefinition:
    """Symbolic description of a planar contact interaction law.

    All expressions are dimensionless (seed Eq. 37) and may use the symbols
    :data:`L`, :data:`ALPHA`, :data:`DELTA` and the parameter symbols; rate
    coefficients may also use the current forces :data:`N` and :data:`T`.

    Parameters
    ----------
    name
        Registry name (``"mcnamara"``).
    title
        Short human name with its reference.
    equations
        Seed equations the law implements, e.g. ``"Eq. (18)-(20)"``.
    normal_overlap
        delta(l, alpha): the compression of the normal spring (1 - l for the
        rotational laws, cos(alpha - alpha0) - l for Turco et al.).
    normal_force
        N as an expression of ``delta`` (and possibly l, alpha).
    tangential_force
        T as an expression (total form), or ``None`` when only a rate form exists.
    tangential_rate
        ``(c_l, c_alpha)`` with dT = c_l dl + c_alpha dalpha, required when
        ``tangential_force`` is ``None``; coefficients may depend on N, T.
    energy
        Declared stored energy W(l, alpha) per contact in units of k_n (2R)^2, or
        ``None``.  It is *checked* against the forces, never trusted.
    parameters
        Parameter specifications, in order.
    internal_variables
        Names of the forces that are internal variables (no total form), e.g.
        ``("T",)`` for Cundall--Strack.
    no_tension
        Whether the Macaulay bracket of seed Eq. (59) is applied to ``delta``.
    """

    #: The family of interactions this law fits (see :class:`ncstab.systems.InteractionFamily`).
    kind: ClassVar[str] = "contact"

    name: str
    title: str
    equations: str
    normal_overlap: sp.Expr
    normal_force: sp.Expr
    tangential_force: sp.Expr | None = None
    tangential_rate: tuple[sp.Expr, sp.Expr] | None = None
    energy: sp.Expr | None = None
    parameters: tuple[ParameterSpec, ...] = field(default=(GAMMA_SPEC, ALPHA0_SPEC))
    internal_variables: tuple[str, ...] = ()
    no_tension: bool = False

    def __post_init__(self) -> None:
        if self.tangential_force is None and self.tangential_rate is None:
            raise ValueError(
                f"law {self.name!r}: give a total tangential force or a tangential rate"
            )

    # --- expressions with the normal overlap substituted -------------------------
    @property
    def effective_overlap(self) -> sp.Expr:
        """delta, or its Macaulay bracket <delta> with no tension (seed Eq. 59).

        The bracket is written as a Piecewise that is *closed* at delta = 0, so
        a contact that touches without overlap (the unloaded state) has the
        stiffness of a closed contact: its derivative is 1, not 1/2.
        """
        if self.no_tension:
            return sp.Piecewise((self.normal_overlap, self.normal_overlap >= 0), (0, True))
        return self.normal_overlap

    def _substitute(self, expr: sp.Expr) -> sp.Expr:
        return sp.sympify(expr).subs(DELTA, self.effective_overlap)

    @property
    def normal_total(self) -> sp.Expr:
        """N(l, alpha) in total form (all seed laws have one, Eq. 14)."""
        return self._substitute(self.normal_force)

    @property
    def tangential_total(self) -> sp.Expr | None:
        """T(l, alpha) in total form, or ``None`` (strongly hypoelastic candidates)."""
        if self.tangential_force is None:
            return None
        return self._substitute(self.tangential_force)

    @property
    def energy_total(self) -> sp.Expr | None:
        """Declared energy W(l, alpha) with delta substituted, or ``None``."""
        if self.energy is None:
            return None
        return self._substitute(self.energy)

    @property
    def has_total_form(self) -> bool:
        """Whether both contact forces are given as functions of (l, alpha)."""
        return self.tangential_force is not None

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def parameter_symbols(self) -> tuple[sp.Symbol, ...]:
        return tuple(p.symbol for p in self.parameters)

    # --- the interaction-law protocol (k variables -> conjugate forces) ---------------
    @property
    def variables(self) -> tuple[sp.Symbol, ...]:
        """The interaction variables q of a contact: ``(l, alpha)``."""
        return (L, ALPHA)

    @property
    def force_symbols(self) -> tuple[sp.Symbol, ...]:
        """The stored contact forces: ``(N, T)``."""
        return (N, T)

    @property
    def conjugate_expressions(self) -> tuple[sp.Expr, ...]:
        """Work-conjugates Q of q in dW_int = Q . dq: ``(-N, l T)`` (seed Eq. 9, 16)."""
        return (-N, L * T)

    @property
    def force_totals(self) -> tuple[sp.Expr | None, ...]:
        """(N(l, alpha), T(l, alpha)); T is ``None`` for a law given in rate form."""
        return (self.normal_total, self.tangential_total)

    @property
    def force_rates(self) -> tuple[tuple[sp.Expr, ...] | None, ...]:
        """Per force without a total form, its rate row (dT = c_l dl + c_alpha dalpha)."""
        if self.tangential_force is not None:
            return (None, None)
        assert self.tangential_rate is not None
        return (None, tuple(sp.sympify(c) for c in self.tangential_rate))
