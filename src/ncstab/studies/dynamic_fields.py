"""The ``dynamic`` table of a ``[[loading]]`` stage (docs/dynamics-after-loss.md).

:func:`read_dynamic_stage` checks one stage with a ``dynamic`` table -- the last
of the programme, on a system with inertia followed by the derived engine -- and
turns it into a :class:`~ncstab.dynamics.DynamicStage`, reporting every problem
as a field of the study file (``loading[2].dynamic.duration``).  A programme
made of a dynamic stage alone starts from rest: :func:`rest_stage` is the static
stage that stores nothing and leaves every case there.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ncstab.dynamics.stage import DYNAMIC_KEYS, DynamicStage, parse_dynamic_stage
from ncstab.paths.options import SystemSpec
from ncstab.paths.programme import ProgrammeError
from ncstab.studies.study_fields import FieldErrors, check_keys, read_number, toml_type

__all__ = ["read_dynamic_stage", "rest_stage"]


def rest_stage(forces: Sequence[str]) -> dict[str, Any]:
    """A static stage that keeps every case at rest (every force held at 0): the programme
    of a study whose only stage is dynamic."""
    return {"hold": {force: 0.0 for force in forces[1:]}, "drive": {forces[0]: 0.0}}


def _engine_problem(system: Any) -> str | None:
    """Why the system's motion cannot be integrated, or None."""
    from ncstab.systems.assembled import is_assembled

    if isinstance(system, SystemSpec) and system.normal == "rigid":
        return "the pure-shear limit (normal = \"rigid\") has no motion in time: use a deformable normal"
    definition = system.definition if isinstance(system, SystemSpec) else system
    if is_assembled(definition):
        return (
            f"system {definition.name!r} of {definition.n_dof} dofs is assembled from elements: dynamic stages "
            "integrate systems derived whole (at most 8 dofs)"
        )
    return None


def read_dynamic_stage(
    raw: Mapping[str, Any],
    number: int,
    count: int,
    errors: FieldErrors,
    references: dict[str, list[str]],
    system: Any,
) -> DynamicStage | None:
    """The dynamic stage ``loading[number]`` (``None`` after reporting its errors).

    Parameters
    ----------
    raw
        The stage's table (``hold``, ``dynamic`` and ``stop_at``).
    number, count
        Its 1-based number and the number of stages (it must be the last).
    errors, references
        Where problems and the parameter names of held values go.
    system
        The study's :class:`SystemSpec` (or a definition).
    """
    from ncstab.studies.study_loading import stage_value

    prefix = f"loading[{number}]"
    before = len(errors)
    table = raw.get("dynamic")
    if number != count:
        errors.add(f"{prefix}.dynamic", f"a dynamic stage is the programme's last (this is stage {number} of {count})")
    for key in sorted(set(raw) - {"dynamic", "hold", "stop_at"}):
        errors.add(f"{prefix}.{key}", "a dynamic stage drives nothing: it takes hold, dynamic and stop_at only")
    if not isinstance(table, dict):
        errors.add(f"{prefix}.dynamic", f"expected a table {{ duration = ..., perturbation = {{ ... }} }}, got {toml_type(table)}")
        return None
    check_keys(table, DYNAMIC_KEYS, f"{prefix}.dynamic", errors, "a dynamic stage")
    problem = _engine_problem(system)
    if problem is not None:
        errors.add(f"{prefix}.dynamic", problem)
    clean: dict[str, Any] = {k: v for k, v in table.items() if k in DYNAMIC_KEYS}
    for key in ("duration", "rtol"):
        if key in clean and isinstance(clean[key], str):
            value = read_number(clean[key], f"{prefix}.dynamic.{key}", errors)
            clean[key] = value if value is not None else 1.0
    if "kinetic_energy_threshold" in clean:  # an expression, or what is wrong with it named here
        value = read_number(clean["kinetic_energy_threshold"], f"{prefix}.dynamic.kinetic_energy_threshold", errors)
        clean["kinetic_energy_threshold"] = value if value is not None else 1.0
    perturbation = clean.get("perturbation")
    if isinstance(perturbation, dict):
        clean["perturbation"] = {}
        for name, value in perturbation.items():
            number_value = read_number(value, f"{prefix}.dynamic.perturbation.{name}", errors)
            clean["perturbation"][name] = 0.0 if number_value is None else number_value
    stage: dict[str, Any] = {"dynamic": clean, "stop_at": raw.get("stop_at", [])}
    hold = raw.get("hold", {})
    if isinstance(hold, dict):
        stage["hold"] = {q: stage_value(v, f"{prefix}.hold.{q}", errors, references) for q, v in hold.items()}
    else:
        stage["hold"] = hold
    definition = system.definition if isinstance(system, SystemSpec) else system
    try:
        parsed = parse_dynamic_stage(
            number, stage, definition.dofs, definition.forces, definition.load_parameter,
            definition.mass is not None, f"system {definition.name!r}", tuple(g.name for g in definition.gaps),
        )
    except ProgrammeError as error:
        errors.add(f"{prefix}.{error.field}", str(error).split(f"field {error.field!r}: ", 1)[-1])
        return None
    return parsed if len(errors) == before else None
