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

import numpy as np
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
from ncstab.studies.user_laws import user_laws_from_tables
from ncstab.systems import SYSTEMS, SystemDefinition, SystemKind

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
    "root_locus",
    "frequencies",
    "damping_map",
)
#: Figures drawn when ``[output] figures`` is not given.
DEFAULT_FIGURES = ("load_displacement", "load_rotation")
#: Most cases a study may have unless ``[options] max_cases`` (or ``--max-cases``) allows more.
DEFAULT_MAX_CASES = 1_000_000

_NAME = re.compile(r"[A-Za-z0-9_-]+")
_SYSTEM_SETTINGS = ("name", "secondary_contacts", "normal")
#: Structural settings of every shipped system (when the system itself is unknown).
_ALL_SETTINGS = ("reduction", "grains", "links", "load")
_STAGE_KEYS = ("hold", "drive", "stop_at", "cycle", "at_bifurcation")
_CYCLE_KEYS = ("center", "turns", "direction", "dofs")
_OUTPUT_KEYS = ("figures", "file", "spectrum")
#: Figure kinds drawn from the dynamic spectrum (which they store).
SPECTRUM_FIGURES = ("root_locus", "frequencies")
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
        System, secondary-contact mode and normal mode (a :class:`SystemSpec`),
        or, for a study built in Python, any
        :class:`~ncstab.systems.SystemDefinition` (then followed with
        secondary contacts activated); it reaches the workers of a chunked or
        dask run as a value.
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
        The ``[map]`` section, or ``None``.
    user_laws
        The laws of the ``[laws.<name>]`` tables (:func:`ncstab.laws.user_law`),
        without modifiers; :meth:`law_definition` resolves any of :attr:`laws`.
        ``[map]``: second-order work maps to add, or ``None``.
    max_cases
        ``[options] max_cases``: the most cases ``ncstab run`` runs
        (:data:`DEFAULT_MAX_CASES` unless given).
    """

    name: str
    description: str
    path: str | None
    text: str
    system: "SystemSpec | SystemDefinition"
    laws: tuple[str, ...]
    parameters: dict[str, float | list[float]]
    programme: LoadingProgramme
    options: PathOptions
    figures: tuple[str, ...] = DEFAULT_FIGURES
    output: str | None = None
    map: "StudyMap | None" = None
    spectrum: bool = False
    user_laws: tuple[LawDefinition, ...] = ()

    def law_definition(self, name: str) -> LawDefinition:
        """The definition of one of :attr:`laws` (a user law of the file or a catalogue law)."""
        return law_definition(name, {definition.name: definition for definition in self.user_laws})

    @property
    def law_definitions(self) -> tuple[LawDefinition, ...]:
        """The definitions of :attr:`laws`, in order: what every run mode follows."""
        return tuple(self.law_definition(name) for name in self.laws)
    max_cases: int = DEFAULT_MAX_CASES

    @property
    def sweep(self) -> dict[str, list[float]]:
        """The swept parameters (sweep dimensions after ``law``), in order."""
        return {k: v for k, v in self.parameters.items() if isinstance(v, list)}

    def model(self, law: str | None = None):
        """The :class:`~ncstab.paths.api.Model` of the study (of one of its laws)."""
        from ncstab.paths.api import resolve_model

        names = list(self.laws) if law is None else [law]
        return resolve_model(self.system, [self.law_definition(name) for name in names] or None)

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
) -> tuple[SystemSpec, SystemKind | None, dict[str, Any]]:
    """SystemSpec, the system's kind (``None`` if unknown or its settings are bad) and
    the raw parameters given there (shorthands such as ``damping = [b1, b2]`` expanded)."""
    table = _table(data, "system", errors) or {}
    settings: dict[str, Any] = {}
    name = table.get("name", "diamond")
    kind = None
    if not isinstance(name, str):
        errors.add("system.name", f"expected a string, got {_toml_type(name)}; systems are: {', '.join(SYSTEMS)}")
    elif name not in SYSTEMS:
        errors.add("system.name", f"unknown system {name!r}{_hint(name, SYSTEMS)}; systems are: {', '.join(SYSTEMS)}")
    else:
        kind = SYSTEMS[name]
        settings["name"] = name
    for key, allowed in (("secondary_contacts", SECONDARY_CONTACT_MODES), ("normal", NORMAL_MODES)):
        if key not in table:
            continue
        value = table[key]
        if kind is not None and not kind.granular:
            errors.add(f"system.{key}", f"system {name!r} has no grains in contact: {key} does not apply to it")
        elif not isinstance(value, str) or value not in allowed:
            shown = repr(value) if isinstance(value, str) else _toml_type(value)
            hint = _hint(value, allowed) if isinstance(value, str) else ""
            errors.add(f"system.{key}", f"{shown} is not allowed{hint}; allowed: {', '.join(allowed)}")
        else:
            settings[key] = value
    structural = kind.setting_names() if kind is not None else _ALL_SETTINGS
    for key in structural:
        if key in table:
            settings[key] = table[key]
    if kind is not None:
        for setting in kind.settings:
            value = settings.get(setting.name, setting.default)
            problem = "missing" if value is None else setting.check(value)
            if problem == "missing":
                errors.add(f"system.{setting.name}", f"missing: system {name!r} needs {setting.name} ({setting.description})")
                kind = None
            elif problem is not None:
                shown = repr(value) if isinstance(value, (str, int, float)) else _toml_type(value)
                errors.add(f"system.{setting.name}", f"{setting.name} = {shown} is not allowed for system {name!r}: give {problem}")
                kind = None
    spec = SystemSpec()
    if kind is not None:
        try:
            spec = SystemSpec(**settings)
        except ValueError as error:  # normal = "rigid" where there is no pure-shear limit
            errors.add("system.normal", str(error))
            kind = None

    system_parameters = _system_parameter_names(kind)
    shorthands = dict(kind.shorthands) if kind is not None else {}
    parameters: dict[str, Any] = {}
    allowed_keys = list(_SYSTEM_SETTINGS) + list(structural) + list(shorthands) + system_parameters
    for key, value in table.items():
        if key in _SYSTEM_SETTINGS or key in structural:
            continue
        if key in shorthands:
            targets = shorthands[key]
            if not isinstance(value, list) or len(value) != len(targets):
                errors.add(
                    f"system.{key}",
                    f"expected [{', '.join(targets)}] (a list of {len(targets)} numbers), got {value!r}; "
                    f"to sweep them, give {', '.join(targets)} in [parameters]",
                )
                continue
            for target, element in zip(targets, value):
                parameters[target] = element
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
    return spec, kind, parameters


def _system_parameter_names(kind: SystemKind | None) -> list[str]:
    kinds = [kind] if kind is not None else list(SYSTEMS.values())
    names: list[str] = []
    for k in kinds:
        names += [p.name for p in k.parameter_specs if p.name not in names]
    if kind is None or kind.granular:
        names.append("kappa")
    return names


def _laws_section(
    data: Mapping[str, Any], errors: _Errors, optional: bool = False
) -> tuple[list[str], list[LawDefinition], bool, dict[str, LawDefinition]]:
    """Valid law names, their definitions, whether every name given was valid, and the
    user laws of the ``[laws.<name>]`` tables (see :mod:`ncstab.studies.user_laws`).

    ``optional``: the system's interactions have laws of their own (a column,
    Ziegler's pendulum), so a study may leave ``[laws]`` out.
    """
    table = _table(data, "laws", errors)
    if table is None:
        if "laws" not in data and not optional:
            errors.add("laws.names", f"missing: give [laws] names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], optional and "laws" not in data, {}
    tables = {key: value for key, value in table.items() if key != "names" and isinstance(value, dict)}
    _check_keys({k: v for k, v in table.items() if k not in tables}, ("names",), "laws", errors, "[laws]")
    user_laws, invalid = user_laws_from_tables(tables, errors.add, set(_system_parameter_names(None)))
    names = table.get("names")
    if names is None:
        errors.add("laws.names", f"missing: give names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], False, user_laws
    if not isinstance(names, list):
        errors.add(
            "laws.names",
            f"expected an array of law names such as [\"mcnamara\"], got {_toml_type(names)}; "
            f"the catalogue has: {', '.join(LAWS)}",
        )
        return [], [], False, user_laws
    if not names:
        errors.add("laws.names", f"give at least one law; the catalogue has: {', '.join(LAWS)}")
        return [], [], False, user_laws
    valid: list[str] = []
    definitions: list[LawDefinition] = []
    all_valid = not invalid
    seen: set[str] = set()
    listed: set[str] = set()
    for name in names:
        if not isinstance(name, str):
            errors.add("laws.names", f"expected law names (strings), got {_toml_type(name)} ({name!r})")
            all_valid = False
            continue
        listed.add(name.split("+")[0].strip())
        if name.split("+")[0].strip() in invalid:
            continue  # its table's errors are reported
        try:
            definition = law_definition(name, user_laws)
        except ValueError as error:
            errors.add("laws.names", str(error))
            all_valid = False
            continue
        if definition.name in seen:
            errors.add("laws.names", f"law {name!r} is listed twice; list each law once")
            continue
        seen.add(definition.name)
        definitions.append(definition)
        valid.append(definition.name)
    for name in tables:
        if name not in listed:
            errors.add(
                f"laws.{name}",
                f"user law {name!r} is defined but not listed in names: add it to names = [...] or remove [laws.{name}]",
            )
    return valid, definitions, all_valid, user_laws


def _user_laws_need_a_deformable_normal(
    system: SystemSpec, user_laws: Mapping[str, LawDefinition], errors: _Errors
) -> None:
    if system.normal == "rigid":
        for name in user_laws:
            errors.add(
                f"laws.{name}",
                "user laws are not available with normal = \"rigid\" (the pure-shear limit is derived for "
                "the catalogue laws only); use normal = \"deformable\"",
            )


def _parameter_specs(
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


def _duplicates(values: Sequence[float]) -> list[float]:
    """Values that appear more than once, sorted (one pass over a set: linear time)."""
    seen: set[float] = set()
    repeated: set[float] = set()
    for value in values:
        (repeated if value in seen else seen).add(value)
    return sorted(repeated)


def _range_count(table: Mapping[str, Any], field: str, errors: _Errors) -> int | None:
    """``num`` of a range: a TOML integer from 1 to :data:`MAX_RANGE_VALUES`."""
    num = table["num"]
    if isinstance(num, bool) or not isinstance(num, int):
        errors.add(
            f"{field}.num",
            f"expected a whole number of values (a TOML integer such as 64), got {_toml_type(num)} ({num!r})",
        )
        return None
    if not 1 <= num <= MAX_RANGE_VALUES:
        errors.add(f"{field}.num", f"{num} values: a range has from 1 to {MAX_RANGE_VALUES:,} values")
        return None
    return num


def _step_values(start: float, stop: float, step: float, field: str, errors: _Errors) -> list[float] | None:
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


def _range_values(table: Mapping[str, Any], field: str, errors: _Errors) -> list[float] | None:
    """The values of a range table, or ``None`` after reporting its errors.

    ``{start, stop, num}``: ``numpy.linspace(start, stop, num)`` (endpoints
    exact); with ``scale = "log"``: ``numpy.geomspace`` (bounds > 0);
    ``{start, stop, step}``: :func:`_step_values`.  Each error names its key
    (``parameters.gamma.num``).
    """
    before = len(errors)
    _check_keys(table, RANGE_KEYS, field, errors, "a range")
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
    bounds = {key: _number(table[key], f"{field}.{key}", errors) for key in ("start", "stop") if key in table}
    num = _range_count(table, field, errors) if "num" in table else None
    step = _number(table["step"], f"{field}.step", errors) if "step" in table else None
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
        return _step_values(start, stop, step, field, errors)
    assert num is not None
    if start == stop and num > 1:
        errors.add(
            f"{field}.num",
            f"start = stop = {start:g} with num = {num}: the values would repeat; give num = 1 or two bounds",
        )
        return None
    values = np.geomspace(start, stop, num) if scale == "log" else np.linspace(start, stop, num)
    return values.tolist()


def _parameter_value(
    value: Any, field: str, errors: _Errors, allow_sweep: bool = True
) -> float | list[float] | None:
    """A number, or a sweep: a non-empty list of distinct numbers or a range table; ``None`` on error."""
    if isinstance(value, (list, dict)) and not allow_sweep:
        errors.add(field, f"a sweep ({'list' if isinstance(value, list) else 'range'}) belongs in [parameters]")
        return None
    values: list[float] | None
    if isinstance(value, dict):
        values = _range_values(value, field, errors)
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
            number = _number(element, field, errors)
            if number is None:
                ok = False
            else:
                values.append(number)
        if not ok:
            return None
    else:
        return _number(value, field, errors)
    if values is None:
        return None
    duplicated = _duplicates(values)
    if duplicated:
        shown = ", ".join(f"{v:g}" for v in duplicated[:5])
        shown += f" (and {len(duplicated) - 5} more)" if len(duplicated) > 5 else ""
        errors.add(field, f"value(s) {shown} appear more than once in the sweep; give each value once")
        return None
    return values


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
    if "at_bifurcation" in raw:
        if "cycle" in raw:
            errors.add(f"{prefix}.at_bifurcation", "a cycle stage goes on through bifurcations: at_bifurcation is for linear stages")
        else:
            stage["at_bifurcation"] = raw["at_bifurcation"]  # checked by parse_programme
    return stage, checkable


def _loading_section(
    data: Mapping[str, Any], errors: _Errors, kind: SystemKind | None, system: SystemSpec
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
    if kind is not None:
        definition = system.definition
        dofs, forces, load = definition.dofs, definition.forces, definition.load_parameter
    else:
        dofs, forces, load = ("D1", "D2"), ("F1", "F2"), None
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
            parse_programme([stage], dofs, forces, load)
        except ProgrammeError as error:
            field = prefix if error.field in ("", "loading") else f"{prefix}.{error.field}"
            errors.add(field, _programme_message(error))
            continue
        clean.append(stage)
    if len(errors) > before:
        return None, references
    try:
        return parse_programme(clean, dofs, forces, load), references
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


def _spectrum_option(data: Mapping[str, Any], errors: _Errors, figures: tuple[str, ...], system: Any) -> bool:
    """``[output] spectrum``: store the dynamic spectrum at every state (a system with
    inertia); on by default where a figure draws it."""
    table = data.get("output") if isinstance(data.get("output"), dict) else {}
    wanted = any(kind in SPECTRUM_FIGURES for kind in figures)
    value = table.get("spectrum", wanted)
    if not isinstance(value, bool):
        errors.add("output.spectrum", f"expected true or false, got {_toml_type(value)} ({value!r})")
        return False
    if wanted and not value:
        errors.add("output.spectrum", f"figure kinds {', '.join(SPECTRUM_FIGURES)} draw the spectrum: it cannot be false")
    if value and isinstance(system, SystemSpec) and system.definition.mass is None:
        errors.add("output.spectrum", f"system {system.name!r} declares no inertia: it has no dynamic spectrum")
        return False
    return value


def _check_law_kinds(errors: _Errors, definitions: Sequence[Any], system: SystemSpec) -> None:
    """Every law fits an interaction of the system; a system that needs a law has one."""
    families = system.definition.families
    kinds = {f.kind for f in families}
    for definition in definitions:
        if definition.kind not in kinds:
            errors.add(
                "laws.names",
                f"law {definition.name!r} is a {definition.kind} law; system {system.name!r} has "
                f"{' and '.join(sorted(kinds))} interactions only",
            )


def _check_fixed_parameters(data: Mapping[str, Any], errors: _Errors, kind: SystemKind | None, system: SystemSpec) -> None:
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
    named = (data.get("system") or {}).get("name", "diamond") if isinstance(data.get("system"), dict) else "diamond"
    own_laws = isinstance(named, str) and named in SYSTEMS and SYSTEMS[named].own_laws
    laws, definitions, all_laws_valid, user_laws = _laws_section(data, errors, optional=own_laws)
    _check_law_spellings(laws, definitions, errors)
    law_only = {p.name for d in (definitions if all_laws_valid else LAWS.values()) for p in d.parameters}
    law_only -= set(_system_parameter_names(None))
    system, kind, system_raw = _system_section(data, errors, law_only)
    _user_laws_need_a_deformable_normal(system, user_laws, errors)
    if kind is not None:
        _check_law_kinds(errors, definitions, system)
    specs = _parameter_specs(definitions, all_laws_valid, kind, system)
    _check_fixed_parameters(data, errors, kind, system)
    parameters, fields, free = _parameters(data, errors, system, system_raw, specs, definitions)
    programme, references = _loading_section(data, errors, kind, system)
    known = [k for k in specs if not (system.normal == "rigid" and k in RIGID_MEANINGLESS)]
    _check_references(errors, references, fields, free, known)
    options, max_cases = _options_section(data, errors)
    study_map = _map_section(data, errors)
    fit = None if errors.items else figure_fit(programme, parameters, study_map, definitions, system)
    figures, output = _output_section(data, errors, fit)
    spectrum = _spectrum_option(data, errors, figures, system)
    if not errors.items and programme is not None:
        _check_stages_do_something(programme, parameters, errors)

    if programme is not None and programme.follows_branches:
        from ncstab.paths.api import with_branches

        parameters = with_branches(programme, parameters)
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
        spectrum=spectrum,
        output=output,
        map=study_map,
        user_laws=tuple(user_laws.values()),
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

