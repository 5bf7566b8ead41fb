"""``[output] extrema``: the state variables whose first extremum a study locates.

``extrema = ["alpha", "u:D2"]`` names stored state variables: an interaction
variable (``alpha``, ``l``, ``N``, ``T``, ``theta``, ``moment``; ``alpha:top_left``
for one member of a family with several), a displacement ``u:<dof>``, a force
``F:<force>`` or ``load``.  Each gives the event ``extremum_<name>`` (``:`` read
``_``: ``extremum_u_D2``), located by :mod:`ncstab.paths.extrema`.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from ncstab.paths.options import SystemSpec
from ncstab.studies.study_fields import FieldErrors, did_you_mean, toml_type

__all__ = ["FIELD", "extrema_option"]

#: The field the errors of ``[output] extrema`` name.
FIELD = "output.extrema"


def extrema_option(table: Mapping[str, Any], errors: FieldErrors, system: Any) -> tuple[str, ...]:
    """The names of ``[output] extrema`` (``()`` if absent), each checked against the system.

    Refused: a name the system stores no variable for (the message lists the
    choices), a name given twice, the pure-shear limit (``normal = "rigid"``:
    its state coordinates are not its displacements) and assembled systems
    (followed by the sparse engine).
    """
    from ncstab.paths.extrema import extremum_choices
    from ncstab.systems.assembled import is_assembled

    if "extrema" not in table:
        return ()
    raw = table["extrema"]
    example = 'such as ["alpha"] or ["u:D2"]'
    if not isinstance(raw, list) or not all(isinstance(name, str) for name in raw):
        shown = toml_type(raw) if not isinstance(raw, list) else "an array holding " + ", ".join(
            sorted({toml_type(name) for name in raw if not isinstance(name, str)}))
        errors.add(FIELD, f"expected an array of state variable names {example}, got {shown}")
        return ()
    try:
        definition = system.definition if isinstance(system, SystemSpec) else system
        choices = extremum_choices(definition)
    except (ValueError, TypeError, KeyError, AttributeError):  # an invalid system: its own error says so
        return tuple(raw)
    if isinstance(system, SystemSpec) and system.normal == "rigid":
        errors.add(FIELD, 'extrema are not located in the pure-shear limit (normal = "rigid")')
        return ()
    if is_assembled(definition):
        errors.add(FIELD, f"extrema are not located yet for system {definition.name!r} at this size "
                          "(an assembled system, followed by the sparse engine)")
        return ()
    names: list[str] = []
    for name in raw:
        if name in names:
            errors.add(FIELD, f"{name!r} is listed twice")
        elif name not in choices:
            errors.add(FIELD, f"unknown state variable {name!r}{did_you_mean(name, choices)}; for system "
                              f"{definition.name!r} the choices are {', '.join(choices)}")
        else:
            names.append(name)
    return tuple(names)
