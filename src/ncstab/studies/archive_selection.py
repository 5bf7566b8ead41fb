"""Which data variables a study's archive stores: ``[output] variables`` and the lean default.

An archive always holds its coordinates and the variables ``status``,
``message`` and ``n_steps``.  Of the other data variables it holds

* those ``[output] variables`` names (an event's name, such as
  ``"limit_point"``, stands for all its variables ``limit_point_*``), or
  every one with ``variables = "all"``;
* by default, every one for a sweep of at most :data:`LEAN_ABOVE_CASES` cases
  per law; for a larger sweep, the *lean* default leaves out the tangent
  operator along the paths (:data:`LEAN_LEFT_OUT`: ``K``, ``K_sym``,
  ``K_skew``) and the tables of the events that no case of the sweep meets
  (:func:`leave_out_unseen_events`), keeping whatever the study's figures
  draw (:data:`FIGURE_VARIABLES`).

The archive says what it left out in its attributes
:data:`VARIABLES_LEFT_OUT` and :data:`EVENTS_LEFT_OUT`;
:func:`fill_left_out_events` puts back the tables of the events left out (NaN,
their ``_stage`` -1: what an archive with every variable holds for them).
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.options import SystemSpec
from ncstab.paths.programme import EVENTS, CycleStage, LoadingProgramme
from ncstab.studies.study_fields import FieldErrors, did_you_mean, toml_type
from ncstab.studies.verification import REQUIRED_VARIABLES

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.studies.study import Study

__all__ = [
    "ALL_VARIABLES",
    "EVENTS_LEFT_OUT",
    "FIGURE_VARIABLES",
    "LEAN_ABOVE_CASES",
    "LEAN_LEFT_OUT",
    "VARIABLES_LEFT_OUT",
    "ArchiveSelection",
    "archive_selection",
    "event_variables",
    "fill_left_out_events",
    "leave_out_unseen_events",
    "read_variables",
    "select_variables",
    "study_variable_names",
    "unseen_events",
]

#: ``[output] variables = "all"``: every variable, whatever the sweep's size.
ALL_VARIABLES = "all"
#: Sweeps of more cases per law than this get the lean default.
LEAN_ABOVE_CASES = 1000
#: Variables the lean default leaves out: K along the paths (n^2 values per state
#: each); ``ncstab.studies.tangent_operators`` computes K again from what is kept.
LEAN_LEFT_OUT = ("K", "K_sym", "K_skew")
#: Attribute listing the data variables a selection left out (comma-separated).
VARIABLES_LEFT_OUT = "variables_left_out"
#: Attribute listing the events whose tables the lean default left out because no case meets them.
EVENTS_LEFT_OUT = "events_left_out"

_PATH = ("u", "F", "load", "hill")
_CYCLES = ("u", "F", "T", "alpha", "l", "lam", "stage", "cycle_work", "cumulative_work", "cycle_force_gap", "cycle_T_drift")
_SPECTRUM = ("load", "spectrum_re", "spectrum_im")
#: Variables each figure kind draws (those of them the study stores).  A selection
#: that leaves one out is refused; the lean default keeps them.  Event tables a
#: figure marks where they exist are not needed (an event left out is one no case meets).
FIGURE_VARIABLES: dict[str, tuple[str, ...]] = {
    "load_rotation": (*_PATH, "alpha", "theta"),
    "load_displacement": _PATH,
    "load_displacement_rotation": (*_PATH, "alpha"),
    "stability": (*_PATH, "det_K", "d2W", "stage"),
    "cycle_work": _CYCLES,
    "cycle_paths": _CYCLES,
    "cycle_force_drift": _CYCLES,
    "stability_diagram": (),
    "second_order_work_map": ("s", "d2W_dir", "cone_lower", "cone_upper"),
    "second_order_work_polar": ("K",),
    "state_map": ("u", "map_hill", "map_det_K", "map_cone_width", "map_mixed_control_F1", "map_mixed_control_F2",
                  "map_F1", "map_F2"),
    "root_locus": _SPECTRUM,
    "frequencies": _SPECTRUM,
    "damping_map": ("flutter_onset_load",),
}


def study_variable_names(
    system: Any, programme: LoadingProgramme, study_map: Any = None, spectrum: bool = False,
    extrema: Sequence[str] = (),
) -> tuple[str, ...]:
    """The data variables of a study's archive with every variable stored.

    As :func:`ncstab.paths.dataset.path_dataset` and
    :func:`ncstab.studies.maps.add_state_maps` make them (a test compares the two).

    Parameters
    ----------
    system
        The study's :class:`~ncstab.paths.options.SystemSpec` or
        :class:`~ncstab.systems.SystemDefinition`.
    programme, study_map, spectrum, extrema
        The study's loading programme, ``[map]`` section (or None), ``[output] spectrum``
        and ``[output] extrema``.
    """
    from ncstab.paths.dataset import event_field_dims
    from ncstab.paths.variables import family_fields
    from ncstab.studies.maps import STATE_MAP_FIELDS

    definition = system.definition if isinstance(system, SystemSpec) else system
    reduced = isinstance(system, SystemSpec) and system.is_reduced_diamond
    members = [name for _, names, _ in family_fields(definition) for name in names]
    names = ["u", "F", *members, "s", "stage", "lam", "work", *LEAN_LEFT_OUT, "det_K", "hill", "d2W", "flutter",
             "mixed_control", "n_steps", "status", "message", "accepted_steps", "rejected_steps"]
    if definition.load is not None:
        names.append("load")
    if spectrum:
        names += ["spectrum_re", "spectrum_im"]
    if not reduced:
        names.append("branch_index")
    if study_map is not None and study_map.directions is not None:
        names += ["d2W_dir", "cone_width", "cone_lower", "cone_upper"]
    if any(isinstance(stage, CycleStage) for stage in programme.stages):
        names += ["cycle_work", "cumulative_work", "cycle_force_gap", "cycle_T_drift"]
    fields = event_field_dims(definition)
    names += [f"{event}_{suffix}" for event in EVENTS for suffix in fields]
    if definition.mass is not None:
        names.append("flutter_onset_frequency")
    if study_map is not None and study_map.grid is not None:
        names += list(STATE_MAP_FIELDS)
    if extrema:
        from ncstab.paths.extrema import extremum_names

        names += extremum_names(definition, extrema)
    return tuple(names)


def event_variables(event: str, names: Iterable[str]) -> list[str]:
    """The variables of ``names`` that belong to an event's table (``<event>_*``)."""
    return [name for name in names if name.startswith(f"{event}_")]


