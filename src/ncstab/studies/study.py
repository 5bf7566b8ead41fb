"""Study files (TOML) read and validated into a :class:`Study`.

A study file says which system, which laws, which parameters (a list is a sweep
dimension), which loading programme, which engine options and which figures
(``docs/study-files.md``).  :func:`parse_study` checks the whole file before any
computation and reports *every* error it finds at once, each naming the file,
the field (``parameters.gamma``, ``loading[2].hold.F2``) and what is allowed,
in one :class:`StudyFileError`.

The sections are read by :mod:`~ncstab.studies.study_system`, :mod:`~ncstab.studies.study_values`
and :mod:`~ncstab.studies.study_loading`, with the vocabulary of :mod:`~ncstab.studies.study_fields`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path as FilePath

from ncstab.laws.definition import LawDefinition
from ncstab.laws.registry import LAWS, law_definition
from ncstab.paths.options import PathOptions, SystemSpec
from ncstab.paths.programme import (
    LoadingProgramme,
)
from ncstab.studies.archive_selection import read_variables, study_variable_names
from ncstab.studies.boundary_fields import BoundarySpec, boundary_figures, boundary_section, check_boundary_model
from ncstab.studies.figure_fit import figure_fit
from ncstab.studies.study_extrema import extrema_option
from ncstab.studies.study_fields import (
    DEFAULT_FIGURES,
    DEFAULT_MAX_CASES,
    FIGURE_KINDS,
    RIGID_MEANINGLESS,
    SECTIONS,
    SPECTRUM_FIGURES,
    FieldErrors,
    StudyFileError,
    decode_toml,
    error_order,
    unknown_sections,
)
from ncstab.studies.study_loading import (
    check_stages_do_something,
    loading_section,
    options_section,
    output_section,
    spectrum_option,
)
from ncstab.studies.study_map import StudyMap, map_section
from ncstab.studies.study_system import (
    check_law_kinds,
    check_law_spellings,
    laws_section,
    study_section,
    system_parameter_names,
    system_section,
    user_laws_need_a_deformable_normal,
)
from ncstab.studies.study_values import (
    MAX_RANGE_VALUES,
    RANGE_STEP_TOL,
    check_fixed_parameters,
    check_references,
    parameter_specs,
    read_parameters,
)
from ncstab.systems import SYSTEMS, SystemDefinition

__all__ = [
    "DEFAULT_FIGURES",
    "DEFAULT_MAX_CASES",
    "FIGURE_KINDS",
    "MAX_RANGE_VALUES",
    "RANGE_STEP_TOL",
    "SECTIONS",
    "SPECTRUM_FIGURES",
    "Study",
    "StudyFileError",
    "StudyMap",
    "load_study",
    "parse_study",
]


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
        The ``[map]`` section (second-order work maps to add), or ``None``.
    spectrum
        ``[output] spectrum``: store the dynamic spectrum at every state.
    user_laws
        The laws of the ``[laws.<name>]`` tables (:func:`ncstab.laws.user_law`),
        without modifiers; :meth:`law_definition` resolves any of :attr:`laws`.
    max_cases
        ``[options] max_cases``: the most cases ``ncstab run`` runs
        (:data:`DEFAULT_MAX_CASES` unless given).
    variables
        ``[output] variables``: the data variables the archive keeps (event
        names stand for their tables), ``"all"``, or None for the default
        (every one up to 1,000 cases per law, the lean archive above:
        :func:`~ncstab.studies.archive_selection.archive_selection`).
    extrema
        ``[output] extrema``: the state variables whose first extremum along
        the path is located (the event ``extremum_<name>``,
        :mod:`ncstab.paths.extrema`).
    boundary
        ``[boundary]``: the stability boundary traced as a curve instead of a
        sweep of paths (:func:`ncstab.boundaries.boundary`), or ``None``.
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
    max_cases: int = DEFAULT_MAX_CASES
    variables: str | tuple[str, ...] | None = None
    extrema: tuple[str, ...] = ()
    boundary: BoundarySpec | None = None

    def law_definition(self, name: str) -> LawDefinition:
        """The definition of one of :attr:`laws` (a user law of the file or a catalogue law)."""
        return law_definition(name, {definition.name: definition for definition in self.user_laws})

    @property
    def law_definitions(self) -> tuple[LawDefinition, ...]:
        """The definitions of :attr:`laws`, in order: what every run mode follows."""
        return tuple(self.law_definition(name) for name in self.laws)

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
    data = decode_toml(text, source)
    errors = FieldErrors()
    unknown_sections(data, errors)
    name, description = study_section(data, errors)
    named = (data.get("system") or {}).get("name", "diamond") if isinstance(data.get("system"), dict) else "diamond"
    own_laws = isinstance(named, str) and named in SYSTEMS and SYSTEMS[named].own_laws
    laws, definitions, all_laws_valid, user_laws = laws_section(data, errors, optional=own_laws)
    check_law_spellings(laws, definitions, errors)
    law_only = {p.name for d in (definitions if all_laws_valid else LAWS.values()) for p in d.parameters}
    law_only -= set(system_parameter_names(None))
    folder = str(FilePath(path).parent) if path is not None and not str(path).startswith("<") else None
    system, kind, system_raw = system_section(data, errors, law_only, folder)
    user_laws_need_a_deformable_normal(system, user_laws, errors)
    if kind is not None:
        check_law_kinds(errors, definitions, system)
    specs = parameter_specs(definitions, all_laws_valid, kind, system)
    check_fixed_parameters(data, errors, kind, system)
    parameters, fields, free = read_parameters(data, errors, system, system_raw, specs, definitions)
    programme, references = loading_section(data, errors, kind, system)
    known = [k for k in specs if not (system.normal == "rigid" and k in RIGID_MEANINGLESS)]
    if kind is not None:  # else the stages were not read: which parameters they use is unknown
        check_references(errors, references, fields, free, known)
    options, max_cases = options_section(data, errors)
    study_map = map_section(data, errors)
    fit = None if errors.items else figure_fit(programme, parameters, study_map, definitions, system)
    figures, output = output_section(data, errors, fit)
    boundary = boundary_section(data, errors, None if errors.items else parameters)
    figures = boundary_figures(data, errors, boundary, figures)
    if boundary is not None and not errors.items:
        check_boundary_model(boundary, system, [law_definition(n, user_laws) for n in laws], programme, parameters, errors)
    spectrum = spectrum_option(data, errors, figures, system)
    output_table = data.get("output") if isinstance(data.get("output"), dict) else {}
    extrema = extrema_option(output_table, errors, system)
    available = None if errors.items else study_variable_names(system, programme, study_map, spectrum, extrema)
    variables = read_variables(output_table, errors, available, figures)
    if not errors.items and programme is not None:
        check_stages_do_something(programme, parameters, errors)

    if programme is not None and programme.follows_branches:
        from ncstab.paths.api import with_branches

        parameters = with_branches(programme, parameters)
    if errors.items or programme is None:
        if not errors.items:  # pragma: no cover - a missing programme always reports why
            errors.add("loading", "no valid loading programme")
        raise StudyFileError(source, sorted(errors.items, key=error_order))
    from ncstab.studies.verification import remember_valid_study

    remember_valid_study(text)  # the archives of this study then check it without parsing it again
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
        variables=variables,
        extrema=extrema,
        boundary=boundary,
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
