"""The ``[study]``, ``[system]`` and ``[laws]`` sections of a study file, and the checks
that the laws fit the system (a spring law on a column, a contact law on a diamond)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

from ncstab.laws.definition import LawDefinition
from ncstab.laws.registry import LAWS, law_definition
from ncstab.paths.options import NORMAL_MODES, SECONDARY_CONTACT_MODES, SystemSpec
from ncstab.studies.study_fields import (
    ALL_SETTINGS,
    NAME_PATTERN,
    STUDY_KEYS,
    SYSTEM_KEYS,
    FieldErrors,
    check_keys,
    did_you_mean,
    read_table,
    toml_type,
)
from ncstab.studies.user_laws import user_laws_from_tables
from ncstab.systems import SYSTEMS, SystemKind


def study_section(data: Mapping[str, Any], errors: FieldErrors) -> tuple[str, str]:
    table = read_table(data, "study", errors)
    if table is None:
        if "study" not in data:
            errors.add("study.name", "missing: give [study] name = \"...\" (letters, digits, _ and -)")
        return "", ""
    check_keys(table, STUDY_KEYS, "study", errors, "[study]")
    name = table.get("name")
    if name is None:
        errors.add("study.name", "missing: give a name (letters, digits, _ and -), used for the archive file name")
        name = ""
    elif not isinstance(name, str):
        errors.add("study.name", f"expected a string, got {toml_type(name)}")
        name = ""
    elif not NAME_PATTERN.fullmatch(name):
        errors.add(
            "study.name",
            f"{name!r} is not allowed: use only letters, digits, '_' and '-' (it names the archive file)",
        )
    description = table.get("description", "")
    if not isinstance(description, str):
        errors.add("study.description", f"expected a string, got {toml_type(description)}")
        description = ""
    return name, description


def system_section(
    data: Mapping[str, Any], errors: FieldErrors, law_parameters: set[str], base: str | None = None
) -> tuple[SystemSpec, SystemKind | None, dict[str, Any]]:
    """SystemSpec, the system's kind (``None`` if unknown or its settings are bad) and
    the raw parameters given there (shorthands such as ``damping = [b1, b2]`` expanded);
    ``base``: the study file's folder, against which a packing's ``file`` is resolved."""
    table = read_table(data, "system", errors) or {}
    settings: dict[str, Any] = {}
    name = table.get("name", "diamond")
    kind = None
    if not isinstance(name, str):
        errors.add("system.name", f"expected a string, got {toml_type(name)}; systems are: {', '.join(SYSTEMS)}")
    elif name not in SYSTEMS:
        errors.add("system.name", f"unknown system {name!r}{did_you_mean(name, SYSTEMS)}; systems are: {', '.join(SYSTEMS)}")
    else:
        kind = SYSTEMS[name]
        settings["name"] = name
    for key, allowed in (("secondary_contacts", SECONDARY_CONTACT_MODES), ("normal", NORMAL_MODES)):
        if key not in table:
            continue
        value = table[key]
        if kind is not None and not kind.granular:
            errors.add(f"system.{key}", f"system {name!r} has no secondary contacts (new contacts between grains "
                                        f"are not looked for): {key} does not apply to it")
        elif not isinstance(value, str) or value not in allowed:
            shown = repr(value) if isinstance(value, str) else toml_type(value)
            hint = did_you_mean(value, allowed) if isinstance(value, str) else ""
            errors.add(f"system.{key}", f"{shown} is not allowed{hint}; allowed: {', '.join(allowed)}")
        else:
            settings[key] = value
    structural = kind.setting_names() if kind is not None else ALL_SETTINGS
    for key in structural:
        if key in table:
            settings[key] = table[key]
    if name == "packing" and "file" in settings:  # relative to the study file (docs/packing-paths.md)
        from ncstab.systems.packing_system import resolve_packing_file

        settings["file"] = resolve_packing_file(settings["file"], base)
    if kind is not None:
        for setting in kind.settings:
            value = settings.get(setting.name, setting.default)
            problem = "missing" if value is None else setting.check(value)
            if problem == "missing":
                errors.add(f"system.{setting.name}", f"missing: system {name!r} needs {setting.name} ({setting.description})")
                kind = None
            elif problem is not None:
                shown = repr(value) if isinstance(value, (str, int, float)) else toml_type(value)
                errors.add(f"system.{setting.name}", f"{setting.name} = {shown} is not allowed for system {name!r}: give {problem}")
                kind = None
    if kind is not None and kind.check_together is not None:  # a contact naming a missing grain, overlaps
        values = {s.name: settings.get(s.name, s.default) for s in kind.settings}
        for field_name, problem in kind.check_together(**values):
            errors.add(f"system.{field_name}", problem)
            kind = None
    if kind is not None:
        settings.update({s.name: s.frozen(settings[s.name]) for s in kind.settings if s.name in settings})
    spec = SystemSpec()
    if kind is not None:
        try:
            spec = SystemSpec(**settings)
        except ValueError as error:  # normal = "rigid" where there is no pure-shear limit
            errors.add("system.normal", str(error))
            kind = None

    system_parameters = system_parameter_names(kind)
    shorthands = dict(kind.shorthands) if kind is not None else {}
    parameters: dict[str, Any] = {}
    allowed_keys = list(SYSTEM_KEYS) + list(structural) + list(shorthands) + system_parameters
    for key, value in table.items():
        if key in SYSTEM_KEYS or key in structural:
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
                f"unknown key {key!r}{did_you_mean(key, allowed_keys)}; [system] takes: {', '.join(allowed_keys)}",
            )
    return spec, kind, parameters


def system_parameter_names(kind: SystemKind | None) -> list[str]:
    kinds = [kind] if kind is not None else list(SYSTEMS.values())
    names: list[str] = []
    for k in kinds:
        names += [p.name for p in k.parameter_specs if p.name not in names]
    if kind is None or kind.granular:
        names.append("kappa")
    return names


def laws_section(
    data: Mapping[str, Any], errors: FieldErrors, optional: bool = False
) -> tuple[list[str], list[LawDefinition], bool, dict[str, LawDefinition]]:
    """Valid law names, their definitions, whether every name given was valid, and the
    user laws of the ``[laws.<name>]`` tables (see :mod:`ncstab.studies.user_laws`).

    ``optional``: the system's interactions have laws of their own (a column,
    Ziegler's pendulum), so a study may leave ``[laws]`` out.
    """
    table = read_table(data, "laws", errors)
    if table is None:
        if "laws" not in data and not optional:
            errors.add("laws.names", f"missing: give [laws] names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], optional and "laws" not in data, {}
    tables = {key: value for key, value in table.items() if key != "names" and isinstance(value, dict)}
    check_keys({k: v for k, v in table.items() if k not in tables}, ("names",), "laws", errors, "[laws]")
    user_laws, invalid = user_laws_from_tables(tables, errors.add, set(system_parameter_names(None)))
    names = table.get("names")
    if names is None:
        errors.add("laws.names", f"missing: give names = [...]; the catalogue has: {', '.join(LAWS)}")
        return [], [], False, user_laws
    if not isinstance(names, list):
        errors.add(
            "laws.names",
            f"expected an array of law names such as [\"mcnamara\"], got {toml_type(names)}; "
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
            errors.add("laws.names", f"expected law names (strings), got {toml_type(name)} ({name!r})")
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


def user_laws_need_a_deformable_normal(
    system: SystemSpec, user_laws: Mapping[str, LawDefinition], errors: FieldErrors
) -> None:
    if system.normal == "rigid":
        for name in user_laws:
            errors.add(
                f"laws.{name}",
                "user laws are not available with normal = \"rigid\" (the pure-shear limit is derived for "
                "the catalogue laws only); use normal = \"deformable\"",
            )


def check_law_kinds(errors: FieldErrors, definitions: Sequence[Any], system: SystemSpec) -> None:
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


def check_law_spellings(names: Sequence[str], definitions: Sequence[LawDefinition], errors: FieldErrors) -> None:
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
