"""Parameter values of a study file: numbers, expressions, lists and ranges (a sweep
dimension), checked against the ranges the laws and the system allow
(``docs/study-files.md``, "Parameters and sweeps")."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ncstab.laws.definition import LawDefinition, ParameterSpec
from ncstab.laws.registry import LAWS
from ncstab.paths.options import SystemSpec
from ncstab.paths.variables import RESERVED_NAMES
from ncstab.studies.study_fields import (
    KAPPA_SPEC,
    RIGID_MEANINGLESS,
    FieldErrors,
    check_keys,
    did_you_mean,
    read_number,
    read_table,
    toml_type,
)
from ncstab.systems import SYSTEMS, SystemKind


def parameter_specs(
    definitions: Sequence[LawDefinition], all_laws_valid: bool, kind: SystemKind | None, system: SystemSpec
) -> dict[str, ParameterSpec]:
    """Specification of every law, system and engine parameter the study may set
    (not the law parameters the system's geometry fixes: a ring's alpha0)."""
    laws = definitions if all_laws_valid else list(definitions) + list(LAWS.values())
    fixed: set[str] = set()
    if kind is not None:
        definition = system.definition
        laws = list(laws) + [f.law for f in definition.families if f.law is not None]
        fixed = {name for f in definition.families for name in f.fixed_parameters}
        fixed -= {p.name for p in definition.parameters}
    specs: dict[str, ParameterSpec] = {}
    for definition_ in laws:
        for spec in definition_.parameters:
            if spec.name not in fixed:
                specs.setdefault(spec.name, spec)
    kinds = [kind] if kind is not None else list(SYSTEMS.values())
    for k in kinds:
        for spec in k.parameter_specs:
            specs.setdefault(spec.name, spec)
    if kind is None or kind.granular:
        specs["kappa"] = KAPPA_SPEC
    return specs


#: Keys of a range table (``gamma = { start = 0.1, stop = 2.0, num = 64 }``).
RANGE_KEYS = ("start", "stop", "num", "step", "scale")


#: Scales of a range: ``linear`` (numpy.linspace) or ``log`` (numpy.geomspace).
RANGE_SCALES = ("linear", "log")


#: Most values one range may give (a sweep dimension longer than this is a typo).
MAX_RANGE_VALUES = 1_000_000


#: A ``step`` range keeps ``start + k*step`` while it passes ``stop`` by at most this
#: fraction of ``|step|`` (rounding: 3 * 0.1 is 4e-17 past 0.3); a last value
#: within that tolerance of ``stop`` is ``stop`` exactly.
RANGE_STEP_TOL = 1e-9


def repeated_values(values: Sequence[float]) -> list[float]:
    """Values that appear more than once, sorted (one pass over a set: linear time)."""
    seen: set[float] = set()
    repeated: set[float] = set()
    for value in values:
        (repeated if value in seen else seen).add(value)
    return sorted(repeated)


def range_count(table: Mapping[str, Any], field: str, errors: FieldErrors) -> int | None:
    """``num`` of a range: a TOML integer from 1 to :data:`MAX_RANGE_VALUES`."""
    num = table["num"]
    if isinstance(num, bool) or not isinstance(num, int):
        errors.add(
            f"{field}.num",
            f"expected a whole number of values (a TOML integer such as 64), got {toml_type(num)} ({num!r})",
        )
        return None
    if not 1 <= num <= MAX_RANGE_VALUES:
        errors.add(f"{field}.num", f"{num} values: a range has from 1 to {MAX_RANGE_VALUES:,} values")
        return None
    return num


def step_values(start: float, stop: float, step: float, field: str, errors: FieldErrors) -> list[float] | None:
    """``start + k*step`` for k = 0, 1, ... while not past ``stop`` by more than
    :data:`RANGE_STEP_TOL` ``* |step|``; a last value that close to ``stop`` is ``stop``."""
    if step == 0 or (stop - start) * step < 0:
        errors.add(
            f"{field}.step",
            f"step = {step:g} does not go from start = {start:g} to stop = {stop:g}; "
            "give a step of the sign of stop - start",
        )
        return None
    span = (stop - start) / step
    if not span < MAX_RANGE_VALUES:  # also an overflowing span (inf)
        errors.add(
            f"{field}.step",
            f"step = {step:g} gives more than {MAX_RANGE_VALUES:,} values from {start:g} to {stop:g}",
        )
        return None
    values = start + step * np.arange(math.floor(span + RANGE_STEP_TOL) + 1, dtype=float)
    if abs(values[-1] - stop) <= RANGE_STEP_TOL * abs(step):
        values[-1] = stop
    return values.tolist()


def range_values(table: Mapping[str, Any], field: str, errors: FieldErrors) -> list[float] | None:
    """The values of a range table, or ``None`` after reporting its errors.

    ``{start, stop, num}``: ``numpy.linspace(start, stop, num)`` (endpoints
    exact); with ``scale = "log"``: ``numpy.geomspace`` (bounds > 0);
    ``{start, stop, step}``: :func:`step_values`.  Each error names its key
    (``parameters.gamma.num``).
    """
    before = len(errors)
    check_keys(table, RANGE_KEYS, field, errors, "a range")
    for key in ("start", "stop"):
        if key not in table:
            errors.add(field, f"a range needs {key}: {{ start = 0.1, stop = 2.0, num = 64 }} "
                       "or { start = 0, stop = 1, step = 0.1 }")
    if "num" in table and "step" in table:
        errors.add(f"{field}.step", "give num (the number of values) or step (their spacing), not both")
    elif "num" not in table and "step" not in table:
        errors.add(field, "a range needs num (the number of values) or step (their spacing)")
    scale = table.get("scale", "linear")
    if scale not in RANGE_SCALES:
        errors.add(f"{field}.scale", f"{scale!r} is not allowed; allowed: {', '.join(RANGE_SCALES)}")
    elif scale == "log" and "step" in table:
        errors.add(f"{field}.scale", 'scale = "log" takes num (values evenly spaced in log), not step')
    bounds = {key: read_number(table[key], f"{field}.{key}", errors) for key in ("start", "stop") if key in table}
    num = range_count(table, field, errors) if "num" in table else None
    step = read_number(table["step"], f"{field}.step", errors) if "step" in table else None
    start, stop = bounds.get("start"), bounds.get("stop")
    if len(errors) > before or start is None or stop is None:
        return None
    if scale == "log":
        for key, bound in bounds.items():
            if bound is not None and bound <= 0:
                errors.add(f"{field}.{key}", f"{key} = {bound:g}: a log range needs bounds > 0")
        if len(errors) > before:
            return None
    if step is not None:
        return step_values(start, stop, step, field, errors)
    assert num is not None
    if start == stop and num > 1:
        errors.add(
            f"{field}.num",
            f"start = stop = {start:g} with num = {num}: the values would repeat; give num = 1 or two bounds",
        )
        return None
    values = np.geomspace(start, stop, num) if scale == "log" else np.linspace(start, stop, num)
    return values.tolist()


def parameter_value(
    value: Any, field: str, errors: FieldErrors, allow_sweep: bool = True
) -> float | list[float] | None:
    """A number, or a sweep: a non-empty list of distinct numbers or a range table; ``None`` on error."""
    if isinstance(value, (list, dict)) and not allow_sweep:
        errors.add(field, f"a sweep ({'list' if isinstance(value, list) else 'range'}) belongs in [parameters]")
        return None
    values: list[float] | None
    if isinstance(value, dict):
        values = range_values(value, field, errors)
    elif isinstance(value, list):
        if not value:
            errors.add(field, "an empty sweep has no cases: give at least one value, or a single number")
            return None
        values = []
        ok = True
        for k, element in enumerate(value, start=1):
            if isinstance(element, list):
                errors.add(field, f"element {k} is an array: a sweep is a flat list of numbers")
                ok = False
                continue
            number = read_number(element, field, errors)
            if number is None:
                ok = False
            else:
                values.append(number)
        if not ok:
            return None
    else:
        return read_number(value, field, errors)
    if values is None:
        return None
    duplicated = repeated_values(values)
    if duplicated:
        shown = ", ".join(f"{v:g}" for v in duplicated[:5])
        shown += f" (and {len(duplicated) - 5} more)" if len(duplicated) > 5 else ""
        errors.add(field, f"value(s) {shown} appear more than once in the sweep; give each value once")
        return None
    return values


def within_range(value: float | list[float], spec: ParameterSpec, field: str, errors: FieldErrors) -> bool:
    try:
        spec.validate(value)
    except ValueError as error:
        errors.add(field, str(error))
        return False
    return True


def read_parameters(
    data: Mapping[str, Any],
    errors: FieldErrors,
    system: SystemSpec,
    system_raw: Mapping[str, Any],
    specs: Mapping[str, ParameterSpec],
    definitions: Sequence[LawDefinition],
) -> tuple[dict[str, float | list[float]], dict[str, str], set[str]]:
    """Parameters (``[system]`` first, then ``[parameters]``, file order), where each
    was given (``name -> field``) and the free ones (not a system or law parameter)."""
    parameters: dict[str, float | list[float]] = {}
    fields: dict[str, str] = {}
    free: set[str] = set()
    for key, raw in system_raw.items():
        fields[key] = f"system.{key}"
        value = parameter_value(raw, fields[key], errors, allow_sweep=False)
        if value is not None:
            parameters[key] = value
    for key, raw in (read_table(data, "parameters", errors) or {}).items():
        field = f"parameters.{key}"
        if key in fields:
            errors.add(field, f"{key!r} is also given in [system] ({fields[key]}); give it once")
            continue
        fields[key] = field
        if key not in specs:
            if not key.isidentifier():
                errors.add(field, f"parameter name {key!r} is not allowed: use letters, digits and '_' (not first)")
                continue
            if key in RESERVED_NAMES:
                errors.add(
                    field, f"parameter name {key!r} is reserved (a dimension, variable or keyword); choose another name"
                )
                continue
            free.add(key)
        value = parameter_value(raw, field, errors)
        if value is not None:
            parameters[key] = value

    # Ranges of known parameters; gamma and kappa mean nothing in the pure-shear limit.
    rigid = system.normal == "rigid"
    for key, value in list(parameters.items()):
        if rigid and key in RIGID_MEANINGLESS:
            errors.add(
                fields[key],
                f"{key} has no meaning with normal = \"rigid\" (the pure-shear limit, seed Eq. 60-68: forces "
                "in units of 2R k_t, rigid secondary contacts); remove it or use normal = \"deformable\"",
            )
            del parameters[key]
        elif key in specs and not within_range(value, specs[key], fields[key], errors):
            del parameters[key]

    # Law parameters without a default (gamma) must be given.
    needed: dict[str, tuple[ParameterSpec, list[str]]] = {}
    for definition in definitions:
        for spec in definition.parameters:
            if spec.default is None and spec.name not in fields and not (rigid and spec.name in RIGID_MEANINGLESS):
                needed.setdefault(spec.name, (spec, []))[1].append(definition.name)
    for key, (spec, users) in needed.items():
        errors.add(
            f"parameters.{key}",
            f"missing: law(s) {', '.join(map(repr, users))} need {key} ({spec.description}); "
            f"allowed: {spec.allowed} (a number, or a list to sweep it)",
        )
    return parameters, fields, free


def check_references(
    errors: FieldErrors,
    references: Mapping[str, list[str]],
    fields: Mapping[str, str],
    free: set[str],
    known: Sequence[str],
) -> None:
    """Every name a stage refers to is defined; every free parameter is referred to."""
    for reference, referring_fields in references.items():
        if reference not in fields:
            for field in referring_fields:
                errors.add(
                    field,
                    f"refers to undefined parameter {reference!r}{did_you_mean(reference, fields)}; "
                    f"defined parameters: {', '.join(fields) or 'none'} (give it in [parameters])",
                )
    for key in fields:
        if key in free and key not in references:
            errors.add(
                fields[key],
                f"parameter {key!r} is unused{did_you_mean(key, known)}: it is not a parameter of the system or the "
                f"laws ({', '.join(known)}) and no loading stage refers to it",
            )


def check_fixed_parameters(data: Mapping[str, Any], errors: FieldErrors, kind: SystemKind | None, system: SystemSpec) -> None:
    """Law parameters the system's geometry fixes (a ring's alpha0) cannot be set."""
    if kind is None:
        return
    definition = system.definition
    fixed = {name for f in definition.families for name in f.fixed_parameters} - {p.name for p in definition.parameters}
    table = data.get("parameters")
    for key in sorted(fixed & set(table or {})) if isinstance(table, dict) else ():
        errors.add(
            f"parameters.{key}",
            f"{key} is fixed by the geometry of system {system.name!r} (each contact has its own); remove it",
        )
