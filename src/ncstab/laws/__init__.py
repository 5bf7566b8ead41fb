"""Contact interaction laws (layer ``laws/``): definitions, catalogue, registry.

Knows nothing of the other layers.  See ``docs/laws.md`` for the equations.
"""

from ncstab.laws.catalogue import (
    CUNDALL_STRACK,
    DEM_CHRONO_ONE_STEP,
    DEM_YADE_AVOID_RATCHETING,
    MCNAMARA,
    TURCO,
    WEAKLY_HYPOELASTIC,
    no_tension,
)
from ncstab.laws.definition import (
    ALPHA,
    ALPHA0,
    ALPHA0_SPEC,
    DELTA,
    GAMMA,
    GAMMA_SPEC,
    L,
    N,
    T,
    LawDefinition,
    ParameterSpec,
)
from ncstab.laws.formula import FormulaError, UserLawError, parse_formula
from ncstab.laws.registry import LAWS, MODIFIERS, Law, law_definition, law_names, make_law
from ncstab.laws.user import user_law

__all__ = [
    "ALPHA",
    "ALPHA0",
    "ALPHA0_SPEC",
    "CUNDALL_STRACK",
    "DELTA",
    "DEM_CHRONO_ONE_STEP",
    "DEM_YADE_AVOID_RATCHETING",
    "FormulaError",
    "GAMMA",
    "GAMMA_SPEC",
    "L",
    "LAWS",
    "MCNAMARA",
    "MODIFIERS",
    "N",
    "T",
    "TURCO",
    "UserLawError",
    "WEAKLY_HYPOELASTIC",
    "Law",
    "LawDefinition",
    "ParameterSpec",
    "law_definition",
    "law_names",
    "make_law",
    "no_tension",
    "parse_formula",
    "user_law",
]