def _expanded(names: Sequence[str], available: Sequence[str]) -> list[str]:
    """Names with each event name replaced by its event's variables."""
    out: list[str] = []
    for name in names:
        out.extend(event_variables(name, available) if name in EVENTS else [name])
    return out


def read_variables(
    table: Mapping[str, Any], errors: FieldErrors, available: Sequence[str] | None, figures: Sequence[str]
) -> str | tuple[str, ...] | None:
    """``[output] variables``: ``"all"``, the names given, or None (the default).

    Each name must be one of ``available`` (the study's variables,
    :func:`study_variable_names`) or an event's name; a figure of ``figures``
    that draws a variable the names leave out is an error of ``output.variables``.
    ``available`` is None when the rest of the study is invalid: only the
    form of the value is checked then.
    """
    if "variables" not in table:
        return None
    raw = table["variables"]
    field = "output.variables"
    if isinstance(raw, str):
        if raw != ALL_VARIABLES:
            errors.add(field, f'expected "all" or an array of variable names, got {raw!r}')
            return None
        return ALL_VARIABLES
    if not isinstance(raw, list):
        errors.add(field, f'expected an array of variable names or "all", got {toml_type(raw)}')
        return None
    choices = list(available or ()) + list(EVENTS)
    names: list[str] = []
    for name in raw:
        if not isinstance(name, str):
            errors.add(field, f"expected variable names (strings), got {toml_type(name)}")
        elif name in names:
            errors.add(field, f"variable {name!r} is listed twice")
        elif available is not None and name not in choices:
            shown = [n for n in available if not any(n.startswith(f"{e}_") for e in EVENTS)]
            errors.add(
                field,
                f"unknown variable {name!r}{did_you_mean(name, choices)}; this study's variables are "
                f"{', '.join(shown)}, and the tables of the events {', '.join(EVENTS)} (<event>_s, <event>_F...)",
            )
        else:
            names.append(name)
    if available is not None:
        kept = set(_expanded(names, available)) | set(REQUIRED_VARIABLES)
        for kind in figures:
            missing = [n for n in FIGURE_VARIABLES.get(kind, ()) if n in available and n not in kept]
            if missing:
                errors.add(
                    field,
                    f"figure {kind!r} draws {', '.join(missing)}, which variables leaves out: add "
                    f"{'it' if len(missing) == 1 else 'them'} or remove the figure from output.figures",
                )
    return tuple(names)


@dataclass(frozen=True)
class ArchiveSelection:
    """What an archive keeps of a study's data variables.

    Attributes
    ----------
    kept
        The data variables kept (those of the study not among them are left
        out), or None for every one.
    leave_out_unseen_events
        Leave out the tables of the events no case of the sweep meets (the
        lean default), but those of :attr:`needed_events`.
    needed_events
        Events whose tables a figure of the study draws.
    """

    kept: frozenset[str] | None = None
    leave_out_unseen_events: bool = False
    needed_events: frozenset[str] = frozenset()


