"""Study files (TOML) read and validated into a :class:`Study`.

A study file says which system, which laws, which parameters (a list is a sweep
dimension), which loading programme, which engine options and which figures
(``docs/study-files.md``).  :func:`parse_study` checks the whole file before any
computation and reports *every* error it finds at once, each naming the file,
the field (``parameters.gamma``, ``loading[2].hold.F2``) and what is allowed,
in one :class:`StudyFileError`.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
import re
import tomllib
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path as FilePath
from typing import Any

import sympy as sp

from ncstab.laws.definition import LawDefinition, ParameterSpec
from ncstab.laws.registry import LAWS, law_definition
from ncstab.paths.options import NORMAL_MODES, SECONDARY_CONTACT_MODES, PathOptions, SystemSpec
from ncstab.paths.programme import (
    CURRENT,
    EVENTS,
    CycleStage,
    LoadingProgramme,
    ProgrammeError,
    parse_programme,
)
from ncstab.studies.expressions import ExpressionError, evaluate_expression, is_expression
from ncstab.studies.figure_fit import FigureFit, figure_fit, figure_misfit
from ncstab.systems import SYSTEMS

__all__ = [
    "DEFAULT_FIGURES",
    "DEFAULT_MAX_CASES",
    "FIGURE_KINDS",
    "SECTIONS",
    "Study",
    "StudyFileError",
    "load_study",
    "parse_study",
]

#: Sections of a study file, in the order they are documented.
SECTIONS = ("study", "system", "laws", "parameters", "loading", "options", "map", "output")
#: Figure kinds a study may ask for in ``[output] figures``: those
#: ``ncstab.plotting.FIGURE_KINDS`` draws (the cycle kinds for programmes with cycle stages).
FIGURE_KINDS = (
    "load_rotation",
    "load_displacement",
    "load_displacement_rotation",
    "stability",
    "cycle_work",
    "cycle_paths",
    "cycle_force_drift",
    "stability_diagram",
    "second_order_work_map",
    "second_order_work_polar",
    "state_map",
)
#: Figures drawn when ``[output] figures`` is not given.
DEFAULT_FIGURES = ("load_displacement", "load_rotation")
#: Most cases a study may have unless ``[options] max_cases`` (or ``--max-cases``) allows more.
DEFAULT_MAX_CASES = 1_000_000

_NAME = re.compile(r"[A-Za-z0-9_-]+")
_SYSTEM_SETTINGS = ("name", "secondary_contacts", "normal")
_STAGE_KEYS = ("hold", "drive", "stop_at", "cycle")
_CYCLE_KEYS = ("center", "turns", "direction")
_OUTPUT_KEYS = ("figures", "file")
_MAP_KEYS = ("directions", "grid")
_GRID_KEYS = ("D1", "D2")
_STUDY_KEYS = ("name", "description")

#: Secondary-contact stiffness ratio kappa (understood by the path engine for every system).
KAPPA_SPEC = ParameterSpec(
    "kappa",
    sp.Symbol("kappa", nonnegative=True),
    "secondary-contact stiffness ratio k_secondary/k_n",
    lower=0.0,
    default=1.0,
)

#: Parameters that mean nothing with normal = "rigid" (pure-shear limit, seed Eq. 60-68).
RIGID_MEANINGLESS = ("gamma", "kappa")

#: Names a free parameter may not take: dimensions, variables and coordinates of
#: the Dataset (a swept parameter becomes a coordinate), and words of the file format.
from ncstab.paths.variables import RESERVED_NAMES  # noqa: E402  (one list for follow() and study files)


class StudyFileError(ValueError):
    """A study file with errors; lists every error found, each naming its field.

    Attributes
    ----------
    path
        The study file (``"<string>"`` for text without a file).
    errors
        ``(field, message)`` pairs, e.g. ``("parameters.gamma", "... must be finite and >= 0")``.

    ``str(error)`` has one line per error: ``<file>: <field>: <message>``.
    """

    def __init__(self, path: str, errors: Sequence[tuple[str, str]]) -> None:
        self.path = str(path)
        self.errors = [(str(f), str(m)) for f, m in errors]
        super().__init__("\n".join(f"{self.path}: {f}: {m}" for f, m in self.errors))

    def __reduce__(self):  # picklable despite the custom signature
        return (type(self), (self.path, self.errors))

    @property
    def fields(self) -> list[str]:
        """The offending fields, in the order reported."""
        return [f for f, _ in self.errors]


@dataclass(frozen=True)
class Study:
    """A validated study file: everything :func:`ncstab.studies.run_study` needs.

    Attributes
    ----------
    name
        ``[study] name``; the default archive is ``results/<name>.nc``.
    description
        ``[study] description`` (``""`` if not given).
    path
        The file it was read from, or ``None``.
    text
        The whole file text (kept in the archive as provenance).
    system
        System, secondary-contact mode and normal mode.
    laws
        Law names (the ``law`` dimension), with modifiers.
    parameters
        ``name -> float`` (fixed) or ``name -> list[float]`` (a sweep dimension),
        in file order: those of ``[system]`` first, then ``[parameters]``.
    programme
        The loading programme.
    options
        Engine options (``[options]`` over the defaults of :class:`PathOptions`).
    figures
        Figure kinds to draw (:data:`FIGURE_KINDS`).
    output
        ``[output] file``, or ``None`` for ``results/<name>.nc``.
    map
        ``[map]``: second-order work maps to add, or ``None``.
    max_cases
        ``[options] max_cases``: the most cases ``ncstab run`` runs
        (:data:`DEFAULT_MAX_CASES` unless given).
    """

    name: str
    description: str
    path: str | None
    text: str
    system: SystemSpec
    laws: tuple[str, ...]
    parameters: dict[str, float | list[float]]
    programme: LoadingProgramme
    options: PathOptions
    figures: tuple[str, ...] = DEFAULT_FIGURES
    output: str | None = None
    map: "StudyMap | None" = None
    max_cases: int = DEFAULT_MAX_CASES

    @property
    def sweep(self) -> dict[str, list[float]]:
        """The swept parameters (sweep dimensions after ``law``), in order."""
        return {k: v for k, v in self.parameters.items() if isinstance(v, list)}

    @property
    def n_cases(self) -> int:
        """Number of cases: laws times the product of the sweep lengths."""
        return len(self.laws) * math.prod(len(v) for v in self.sweep.values())


# --- helpers ------------------------------------------------------------------------------------


class _Errors:
    """Collects ``(field, message)`` pairs in the order they are found."""

    def __init__(self) -> None:
        self.items: list[tuple[str, str]] = []

    def add(self, field: str, message: str) -> None:
        if (field, message) not in self.items:
            self.items.append((field, message))

    def __len__(self) -> int:
        return len(self.items)


def _toml_type(value: Any) -> str:
    if isinstance(value, bool):
        return "a boolean"
    if isinstance(value, int):
        return "an integer"
    if isinstance(value, float):
        return "a float"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, list):
        return "an array"
    if isinstance(value, dict):
        return "a table"
    return f"a {type(value).__name__}"  # dates and times


def _hint(name: str, choices: Iterable[str]) -> str:
    close = difflib.get_close_matches(name, list(choices), n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


def _check_keys(table: Mapping[str, Any], allowed: Sequence[str], prefix: str, errors: _Errors, what: str) -> None:
    for key in table:
        if key not in allowed:
            errors.add(
                f"{prefix}.{key}",
                f"unknown key {key!r}{_hint(key, allowed)}; {what} takes: {', '.join(allowed)}",
            )


def _number(value: Any, field: str, errors: _Errors) -> float | None:
    """A finite number from a TOML number or an expression string (``None`` on error)."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        errors.add(field, f"expected a number or an expression string such as \"pi/4\", got {_toml_type(value)} ({value!r})")
        return None
    if isinstance(value, str):
        try:
            return evaluate_expression(value)
        except ExpressionError as error:
            errors.add(field, str(error))
            return None
    if not math.isfinite(value):
        errors.add(field, f"{value} is not finite; give a finite number")
        return None
    try:
        return float(value)
    except OverflowError:  # an integer too large for a float
        errors.add(field, f"{value} is too large for a floating-point number")
        return None


