"""The ``[loading]``, ``[options]`` and ``[output]`` sections of a study file:
stages into a :class:`~ncstab.paths.programme.LoadingProgramme`, engine options and
figures (the ``[map]`` section: :mod:`ncstab.studies.study_map`)."""

from __future__ import annotations

import dataclasses
import re
from collections.abc import Mapping, Sequence
from typing import Any

from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import (
    CURRENT,
    EVENTS,
    CycleStage,
    LoadingProgramme,
    ProgrammeError,
    parse_programme,
)
from ncstab.studies.expressions import is_expression
from ncstab.studies.figure_fit import FigureFit, figure_misfit
from ncstab.studies.study_fields import (
    CYCLE_KEYS,
    DEFAULT_FIGURES,
    DEFAULT_MAX_CASES,
    FIGURE_KINDS,
    OUTPUT_KEYS,
    SPECTRUM_FIGURES,
    STAGE_KEYS,
    FieldErrors,
    check_keys,
    did_you_mean,
    read_number,
    read_table,
    toml_type,
)
from ncstab.systems import SystemKind


def stage_value(
    value: Any, field: str, errors: FieldErrors, references: dict[str, list[str]]
) -> Any:
    """A number, a parameter name or ``"current"``; expressions are evaluated."""
    if isinstance(value, str) and not is_expression(value):
        name = value.strip()
        if name != CURRENT:
            references.setdefault(name, []).append(field)
        return name
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        errors.add(
            field,
            f"expected a number, an expression, a parameter name or \"current\", got {toml_type(value)} ({value!r})",
        )
        return 0.0
    number = read_number(value, field, errors)
    return 0.0 if number is None else number


def programme_message(error: ProgrammeError) -> str:
    text = str(error)
    for stage in (error.stage, 1):
        where = f"loading stage {stage}" if stage is not None else "loading programme"
        prefix = f"{where}, field {error.field!r}: "
        if text.startswith(prefix):
            return text[len(prefix):]
    return text


def stop_at_events(value: Any, field: str, errors: FieldErrors) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list):
        errors.add(field, f"expected an array of event names, got {toml_type(value)}; events are: {', '.join(EVENTS)}")
        return []
    valid = []
    for name in value:
        if not isinstance(name, str):
            errors.add(field, f"expected event names (strings), got {toml_type(name)}; events are: {', '.join(EVENTS)}")
        elif name not in EVENTS:
            errors.add(field, f"unknown event {name!r}{did_you_mean(name, EVENTS)}; events are: {', '.join(EVENTS)}")
        else:
            valid.append(name)
    return valid


def read_stage(
    raw: Mapping[str, Any], prefix: str, errors: FieldErrors, references: dict[str, list[str]], forces: Sequence[str]
) -> tuple[dict[str, Any], bool]:
    """A stage table with expressions evaluated, and whether its structure can be checked.

    Unknown keys and invalid events are reported and left out, bad values are
    reported and replaced by 0.0, so that :func:`parse_programme` can still
    check the rest of the stage (controlled twice, nothing driven...) without
    reporting the same error twice.  A stage whose ``hold``/``drive``/``cycle``
    is not a table is not checked further (every later error would follow from it).
    """
    check_keys(raw, STAGE_KEYS, prefix, errors, "a stage")
    stage: dict[str, Any] = {}
    checkable = True
    if "cycle" in raw:
        for key in ("hold", "drive"):
            if key in raw:
                errors.add(f"{prefix}.{key}", "a cycle stage drives both displacements: it takes only cycle and stop_at")
        cycle = raw["cycle"]
        if not isinstance(cycle, dict):
            errors.add(
                f"{prefix}.cycle",
                f"expected a table {{center = [D1, D2], turns = n, direction = 1 or -1}}, got {toml_type(cycle)}",
            )
            checkable = False
        else:
            check_keys(cycle, CYCLE_KEYS, f"{prefix}.cycle", errors, "a cycle")
            stage["cycle"] = {k: v for k, v in cycle.items() if k in CYCLE_KEYS}
            center = cycle.get("center")
            if isinstance(center, list):
                field = f"{prefix}.cycle.center"
                stage["cycle"]["center"] = [stage_value(c, field, errors, references) for c in center]
    else:
        for key in ("hold", "drive"):
            table = raw.get(key, {})
            if not isinstance(table, dict):
                errors.add(
                    f"{prefix}.{key}",
                    f"expected a table of quantity = value such as {{ {forces[0]} = 0.0 }}, got {toml_type(table)}",
                )
                checkable = False
            elif key in raw:
                stage[key] = {q: stage_value(v, f"{prefix}.{key}.{q}", errors, references) for q, v in table.items()}
    if "stop_at" in raw:
        stage["stop_at"] = stop_at_events(raw["stop_at"], f"{prefix}.stop_at", errors)
    if "at_bifurcation" in raw:
        if "cycle" in raw:
            errors.add(f"{prefix}.at_bifurcation", "a cycle stage goes on through bifurcations: at_bifurcation is for linear stages")
        else:
            stage["at_bifurcation"] = raw["at_bifurcation"]  # checked by parse_programme
    return stage, checkable