def archive_selection(study: "Study") -> ArchiveSelection:
    """The :class:`ArchiveSelection` of a study (its ``[output] variables`` or the default)."""
    from ncstab.paths.api import ParameterGrid

    if study.variables == ALL_VARIABLES:
        return ArchiveSelection()
    available = study_variable_names(study.system, study.programme, study.map, study.spectrum, study.extrema)
    if study.variables is not None:
        return ArchiveSelection(frozenset(_expanded(study.variables, available)) | frozenset(REQUIRED_VARIABLES))
    if ParameterGrid.from_mapping(study.parameters).size <= LEAN_ABOVE_CASES:
        return ArchiveSelection()
    needed = {name for kind in study.figures for name in FIGURE_VARIABLES.get(kind, ())}
    kept = frozenset(name for name in available if name not in LEAN_LEFT_OUT or name in needed)
    events = frozenset(event for event in EVENTS if any(event_variables(event, needed)))
    return ArchiveSelection(kept, leave_out_unseen_events=True, needed_events=events)


def select_variables(dataset: "xr.Dataset", selection: ArchiveSelection) -> "xr.Dataset":
    """The Dataset without the data variables ``selection`` leaves out (the unseen events aside).

    The names left out are listed in the attribute :data:`VARIABLES_LEFT_OUT`.
    Works on a chunk of cases as on the whole sweep.
    """
    if selection.kept is None:
        return dataset
    left_out = [str(name) for name in dataset.data_vars if name not in selection.kept]
    if not left_out:
        return dataset
    dataset = dataset.drop_vars(left_out)
    dataset.attrs[VARIABLES_LEFT_OUT] = ", ".join(left_out)
    return dataset


def unseen_events(dataset: "xr.Dataset", candidates: Iterable[str] = EVENTS) -> list[str]:
    """The events of ``candidates`` with a table in ``dataset`` that no case meets (``<event>_stage`` -1 everywhere)."""
    out = []
    for event in candidates:
        stage = dataset.get(f"{event}_stage")
        if stage is not None and not bool((np.asarray(stage.values) >= 0).any()):
            out.append(event)
    return out


def leave_out_unseen_events(dataset: "xr.Dataset", selection: ArchiveSelection) -> "xr.Dataset":
    """The whole sweep's Dataset without the tables of the events no case meets, if ``selection`` says so.

    The events left out are listed in the attribute :data:`EVENTS_LEFT_OUT`
    (absent if none is).
    """
    if not selection.leave_out_unseen_events:
        return dataset
    events = unseen_events(dataset, [e for e in EVENTS if e not in selection.needed_events])
    if not events:
        return dataset
    dataset = dataset.drop_vars([name for event in events for name in event_variables(event, dataset.data_vars)])
    dataset.attrs[EVENTS_LEFT_OUT] = ", ".join(events)
    return dataset


def fill_left_out_events(dataset: "xr.Dataset") -> "xr.Dataset":
    """The Dataset with the tables of the events its :data:`EVENTS_LEFT_OUT` names put back.

    Each as an archive with every variable holds an event no case meets: NaN,
    ``<event>_stage`` -1, with their units and descriptions; the attribute is
    removed.  The system (which fields an event has) is read from the
    archive's ``study`` attribute.  A Dataset without the attribute is returned as it is.
    """
    from ncstab.paths.dataset import event_field_dims, event_variable_attributes
    from ncstab.studies.study import parse_study

    names = [e.strip() for e in str(dataset.attrs.get(EVENTS_LEFT_OUT, "")).split(",") if e.strip()]
    if not names:
        return dataset
    study = parse_study(str(dataset.attrs["study"]), "<archive>")
    definition = study.system.definition if isinstance(study.system, SystemSpec) else study.system
    sweep_dims = list(dataset["status"].dims)
    sweep_shape = dataset["status"].shape
    dataset = dataset.copy()
    for event in names:
        for suffix, dims in event_field_dims(definition).items():
            shape = sweep_shape + tuple(dataset.sizes[d] for d in dims)
            values = np.full(shape, -1, np.int32) if suffix == "stage" else np.full(shape, np.nan)
            dataset[f"{event}_{suffix}"] = (sweep_dims + dims, values, event_variable_attributes(event, suffix))
        if event == "flutter_onset" and definition.mass is not None:
            name = "flutter_onset_frequency"
            dataset[name] = (sweep_dims, np.full(sweep_shape, np.nan), event_variable_attributes(event, "frequency"))
    dataset.attrs = {k: v for k, v in dataset.attrs.items() if k != EVENTS_LEFT_OUT}
    return dataset