def _table(data: Mapping[str, Any], name: str, errors: _Errors) -> dict[str, Any] | None:
    value = data.get(name)
    if value is None:
        return None
    if not isinstance(value, dict):
        errors.add(name, f"expected a [{name}] table, got {_toml_type(value)}")
        return None
    return value


# --- sections ------------------------------------------------------------------------------------


def _study_section(data: Mapping[str, Any], errors: _Errors) -> tuple[str, str]:
    table = _table(data, "study", errors)
    if table is None:
        if "study" not in data:
            errors.add("study.name", "missing: give [study] name = \"...\" (letters, digits, _ and -)")
        return "", ""
    _check_keys(table, _STUDY_KEYS, "study", errors, "[study]")
    name = table.get("name")
    if name is None:
        errors.add("study.name", "missing: give a name (letters, digits, _ and -), used for the archive file name")
        name = ""
    elif not isinstance(name, str):
        errors.add("study.name", f"expected a string, got {_toml_type(name)}")
        name = ""
    elif not _NAME.fullmatch(name):
        errors.add(
            "study.name",
            f"{name!r} is not allowed: use only letters, digits, '_' and '-' (it names the archive file)",
        )
    description = table.get("description", "")
    if not isinstance(description, str):
        errors.add("study.description", f"expected a string, got {_toml_type(description)}")
        description = ""
    return name, description


