"""Rotational springs: one relative angle -> one moment (bars, columns, pendulums).

A spring law is the one-variable case of an interaction law (docs/models.md): its interaction variable is a relative rotation ``theta`` and
its conjugate force the moment ``M`` (``dW_int = M dtheta``).  Moments are in
units of the spring's stiffness (k, or C for Hencky's column), angles in
radians.  Like a contact law it may be given in total form ``M(theta)``, in
rate form ``dM = c(theta, M) dtheta``, or from an energy ``W(theta)``; its
class is computed by :mod:`ncstab.symbolic`, never declared.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

import sympy as sp

from ncstab.laws.definition import ParameterSpec

__all__ = ["MOMENT", "THETA", "LINEAR_SPRING", "SpringLaw"]

#: Relative rotation across a rotational spring (rad).
THETA = sp.Symbol("theta", real=True)
#: Moment of the spring, in units of its stiffness (k or C).
MOMENT = sp.Symbol("M", real=True)


@dataclass(frozen=True)
class SpringLaw:
    """Symbolic description of a rotational spring law.

    Parameters
    ----------
    name
        Registry name (``"linear_spring"``).
    title
        Short human name.
    equations
        What it implements, for the catalogue.
    moment
        M(theta) in total form, or ``None`` for a rate law.
    moment_rate
        c(theta, M) with dM = c dtheta, required when ``moment`` is ``None``.
    energy
        Declared stored energy W(theta) (units of the stiffness times rad^2),
        checked against the moment (dW/dtheta = M), never trusted.
    parameters
        Parameter specifications, in order.
    """

    #: The family of interactions this law fits (see :class:`ncstab.systems.InteractionFamily`).
    kind: ClassVar[str] = "spring"

    name: str
    title: str
    equations: str
    moment: sp.Expr | None = None
    moment_rate: sp.Expr | None = None
    energy: sp.Expr | None = None
    parameters: tuple[ParameterSpec, ...] = ()

    def __post_init__(self) -> None:
        if (self.moment is None) == (self.moment_rate is None):
            raise ValueError(f"spring law {self.name!r}: give exactly one of moment and moment_rate")

    @property
    def no_tension(self) -> bool:
        """Springs have no unilateral modifier."""
        return False

    @property
    def has_total_form(self) -> bool:
        return self.moment is not None

    @property
    def internal_variables(self) -> tuple[str, ...]:
        """``("M",)`` for a rate law: the moment travels with the state."""
        return () if self.has_total_form else ("M",)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        return tuple(p.name for p in self.parameters)

    @property
    def parameter_symbols(self) -> tuple[sp.Symbol, ...]:
        return tuple(p.symbol for p in self.parameters)

    # --- the interaction-law protocol (k variables -> conjugate forces) ---------------
    @property
    def variables(self) -> tuple[sp.Symbol, ...]:
        """The interaction variables q: ``(theta,)``."""
        return (THETA,)

    @property
    def force_symbols(self) -> tuple[sp.Symbol, ...]:
        """The stored forces: ``(M,)``."""
        return (MOMENT,)

    @property
    def conjugate_expressions(self) -> tuple[sp.Expr, ...]:
        """Work-conjugates Q of q in dW_int = Q . dq: the moment itself."""
        return (MOMENT,)

    @property
    def force_totals(self) -> tuple[sp.Expr | None, ...]:
        """M(theta), or ``None`` for a rate law."""
        return (self.moment,)

    @property
    def force_rates(self) -> tuple[tuple[sp.Expr, ...] | None, ...]:
        """Per force without a total form, its rate row: dM = c dtheta -> ``((c,),)``."""
        if self.moment is not None:
            return (None,)
        return ((sp.sympify(self.moment_rate),),)


#: A linear rotational spring of unit stiffness: M = theta, W = theta^2 / 2 (units k).
LINEAR_SPRING = SpringLaw(
    name="linear_spring",
    title="linear rotational spring",
    equations="M = k theta",
    moment=THETA,
    energy=THETA**2 / 2,
)
