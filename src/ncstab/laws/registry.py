"""The explicit law registry and validated law instances."""

from __future__ import annotations

import dataclasses
import difflib
from dataclasses import dataclass, field
from typing import Mapping

import numpy as np

from ncstab.laws.catalogue import (
    CUNDALL_STRACK,
    DEM_CHRONO_ONE_STEP,
    DEM_YADE_AVOID_RATCHETING,
    MCNAMARA,
    TURCO,
    WEAKLY_HYPOELASTIC,
    no_tension,
)
from ncstab.laws.definition import DELTA, LawDefinition
from ncstab.laws.spring import LINEAR_SPRING, SpringLaw

__all__ = ["LAWS", "MODIFIERS", "SPRING_LAWS", "Law", "law_definition", "make_law", "law_names"]

#: Every law ncstab knows, by name.  Add a law here, nowhere else.
LAWS: dict[str, LawDefinition] = {
    "cundall_strack": CUNDALL_STRACK,
    "weakly_hypoelastic": WEAKLY_HYPOELASTIC,
    "mcnamara": MCNAMARA,
    "turco": TURCO,
    "dem_yade_avoid_ratcheting": DEM_YADE_AVOID_RATCHETING,
    "dem_chrono_one_step": DEM_CHRONO_ONE_STEP,
}

#: Laws of rotational springs (bars, columns, pendulums), by name.
SPRING_LAWS: dict[str, SpringLaw] = {
    "linear_spring": LINEAR_SPRING,
}

#: Modifiers, written after a law name with ``+``: ``"mcnamara+no_tension"``.
MODIFIERS = {"no_tension": no_tension}


def law_names(with_modifiers: bool = False) -> list[str]:
    """Names in the catalogue, optionally with every modified variant."""
    names = list(LAWS)
    if with_modifiers:
        names += [f"{n}+{m}" for n in LAWS for m in MODIFIERS]
    return names + list(SPRING_LAWS)


def _catalogue_text() -> str:
    return (
        "the catalogue has: "
        + ", ".join(LAWS)
        + "; modifiers (append with '+'): "
        + ", ".join(MODIFIERS)
        + "; spring laws: "
        + ", ".join(SPRING_LAWS)
    )


def law_definition(
    name: str, user_laws: Mapping[str, LawDefinition] | None = None
) -> LawDefinition | SpringLaw:
    """Look a law up by name, with modifiers (``"turco+no_tension"``), or a spring law.

    Parameters
    ----------
    name
        A law name, optionally followed by ``+<modifier>``.
    user_laws
        Laws outside the catalogue (a study's ``[laws.<name>]`` tables), by
        name; looked up before the catalogue (their names never clash with it).

    Raises
    ------
    ValueError
        For an unknown law or modifier (the message lists the catalogue and a
        close match when there is one), or a modifier given twice.
    """
    known = dict(user_laws or {})
    if not isinstance(name, str) or not name.strip():
        raise ValueError(f"law name must be a non-empty string, got {name!r}; {_catalogue_text()}")
    if name.strip() in SPRING_LAWS:
        return SPRING_LAWS[name.strip()]
    base, *modifiers = [part.strip() for part in name.split("+")]
    if base not in LAWS and base not in known:
        close = difflib.get_close_matches(base, list(LAWS) + list(SPRING_LAWS) + list(known), n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        user = f"; user laws: {', '.join(known)}" if known else ""
        raise ValueError(f"unknown law {base!r}{hint}; {_catalogue_text()}{user}")
    definition = known[base] if base in known else LAWS[base]
    for k, modifier in enumerate(modifiers):
        if modifier not in MODIFIERS:
            close = difflib.get_close_matches(modifier, MODIFIERS, n=1)
            hint = f" (did you mean {close[0]!r}?)" if close else ""
            raise ValueError(f"unknown law modifier {modifier!r} in {name!r}{hint}; {_catalogue_text()}")
        if modifier in modifiers[:k]:
            raise ValueError(
                f"modifier {modifier!r} is given twice in {name!r}: a modifier applies once "
                f"(write {'+'.join([base, *dict.fromkeys(modifiers)])!r})"
            )
        if definition.energy is not None and DELTA not in definition.energy.free_symbols:
            # An energy not written through delta (a user law's) cannot follow the bracket of
            # the modifier: it is dropped, and the bracketed law's energy, if any, is derived.
            definition = dataclasses.replace(definition, energy=None)
        definition = MODIFIERS[modifier](definition)
    return definition


@dataclass(frozen=True)
class Law:
    """A law of the catalogue with validated parameter values.

    Parameter values are arrays that broadcast against each other and against
    the states they are evaluated at, so one ``Law`` can stand for a whole sweep
    (``gamma`` of shape ``(n_cases,)``).

    Attributes
    ----------
    definition
        The symbolic definition (see :class:`ncstab.laws.LawDefinition`).
    parameters
        Validated parameter values by name (float arrays).
    """

    definition: LawDefinition
    parameters: Mapping[str, np.ndarray] = field(default_factory=dict)

    @property
    def name(self) -> str:
        return self.definition.name

    @property
    def has_total_form(self) -> bool:
        return self.definition.has_total_form

    @property
    def internal_variables(self) -> tuple[str, ...]:
        return self.definition.internal_variables

    def parameter_values(self) -> tuple[np.ndarray, ...]:
        """Parameter values in the definition's order (for compiled functions)."""
        return tuple(self.parameters[name] for name in self.definition.parameter_names)


def make_law(name: str | LawDefinition, /, **parameters: object) -> Law:
    """Build a validated law: ``make_law("mcnamara", gamma=2.0, alpha0=np.pi/4)``.

    Parameters
    ----------
    name
        A catalogue name, optionally with modifiers (``"mcnamara+no_tension"``),
        or a :class:`LawDefinition` (for laws outside the catalogue).
    **parameters
        Values (scalars or arrays) for every parameter of the law; a parameter
        with a default may be omitted.

    Raises
    ------
    ValueError
        Unknown law, unknown or missing parameter, or a value outside its range;
        the message names the parameter and the allowed range.
    """
    definition = name if isinstance(name, (LawDefinition, SpringLaw)) else law_definition(name)
    specs = {p.name: p for p in definition.parameters}
    unknown = sorted(set(parameters) - set(specs))
    if unknown:
        raise ValueError(
            f"law {definition.name!r} has no parameter(s) {', '.join(map(repr, unknown))}; "
            f"its parameters are: {', '.join(specs)}"
        )
    values: dict[str, np.ndarray] = {}
    for pname, spec in specs.items():
        if pname in parameters:
            values[pname] = spec.validate(parameters[pname])
        elif spec.default is not None:
            values[pname] = np.asarray(spec.default, dtype=float)
        else:
            raise ValueError(
                f"law {definition.name!r} needs parameter {pname!r} ({spec.description}), "
                f"allowed: {spec.allowed}"
            )
    return Law(definition, values)
