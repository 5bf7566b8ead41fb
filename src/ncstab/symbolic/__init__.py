"""Symbolic layer (sympy): tangents, integrability conditions, classification, lambdify.

Runs once per law definition; nothing here is called inside a numeric loop.
The printed class and derivation of a law (:func:`class_summary`,
:func:`law_explanation`) are derived once and kept in the cache directory
(:mod:`ncstab.symbolic.class_cache`).
"""

from ncstab.symbolic.classification import (
    HYPERELASTIC,
    STRONGLY_HYPOELASTIC,
    WEAKLY_HYPOELASTIC,
    Classification,
    classify,
)
from ncstab.symbolic.class_cache import ClassSummary, class_summary, law_explanation
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
    "ClassSummary",
    "Classification",
    "CompiledLaw",
    "ConditionCheck",
    "LawDerivation",
    "class_summary",
    "classify",
    "compile_law",
    "derive_law",
    "is_identically_zero",
    "kinematic_integrability",
    "law_explanation",
    "lambdify_broadcast",
]