def _system_section(
    data: Mapping[str, Any], errors: _Errors, law_parameters: set[str]
) -> tuple[SystemSpec, type | None, dict[str, Any]]:
    """SystemSpec, the system class (``None`` if unknown) and the raw parameters given there."""
    table = _table(data, "system", errors) or {}
    settings: dict[str, str] = {}
    name = table.get("name", "diamond")
    system_class = None
    if not isinstance(name, str):
        errors.add("system.name", f"expected a string, got {_toml_type(name)}; systems are: {', '.join(SYSTEMS)}")
    elif name not in SYSTEMS:
        errors.add("system.name", f"unknown system {name!r}{_hint(name, SYSTEMS)}; systems are: {', '.join(SYSTEMS)}")
    else:
        system_class = SYSTEMS[name]
        settings["name"] = name
    for key, allowed in (("secondary_contacts", SECONDARY_CONTACT_MODES), ("normal", NORMAL_MODES)):
        if key not in table:
            continue
        value = table[key]
        if not isinstance(value, str) or value not in allowed:
            shown = repr(value) if isinstance(value, str) else _toml_type(value)
            hint = _hint(value, allowed) if isinstance(value, str) else ""
            errors.add(f"system.{key}", f"{shown} is not allowed{hint}; allowed: {', '.join(allowed)}")
        else:
            settings[key] = value
    spec = SystemSpec(**settings)

    system_parameters = _system_parameter_names(system_class)
    parameters: dict[str, Any] = {}
    allowed_keys = list(_SYSTEM_SETTINGS) + system_parameters
    for key, value in table.items():
        if key in _SYSTEM_SETTINGS:
            continue
        if key in system_parameters:
            if isinstance(value, list):
                errors.add(
                    f"system.{key}",
                    f"a sweep (list) belongs in [parameters]: move {key} = {value!r} there",
                )
                continue
            parameters[key] = value
        elif key in law_parameters:
            errors.add(f"system.{key}", f"{key!r} is a law parameter: give it in [parameters]")
        else:
            errors.add(
                f"system.{key}",
                f"unknown key {key!r}{_hint(key, allowed_keys)}; [system] takes: {', '.join(allowed_keys)}",
            )
    return spec, system_class, parameters


def _system_parameter_names(system_class: type | None) -> list[str]:
    classes = [system_class] if system_class is not None else list(SYSTEMS.values())
    names: list[str] = []
    for cls in classes:
        names += [p.name for p in cls.parameter_specs if p.name not in names]  # type: ignore[attr-defined]
    return names + ["kappa"]