def loading_section(
    data: Mapping[str, Any], errors: FieldErrors, kind: SystemKind | None, system: SystemSpec
) -> tuple[LoadingProgramme | None, dict[str, list[str]]]:
    """The programme (``None`` on error) and ``parameter name -> fields referring to it``."""
    references: dict[str, list[str]] = {}
    stages = data.get("loading")
    if stages is None:
        errors.add("loading", "missing: give at least one [[loading]] stage (hold = {...}, drive = {...})")
        return None, references
    if isinstance(stages, dict):
        errors.add(
            "loading", "expected [[loading]] stages (an array of tables, one per stage), got a single [loading] table"
        )
        return None, references
    if not isinstance(stages, list) or not stages:
        errors.add("loading", "give at least one [[loading]] stage")
        return None, references
    if kind is None:  # the system's own error is reported: its dofs are unknown, so are the stages' quantities
        return None, references
    definition = system.definition
    dofs, forces, load = definition.dofs, definition.forces, definition.load_parameter
    others = getattr(definition, "hold_other_forces", False)  # a packing: uncontrolled forces held
    held = dict(getattr(definition, "held", ()))  # quantities the system holds (a grain's, a support's)
    clean: list[dict[str, Any]] = []
    dynamic = None
    before = len(errors)
    for number, raw in enumerate(stages, start=1):
        prefix = f"loading[{number}]"
        if not isinstance(raw, dict):
            errors.add(prefix, f"expected a table (hold = {{...}}, drive = {{...}}), got {toml_type(raw)}")
            continue
        if "dynamic" in raw:  # integrated in time (ncstab.dynamics), after the static stages
            from ncstab.studies.dynamic_fields import read_dynamic_stage

            if kind is not None:
                dynamic = read_dynamic_stage(raw, number, len(stages), errors, references, system)
            continue
        stage, checkable = read_stage(raw, prefix, errors, references, forces)
        if not checkable:
            continue
        if "cycle" in stage and _is_assembled(definition):
            from ncstab.paths.assembled_control import CYCLE_REFUSED

            errors.add(f"{prefix}.cycle", f"{CYCLE_REFUSED}; system {definition.name!r} has {definition.n_dof} dofs")
            continue
        if held and _held_controls(stage, prefix, held, errors):
            continue
        try:  # one stage at a time, so that every stage's errors are reported
            parse_programme([stage], dofs, forces, load, others)
        except ProgrammeError as error:
            field = prefix if error.field in ("", "loading") else f"{prefix}.{error.field}"
            errors.add(field, programme_message(error))
            continue
        clean.append(stage)
    if len(errors) > before:
        return None, references
    if dynamic is not None and not clean:
        from ncstab.studies.dynamic_fields import rest_stage

        clean.append(rest_stage(forces))
    try:
        return dataclasses.replace(parse_programme(clean, dofs, forces, load, others), dynamic=dynamic), references
    except ProgrammeError as error:  # pragma: no cover - every stage passed alone
        errors.add("loading", programme_message(error))
        return None, references


