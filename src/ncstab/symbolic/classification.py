"""Classify a contact law as hyperelastic, weakly or strongly hypoelastic.

The class is computed from the law's expressions by the conditions of the seed,
never declared:

1. If the rate form is not integrable (Frobenius condition; for the
   Cundall--Strack law it fails because du_t = l dalpha is not exact, seed
   Eq. 8), there is no total form: **strongly hypoelastic**.
2. Otherwise forces have a total form.  If -dN/dalpha = d(l T)/dl (seed
   Eq. 17) the law derives from a potential: **hyperelastic** (Green-elastic).
3. Otherwise: **weakly hypoelastic** (Cauchy-elastic, total forces but no
   potential; seed Eq. 25-27).
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

from ncstab.laws.definition import LawDefinition
from ncstab.symbolic.derivation import ConditionCheck
from ncstab.symbolic.interaction import derive_interaction

__all__ = ["HYPERELASTIC", "WEAKLY_HYPOELASTIC", "STRONGLY_HYPOELASTIC", "Classification", "classify"]

HYPERELASTIC = "hyperelastic"
WEAKLY_HYPOELASTIC = "weakly hypoelastic"
STRONGLY_HYPOELASTIC = "strongly hypoelastic"


@dataclass(frozen=True)
class Classification:
    """The computed class of a law and the condition that decided it.

    Attributes
    ----------
    law
        Law name.
    kind
        One of :data:`HYPERELASTIC`, :data:`WEAKLY_HYPOELASTIC`,
        :data:`STRONGLY_HYPOELASTIC`.
    deciding_condition
        The check whose outcome decided the class.
    checks
        Every condition evaluated, in order.
    energy
        The potential W(l, alpha) for a hyperelastic law, else ``None``.
    """

    law: str
    kind: str
    deciding_condition: ConditionCheck
    checks: tuple[ConditionCheck, ...]
    energy: sp.Expr | None

    @property
    def reason(self) -> str:
        """One line saying which condition decided the class."""
        check = self.deciding_condition
        verdict = "holds" if check.holds else "fails"
        detail = "" if check.holds else f" (residual {sp.sstr(check.residual)})"
        return f"{check.name} {verdict}{detail}"


def classify(definition: LawDefinition) -> Classification:
    """Classify a law definition by the seed's integrability conditions.

    Parameters
    ----------
    definition
        Any law of the interaction protocol (a contact law, a rotational
        spring), including ones not in the catalogue.

    Returns
    -------
    Classification
    """
    derivation = derive_interaction(definition)
    if not derivation.rate_integrability.holds:
        kind, deciding = STRONGLY_HYPOELASTIC, derivation.rate_integrability
    elif derivation.hyperelasticity.holds:
        kind, deciding = HYPERELASTIC, derivation.hyperelasticity
    else:
        kind, deciding = WEAKLY_HYPOELASTIC, derivation.hyperelasticity
    energy = derivation.energy if kind == HYPERELASTIC else None
    if kind != HYPERELASTIC and definition.energy is not None:
        raise ValueError(
            f"law {definition.name!r} declares an energy but is {kind}: the declaration is wrong"
        )
    return Classification(definition.name, kind, deciding, derivation.checks, energy)