def _laws_section(data: Mapping[str, Any], errors: _Errors) -> tuple[list[str], list[LawDefinition], bool]:
    """Valid law names, their definitions, and whether every name given was valid."""
    table = _table(data, "laws", errors)
    if table is None:
        if "laws" not in data:
            errors.add("laws.names", f"missing: give [laws] names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], False
    _check_keys(table, ("names",), "laws", errors, "[laws]")
    names = table.get("names")
    if names is None:
        errors.add("laws.names", f"missing: give names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], False
    if not isinstance(names, list):
        errors.add(
            "laws.names",
            f"expected an array of law names such as [\"mcnamara\"], got {_toml_type(names)}; "
            f"the catalogue has: {', '.join(LAWS)}",
        )
        return [], [], False
    if not names:
        errors.add("laws.names", f"give at least one law; the catalogue has: {', '.join(LAWS)}")
        return [], [], False
    valid: list[str] = []
    definitions: list[LawDefinition] = []
    all_valid = True
    seen: set[str] = set()
    for name in names:
        if not isinstance(name, str):
            errors.add("laws.names", f"expected law names (strings), got {_toml_type(name)} ({name!r})")
            all_valid = False
            continue
        if name in seen:
            errors.add("laws.names", f"law {name!r} is listed twice; list each law once")
            continue
        seen.add(name)
        try:
            definitions.append(law_definition(name))
        except ValueError as error:
            errors.add("laws.names", str(error))
            all_valid = False
            continue
        valid.append(name)
    return valid, definitions, all_valid


def _parameter_specs(
    definitions: Sequence[LawDefinition], all_laws_valid: bool, system_class: type | None
) -> dict[str, ParameterSpec]:
    """Specification of every law, system and engine parameter the study may set."""
    laws = definitions if all_laws_valid else list(definitions) + list(LAWS.values())
    specs: dict[str, ParameterSpec] = {}
    for definition in laws:
        for spec in definition.parameters:
            specs.setdefault(spec.name, spec)
    classes = [system_class] if system_class is not None else list(SYSTEMS.values())
    for cls in classes:
        for spec in cls.parameter_specs:  # type: ignore[attr-defined]
            specs.setdefault(spec.name, spec)
    specs["kappa"] = KAPPA_SPEC
    return specs


def _parameter_value(
    value: Any, field: str, errors: _Errors, allow_sweep: bool = True
) -> float | list[float] | None:
    """A number or a non-empty list of distinct numbers, or ``None`` on error."""
    if isinstance(value, list):
        if not allow_sweep:
            errors.add(field, "a sweep (list) belongs in [parameters]")
            return None
        if not value:
            errors.add(field, "an empty sweep has no cases: give at least one value, or a single number")
            return None
        values: list[float] = []
        ok = True
        for k, element in enumerate(value, start=1):
            if isinstance(element, list):
                errors.add(field, f"element {k} is an array: a sweep is a flat list of numbers")
                ok = False
                continue
            number = _number(element, field, errors)
            if number is None:
                ok = False
            else:
                values.append(number)
        if not ok:
            return None
        duplicated = sorted({v for v in values if values.count(v) > 1})
        if duplicated:
            errors.add(
                field,
                f"value(s) {', '.join(f'{v:g}' for v in duplicated)} appear more than once in the sweep; "
                "give each value once",
            )
            return None
        return values
    return _number(value, field, errors)


def _validate_range(value: float | list[float], spec: ParameterSpec, field: str, errors: _Errors) -> bool:
    try:
        spec.validate(value)
    except ValueError as error:
        errors.add(field, str(error))
        return False
    return True


# --- loading -------------------------------------------------------------------------------------


def _stage_value(
    value: Any, field: str, errors: _Errors, references: dict[str, list[str]]
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
            f"expected a number, an expression, a parameter name or \"current\", got {_toml_type(value)} ({value!r})",
        )
        return 0.0
    number = _number(value, field, errors)
    return 0.0 if number is None else number


def _programme_message(error: ProgrammeError) -> str:
    text = str(error)
    for stage in (error.stage, 1):
        where = f"loading stage {stage}" if stage is not None else "loading programme"
        prefix = f"{where}, field {error.field!r}: "
        if text.startswith(prefix):
            return text[len(prefix):]
    return text


def _stop_at(value: Any, field: str, errors: _Errors) -> list[str]:
    if isinstance(value, str):
        value = [value]
    if not isinstance(value, list):
        errors.add(field, f"expected an array of event names, got {_toml_type(value)}; events are: {', '.join(EVENTS)}")
        return []
    valid = []
    for name in value:
        if not isinstance(name, str):
            errors.add(field, f"expected event names (strings), got {_toml_type(name)}; events are: {', '.join(EVENTS)}")
        elif name not in EVENTS:
            errors.add(field, f"unknown event {name!r}{_hint(name, EVENTS)}; events are: {', '.join(EVENTS)}")
        else:
            valid.append(name)
    return valid


def _stage(
    raw: Mapping[str, Any], prefix: str, errors: _Errors, references: dict[str, list[str]], forces: Sequence[str]
) -> tuple[dict[str, Any], bool]:
    """A stage table with expressions evaluated, and whether its structure can be checked.

    Unknown keys and invalid events are reported and left out, bad values are
    reported and replaced by 0.0, so that :func:`parse_programme` can still
    check the rest of the stage (controlled twice, nothing driven...) without
    reporting the same error twice.  A stage whose ``hold``/``drive``/``cycle``
    is not a table is not checked further (every later error would follow from it).
    """
    _check_keys(raw, _STAGE_KEYS, prefix, errors, "a stage")
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
                f"expected a table {{center = [D1, D2], turns = n, direction = 1 or -1}}, got {_toml_type(cycle)}",
            )
            checkable = False
        else:
            _check_keys(cycle, _CYCLE_KEYS, f"{prefix}.cycle", errors, "a cycle")
            stage["cycle"] = {k: v for k, v in cycle.items() if k in _CYCLE_KEYS}
            center = cycle.get("center")
            if isinstance(center, list):
                field = f"{prefix}.cycle.center"
                stage["cycle"]["center"] = [_stage_value(c, field, errors, references) for c in center]
    else:
        for key in ("hold", "drive"):
            table = raw.get(key, {})
            if not isinstance(table, dict):
                errors.add(
                    f"{prefix}.{key}",
                    f"expected a table of quantity = value such as {{ {forces[0]} = 0.0 }}, got {_toml_type(table)}",
                )
                checkable = False
            elif key in raw:
                stage[key] = {q: _stage_value(v, f"{prefix}.{key}.{q}", errors, references) for q, v in table.items()}
    if "stop_at" in raw:
        stage["stop_at"] = _stop_at(raw["stop_at"], f"{prefix}.stop_at", errors)
    return stage, checkable


def _loading_section(
    data: Mapping[str, Any], errors: _Errors, system_class: type | None
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
    dofs = tuple(getattr(system_class, "dof_names", ("D1", "D2")))
    forces = tuple(getattr(system_class, "force_names", ("F1", "F2")))
    clean: list[dict[str, Any]] = []
    before = len(errors)
    for number, raw in enumerate(stages, start=1):
        prefix = f"loading[{number}]"
        if not isinstance(raw, dict):
            errors.add(prefix, f"expected a table (hold = {{...}}, drive = {{...}}), got {_toml_type(raw)}")
            continue
        stage, checkable = _stage(raw, prefix, errors, references, forces)
        if not checkable:
            continue
        try:  # one stage at a time, so that every stage's errors are reported
            parse_programme([stage], dofs, forces)
        except ProgrammeError as error:
            field = prefix if error.field in ("", "loading") else f"{prefix}.{error.field}"
            errors.add(field, _programme_message(error))
            continue
        clean.append(stage)
    if len(errors) > before:
        return None, references
    try:
        return parse_programme(clean, dofs, forces), references
    except ProgrammeError as error:  # pragma: no cover - every stage passed alone
        errors.add("loading", _programme_message(error))
        return None, references


# --- options and output --------------------------------------------------------------------------

_OPTION_FIELDS = {f.name: f for f in dataclasses.fields(PathOptions)}
_OPTION_NAME = re.compile(r"PathOptions\.(\w+)")


def _options_section(data: Mapping[str, Any], errors: _Errors) -> tuple[PathOptions, int]:
    """Engine options (:class:`PathOptions`) and the study's ``max_cases``."""
    table = _table(data, "options", errors) or {}
    _check_keys(table, [*_OPTION_FIELDS, "max_cases"], "options", errors, "[options]")
    max_cases = DEFAULT_MAX_CASES
    if "max_cases" in table:
        raw = table["max_cases"]
        if isinstance(raw, bool) or not isinstance(raw, int) or raw < 1:
            errors.add("options.max_cases", f"expected a whole number >= 1 (the most cases to run), got {raw!r}")
        else:
            max_cases = raw
    values: dict[str, Any] = {}
    for name, raw in table.items():
        if name not in _OPTION_FIELDS:
            continue
        field = f"options.{name}"
        kinds = str(_OPTION_FIELDS[name].type).split(" | ")  # e.g. ["float", "str"]: a number or a word
        if isinstance(raw, str) and "str" in kinds:
            value: Any = raw  # which words are allowed: PathOptions says
        elif kinds == ["str"]:
            errors.add(field, f"expected a string, got {_toml_type(raw)} ({raw!r})")
            continue
        elif kinds == ["int"]:
            if isinstance(raw, bool) or not isinstance(raw, int):
                errors.add(field, f"expected a whole number, got {_toml_type(raw)} ({raw!r})")
                continue
            value = raw
        else:
            value = _number(raw, field, errors)
            if value is None:
                continue
        try:
            PathOptions(**{name: value})
        except ValueError as error:
            match = _OPTION_NAME.search(str(error))
            if match is None or match.group(1) == name:
                errors.add(field, str(error))
                continue
        values[name] = value
    try:
        return PathOptions(**values), max_cases
    except ValueError as error:
        match = _OPTION_NAME.search(str(error))
        errors.add(f"options.{match.group(1)}" if match else "options", str(error))
        return PathOptions(), max_cases


@dataclass(frozen=True)
class StudyMap:
    """The ``[map]`` section: second-order work maps to add to the archive.

    Attributes
    ----------
    directions
        Number of loading directions theta in [0, pi) for ``d2W_dir`` along the
        paths (and the unstable cone per step), or ``None``.
    grid
        ``((D1 min, D1 max, n1), (D2 min, D2 max, n2))``: a state map of the
        indicators over the displacement plane (laws with a total form), or
        ``None``.
    """

    directions: int | None = None
    grid: tuple[tuple[float, float, int], tuple[float, float, int]] | None = None


def _map_section(data: Mapping[str, Any], errors: _Errors) -> StudyMap | None:
    table = _table(data, "map", errors)
    if table is None:
        return None
    _check_keys(table, _MAP_KEYS, "map", errors, "[map]")
    directions = None
    if "directions" in table:
        raw = table["directions"]
        if isinstance(raw, bool) or not isinstance(raw, int) or not 4 <= raw <= 100_000:
            errors.add("map.directions", f"expected a whole number of directions from 4 to 100000, got {raw!r}")
        else:
            directions = raw
    grid = None
    if "grid" in table:
        raw = table["grid"]
        if not isinstance(raw, dict):
            errors.add("map.grid", "expected a table { D1 = [min, max, n], D2 = [min, max, n] }")
        else:
            _check_keys(raw, _GRID_KEYS, "map.grid", errors, "[map] grid")
            axes = []
            for key in _GRID_KEYS:
                field = f"map.grid.{key}"
                spec = raw.get(key)
                if not isinstance(spec, list) or len(spec) != 3:
                    errors.add(field, f"expected [min, max, n] for {key}, got {spec!r}")
                    continue
                low, high = _number(spec[0], field, errors), _number(spec[1], field, errors)
                count = spec[2]
                if isinstance(count, bool) or not isinstance(count, int) or not 2 <= count <= 2000:
                    errors.add(field, f"the number of grid points must be a whole number from 2 to 2000, got {count!r}")
                    continue
                if low is None or high is None:
                    continue
                if not low < high:
                    errors.add(field, f"expected min < max, got [{low:g}, {high:g}]")
                    continue
                axes.append((low, high, count))
            if len(axes) == 2:
                grid = (axes[0], axes[1])
    if directions is None and grid is None and not errors.items:
        errors.add("map", "an empty [map] section: give directions, a grid, or both")
    return StudyMap(directions, grid)


def _output_section(
    data: Mapping[str, Any], errors: _Errors, fit: FigureFit | None = None
) -> tuple[tuple[str, ...], str | None]:
    """Figure kinds and archive file; a kind the study cannot draw (``fit``) is an error."""
    table = _table(data, "output", errors) or {}
    _check_keys(table, _OUTPUT_KEYS, "output", errors, "[output]")
    figures: tuple[str, ...] = DEFAULT_FIGURES
    if "figures" in table:
        raw = table["figures"]
        if not isinstance(raw, list):
            errors.add("output.figures", f"expected an array of figure kinds, got {_toml_type(raw)}; kinds are: {', '.join(FIGURE_KINDS)}")
        else:
            kinds: list[str] = []
            for kind in raw:
                if not isinstance(kind, str):
                    errors.add("output.figures", f"expected figure kinds (strings), got {_toml_type(kind)}; kinds are: {', '.join(FIGURE_KINDS)}")
                elif kind not in FIGURE_KINDS:
                    errors.add(
                        "output.figures",
                        f"unknown figure kind {kind!r}{_hint(kind, FIGURE_KINDS)}; kinds are: {', '.join(FIGURE_KINDS)}",
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


# --- the whole file ------------------------------------------------------------------------------


def _unknown_sections(data: Mapping[str, Any], errors: _Errors) -> None:
    for key, value in data.items():
        if key in SECTIONS:
            continue
        if isinstance(value, dict):
            errors.add(key, f"unknown section [{key}]{_hint(key, SECTIONS)}; sections are: {', '.join(SECTIONS)}")
        elif isinstance(value, list) and value and all(isinstance(v, dict) for v in value):
            errors.add(key, f"unknown section [[{key}]]{_hint(key, SECTIONS)}; sections are: {', '.join(SECTIONS)}")
        else:
            errors.add(
                key,
                f"key {key!r} is outside any section{_hint(key, SECTIONS)}; keys belong in one of the sections: "
                + ", ".join(f"[{s}]" for s in SECTIONS),
            )


def _parameters(
    data: Mapping[str, Any],
    errors: _Errors,
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
        value = _parameter_value(raw, fields[key], errors, allow_sweep=False)
        if value is not None:
            parameters[key] = value
    for key, raw in (_table(data, "parameters", errors) or {}).items():
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
        value = _parameter_value(raw, field, errors)
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
        elif key in specs and not _validate_range(value, specs[key], fields[key], errors):
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


def _check_references(
    errors: _Errors,
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
                    f"refers to undefined parameter {reference!r}{_hint(reference, fields)}; "
                    f"defined parameters: {', '.join(fields) or 'none'} (give it in [parameters])",
                )
    for key in fields:
        if key in free and key not in references:
            errors.add(
                fields[key],
                f"parameter {key!r} is unused{_hint(key, known)}: it is not a parameter of the system or the "
                f"laws ({', '.join(known)}) and no loading stage refers to it",
            )


def _check_law_spellings(names: Sequence[str], definitions: Sequence[LawDefinition], errors: _Errors) -> None:
    """Two names of ``[laws] names`` that spell the same law (``turco+no_tension``, ``turco + no_tension``)."""
    seen: dict[str, str] = {}
    for name, definition in zip(names, definitions):
        if definition.name in seen:
            errors.add(
                "laws.names",
                f"{seen[definition.name]!r} and {name!r} are the same law ({definition.name}); list it once",
            )
        else:
            seen[definition.name] = name


def _check_stages_do_something(
    programme: LoadingProgramme, parameters: Mapping[str, Any], errors: _Errors
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


def _error_order(error: tuple[str, str]) -> tuple[int, int]:
    """Sort key: the section's place in :data:`SECTIONS` (unknown ones last), then the stage."""
    head = re.split(r"[.\[]", error[0], maxsplit=1)[0]
    stage = re.match(r"loading\[(\d+)\]", error[0])
    return (SECTIONS.index(head) if head in SECTIONS else len(SECTIONS), int(stage.group(1)) if stage else 0)


def _decode_toml(text: str, source: str) -> dict[str, Any]:
    """The TOML text as a table; any text that is not valid TOML is one :class:`StudyFileError`.

    Besides syntax errors: an integer of more digits than Python converts
    (``sys.get_int_max_str_digits()``, 4300), and nesting deeper than the
    parser's recursion allows (``[[[[...`` 100,000 deep).
    """
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        message = str(error)
        if message.endswith("(at end of document)"):
            message = message[: -1] + f", line {text.count(chr(10)) + 1})"
        raise StudyFileError(source, [("toml", f"invalid TOML: {message}")]) from None
    except RecursionError:
        raise StudyFileError(
            source, [("toml", "invalid TOML: arrays or tables nested too deeply for a study file")]
        ) from None
    except ValueError as error:  # an integer too long to convert ("Exceeds the limit (4300 digits)...")
        first = str(error).split(";")[0]
        raise StudyFileError(source, [("toml", f"invalid TOML: a number too long to read ({first})")]) from None


def parse_study(text: str, path: str | None = None) -> Study:
    """Validate the text of a study file into a :class:`Study`.

    Parameters
    ----------
    text
        The TOML text.
    path
        The file it comes from, for error messages and :attr:`Study.path`.

    Raises
    ------
    StudyFileError
        Listing every error of the file, section by section (after a TOML
        syntax error, only that one: nothing else can be read).
    """
    source = str(path) if path is not None else "<string>"
    data = _decode_toml(text, source)
    errors = _Errors()
    _unknown_sections(data, errors)
    name, description = _study_section(data, errors)
    laws, definitions, all_laws_valid = _laws_section(data, errors)
    _check_law_spellings(laws, definitions, errors)
    law_only = {p.name for d in (definitions if all_laws_valid else LAWS.values()) for p in d.parameters}
    law_only -= set(_system_parameter_names(None))
    system, system_class, system_raw = _system_section(data, errors, law_only)
    specs = _parameter_specs(definitions, all_laws_valid, system_class)
    parameters, fields, free = _parameters(data, errors, system, system_raw, specs, definitions)
    programme, references = _loading_section(data, errors, system_class)
    known = [k for k in specs if not (system.normal == "rigid" and k in RIGID_MEANINGLESS)]
    _check_references(errors, references, fields, free, known)
    options, max_cases = _options_section(data, errors)
    study_map = _map_section(data, errors)
    fit = None if errors.items else figure_fit(programme, parameters, study_map, definitions, system)
    figures, output = _output_section(data, errors, fit)
    if not errors.items and programme is not None:
        _check_stages_do_something(programme, parameters, errors)

    if errors.items or programme is None:
        if not errors.items:  # pragma: no cover - a missing programme always reports why
            errors.add("loading", "no valid loading programme")
        raise StudyFileError(source, sorted(errors.items, key=_error_order))
    return Study(
        name=name,
        description=description,
        path=str(path) if path is not None else None,
        text=text,
        system=system,
        laws=tuple(laws),
        parameters=parameters,
        programme=programme,
        options=options,
        figures=figures,
        output=output,
        map=study_map,
        max_cases=max_cases,
    )


def load_study(path: str | FilePath) -> Study:
    """Read and validate a study file.

    Raises
    ------
    StudyFileError
        Listing every error of the file, each with its field.
    OSError
        If the file cannot be read.
    """
    path = FilePath(path)
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError as error:
        raise StudyFileError(str(path), [("toml", f"the file is not UTF-8 text ({error})")]) from None
    return parse_study(text, str(path))