def _held_controls(stage: Mapping[str, Any], prefix: str, held: Mapping[str, str], errors: FieldErrors) -> bool:
    """Report each quantity of a stage that the system holds (a dof both fixed and driven,
    :attr:`~ncstab.systems.assembled.AssembledSystem.held`); whether there was one."""
    found = False
    for table in ("hold", "drive"):
        for name in stage.get(table) or {}:
            if name in held:
                errors.add(f"{prefix}.{table}.{name}", f"{name} is held by {held[name]}: a stage cannot control "
                                                        "a held dof or its force; free it there, or leave it out")
                found = True
    return found


OPTION_FIELDS = {f.name: f for f in dataclasses.fields(PathOptions)}


OPTION_NAME_PATTERN = re.compile(r"PathOptions\.(\w+)")


#: The largest whole-number engine options: Newton iterations per step (each costs a
#: solve of the system) and accepted steps per case (the compiled stepper counts them
#: in 32-bit integers' range; the size estimates multiply them).
INTEGER_OPTION_LIMITS = {"newton_max_iter": 1000, "max_steps": 1_000_000_000}


def options_section(data: Mapping[str, Any], errors: FieldErrors) -> tuple[PathOptions, int]:
    """Engine options (:class:`PathOptions`) and the study's ``max_cases``."""
    table = read_table(data, "options", errors) or {}
    check_keys(table, [*OPTION_FIELDS, "max_cases"], "options", errors, "[options]")
    max_cases = DEFAULT_MAX_CASES
    if "max_cases" in table:
        raw = table["max_cases"]
        if isinstance(raw, bool) or not isinstance(raw, int) or raw < 1:
            errors.add("options.max_cases", f"expected a whole number >= 1 (the most cases to run), got {raw!r}")
        else:
            max_cases = raw
    values: dict[str, Any] = {}
    for name, raw in table.items():
        if name not in OPTION_FIELDS:
            continue
        field = f"options.{name}"
        kinds = str(OPTION_FIELDS[name].type).split(" | ")  # e.g. ["float", "str"]: a number or a word
        if isinstance(raw, str) and "str" in kinds:
            value: Any = raw  # which words are allowed: PathOptions says
        elif kinds == ["str"]:
            errors.add(field, f"expected a string, got {toml_type(raw)} ({raw!r})")
            continue
        elif kinds == ["int"]:
            if isinstance(raw, bool) or not isinstance(raw, int):
                errors.add(field, f"expected a whole number, got {toml_type(raw)} ({raw!r})")
                continue
            largest = INTEGER_OPTION_LIMITS.get(name, INTEGER_OPTION_LIMITS["max_steps"])
            if raw > largest:
                errors.add(field, f"expected a whole number from 1 to {largest:,}, got {raw:,}"[:200])
                continue
            value = raw
        else:
            value = read_number(raw, field, errors)
            if value is None:
                continue
        try:
            PathOptions(**{name: value})
        except ValueError as error:
            match = OPTION_NAME_PATTERN.search(str(error))
            if match is None or match.group(1) == name:
                errors.add(field, str(error))
                continue
        values[name] = value
    try:
        return PathOptions(**values), max_cases
    except ValueError as error:
        match = OPTION_NAME_PATTERN.search(str(error))
        errors.add(f"options.{match.group(1)}" if match else "options", str(error))
        return PathOptions(), max_cases


