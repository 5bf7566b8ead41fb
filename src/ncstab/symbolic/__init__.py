"""Symbolic layer (sympy): tangents, integrability conditions, classification, lambdify.

Runs once per law definition; nothing here is called inside a numeric loop.
"""

from ncstab.symbolic.classification import (
    HYPERELASTIC,
    STRONGLY_HYPOELASTIC,
    WEAKLY_HYPOELASTIC,
    Classification,
    classify,
)
from ncstab.symbolic.compile import CompiledLaw, compile_law, lambdify_broadcast
from ncstab.symbolic.derivation import (
    ConditionCheck,
    LawDerivation,
    derive_law,
    is_identically_zero,
    kinematic_integrability,
)

__all__ = [
    "HYPERELASTIC",
    "STRONGLY_HYPOELASTIC",
    "WEAKLY_HYPOELASTIC",
    "Classification",
    "CompiledLaw",
    "ConditionCheck",
    "LawDerivation",
    "classify",
    "compile_law",
    "derive_law",
    "is_identically_zero",
    "kinematic_integrability",
    "lambdify_broadcast",
]