def output_section(
    data: Mapping[str, Any], errors: FieldErrors, fit: FigureFit | None = None
) -> tuple[tuple[str, ...], str | None]:
    """Figure kinds and archive file; a kind the study cannot draw (``fit``) is an error."""
    table = read_table(data, "output", errors) or {}
    check_keys(table, OUTPUT_KEYS, "output", errors, "[output]")
    figures: tuple[str, ...] = DEFAULT_FIGURES
    if "figures" in table:
        raw = table["figures"]
        if not isinstance(raw, list):
            errors.add("output.figures", f"expected an array of figure kinds, got {toml_type(raw)}; kinds are: {', '.join(FIGURE_KINDS)}")
        else:
            kinds: list[str] = []
            for kind in raw:
                if not isinstance(kind, str):
                    errors.add("output.figures", f"expected figure kinds (strings), got {toml_type(kind)}; kinds are: {', '.join(FIGURE_KINDS)}")
                elif kind not in FIGURE_KINDS:
                    errors.add(
                        "output.figures",
                        f"unknown figure kind {kind!r}{did_you_mean(kind, FIGURE_KINDS)}; kinds are: {', '.join(FIGURE_KINDS)}",
                    )
                elif kind in kinds:
                    errors.add("output.figures", f"figure kind {kind!r} is listed twice")
                elif fit is not None and figure_misfit(kind, fit) is not None:
                    errors.add("output.figures", str(figure_misfit(kind, fit)))
                else:
                    kinds.append(kind)
            figures = tuple(kinds)
    output = None
    if "file" in table:
        raw = table["file"]
        if not isinstance(raw, str) or not raw.strip():
            errors.add("output.file", f"expected a non-empty file name such as \"results/study.nc\", got {raw!r}")
        elif raw.endswith(("/", "\\")):
            errors.add("output.file", f"{raw!r} is a directory: give the archive's file name, e.g. \"{raw}study.nc\"")
        else:
            output = raw
    return figures, output


def spectrum_option(data: Mapping[str, Any], errors: FieldErrors, figures: tuple[str, ...], system: Any) -> bool:
    """``[output] spectrum``: store the dynamic spectrum at every state (a system with
    inertia); on by default where a figure draws it."""
    table = data.get("output") if isinstance(data.get("output"), dict) else {}
    wanted = any(kind in SPECTRUM_FIGURES for kind in figures)
    value = table.get("spectrum", wanted)
    if not isinstance(value, bool):
        errors.add("output.spectrum", f"expected true or false, got {toml_type(value)} ({value!r})")
        return False
    if wanted and not value:
        errors.add("output.spectrum", f"figure kinds {', '.join(SPECTRUM_FIGURES)} draw the spectrum: it cannot be false")
    if value and isinstance(system, SystemSpec) and system.definition.mass is None:
        errors.add("output.spectrum", f"system {system.name!r} declares no inertia: it has no dynamic spectrum")
        return False
    return value


def check_stages_do_something(
    programme: LoadingProgramme, parameters: Mapping[str, Any], errors: FieldErrors
) -> None:
    """A study known, from the file alone, to compute nothing or to fail every case is an error.

    Known from the file (:func:`~ncstab.studies.stage_extent.stage_extents`):
    from rest every displacement and force is 0, and a stage that ends leaves
    its driven quantity at its target and its held ones at their values.
    Refused: a programme whose every linear stage drives its quantity to the
    value it already has, in every case (the study would store no state and
    "finish"), and a cycle whose centre is the point it starts from (radius 0:
    the path engine fails every case there).  A stage that moves nothing
    among stages that do (a preload of 0) is accepted: it is skipped.
    """
    from ncstab.studies.stage_extent import stage_extents

    if programme.dynamic is not None:  # a dynamic stage computes a motion, wherever the others leave the cases
        return
    extents = stage_extents(programme.stages, parameters)
    linear = []
    for number, (stage, extent) in enumerate(zip(programme.stages, extents), 1):
        where = "at rest" if number == 1 else f"where stage {number - 1} leaves it"
        if not isinstance(stage, CycleStage):
            linear.append((number, extent, where))
        elif extent.does_nothing:
            start = ", ".join(f"{extent.start[d]:g}" for d in extent.driven.split(","))
            errors.add(
                f"loading[{number}].cycle.center",
                f"the centre is the point the cycle starts from ([{start}], {where}): a circle of radius 0; "
                "give a centre away from it",
            )
    if linear and len(linear) == len(extents) and all(extent.does_nothing for _, extent, _ in linear):
        number, extent, where = linear[0]
        name = extent.driven
        others = " and so does every later stage" if len(linear) > 1 else ""
        errors.add(
            f"loading[{number}].drive.{name}",
            f"drives {name} to {extent.start[name]:g}, the value it already has ({where}){others}: the study "
            "would compute nothing; give another target",
        )


def _is_assembled(definition: Any) -> bool:
    """Whether the system is assembled from elements (imported here: the 28 ms of the elements'
    modules are paid only by a study that has such a system, which imported them already)."""
    from ncstab.systems.assembled import is_assembled

    return is_assembled(definition)
