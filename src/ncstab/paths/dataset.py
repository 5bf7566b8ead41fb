"""The Dataset of a study: every variable labelled, with units and descriptions.

docs/archive.md.  The dofs and forces are named by the
system (the ``dof`` coordinate holds the dof names, ``force`` their forces);
interaction variables of a family with several members carry its member
dimension (``contact``, ``spring``); ``load`` and ``<event>_load`` appear
where the system has a load parameter.  K is dR/du with R the internal
generalized forces minus the loads (load stiffness included).
"""

from __future__ import annotations

import datetime as _dt
from typing import TYPE_CHECKING

import numpy as np

import ncstab
from ncstab.paths.dataset_dynamics import dynamics_at_states, stored_spectrum
from ncstab.paths.dataset_indicators import state_indicators
from ncstab.paths.programme import EVENTS
from ncstab.paths.variables import (
    CASE_DIMENSION,
    EVENT_FIELDS,
    FLUTTER_FREQUENCY,
    FLUTTER_WITHOUT_INERTIA,
    VARIABLES,
    family_fields,
    member_field_dims,
)

if TYPE_CHECKING:  # pragma: no cover
    import xarray

    from ncstab.paths.result import PathResult
    from ncstab.systems import SystemDefinition

__all__ = ["event_field_dims", "event_variable_attributes", "parameter_attributes", "path_dataset"]

#: Event fields that every system has (the interaction variables and ``load`` are the system's).
COMMON_EVENT_FIELDS = ("s", "s_lower", "s_upper", "stage", "u", "F", "K")


def _system_descriptions(result: "PathResult") -> dict[str, tuple[str, str, str]]:
    """Variables whose description is the system's (not the seed's diamond)."""
    if result.model.is_reduced_diamond:
        return {}
    units = result.model.definition.units
    names = ", ".join(f"{d} (force {f})" for d, f in zip(result.dof_names, result.force_names))
    return {
        "u": (units.displacement, "generalized displacements", f"{units.displacement_description}: {names}"),
        "F": (units.force, "generalized forces", f"{units.force_description}: R(u, load) = internal forces minus loads"),
        "work": (VARIABLES["work"][0], "work", units.work_description),
        "K": ("1", "tangent operator K", "K = dR/du, R = internal generalized forces minus loads (load stiffness included)"),
        "lam": ("1", "driven quantity lambda", "the driven quantity of the stage (several driven together: the "
                "fraction of the stage done, 0 to 1; turned angle, rad, for a cycle stage)"),
    }


def _members(result: "PathResult") -> dict[str, tuple[str, tuple[str, ...]]]:
    """Stored interaction field -> (its member dimension or "", the members)."""
    out = {}
    for family, names, dimension in family_fields(result.model.definition):
        for name in names:
            out[name] = (dimension if family.size > 1 else "", family.members)
    return out


def path_dataset(result: "PathResult", directions: int | None = None, spectrum: bool = False) -> "xarray.Dataset":
    """The labelled Dataset of a :class:`~ncstab.paths.result.PathResult` (see its ``to_dataset``)."""
    import xarray as xr

    sweep_dims = ["law", *result.grid.sweep]
    shape = result.shape
    n = len(result.dof_names)
    length = max(int(r.n_steps.max()) if r.n_steps.size else 0 for r in result.results)

    def stacked(key: str) -> np.ndarray:
        arrays = []
        for r in result.results:
            a = r.steps[key]
            pad = length - a.shape[1]
            if pad:
                fill = -1 if a.dtype.kind == "i" else np.nan
                a = np.concatenate([a, np.full((a.shape[0], pad) + a.shape[2:], fill, dtype=a.dtype)], 1)
            arrays.append(a)
        array = _over_laws(arrays)
        return array.reshape(shape + array.shape[2:])

    # The indicators at every stored state (dataset_indicators); K and u stay views of the
    # recorder's rows, like every stored field.
    stage, K, u = stacked("stage"), stacked("K"), stacked("u")
    indicators = state_indicators(result, K, u, stacked("du"), stage)
    members = _members(result)

    step_dims = [*sweep_dims, "step"]
    data = {
        "u": (step_dims + ["dof"], u),
        "F": (step_dims + ["dof"], stacked("F")),
        **{name: (step_dims + ([dim] if dim else []), stacked(name)) for name, (dim, _) in members.items()},
        "s": (step_dims, stacked("s")),
        "stage": (step_dims, stage.astype(np.int32)),
        "lam": (step_dims, stacked("lam")),
        "work": (step_dims, stacked("work")),
        "K": (step_dims + ["i", "j"], K),
        **{name: (step_dims + ["i", "j"], indicators[name]) for name in ("K_sym", "K_skew")},
        **{name: (step_dims, indicators[name]) for name in ("det_K", "hill", "d2W", "flutter", "mixed_control")},
        "n_steps": (sweep_dims, np.stack([r.n_steps for r in result.results]).reshape(shape).astype(np.int32)),
        "status": (sweep_dims, result.status.astype(str)),
        "message": (sweep_dims, result.message.astype(str)),
        "accepted_steps": (
            sweep_dims,
            np.stack([r.counters["accepted"] for r in result.results]).reshape(shape).astype(np.int32),
        ),
        "rejected_steps": (
            sweep_dims,
            np.stack([r.counters["rejected"] for r in result.results]).reshape(shape).astype(np.int32),
        ),
    }
    has_load = result.model.definition.load is not None
    if has_load:
        data["load"] = (step_dims, stacked("load"))
    if spectrum:
        if result.model.definition.mass is None:
            raise ValueError(f"system {result.model.definition.name!r} declares no inertia: it has no dynamic spectrum")
        roots = stored_spectrum(result, u, K)
        data["spectrum_re"] = (step_dims + ["root"], roots.real)
        data["spectrum_im"] = (step_dims + ["root"], roots.imag)
    if "branch_index" in result.results[0].steps:
        data["branch_index"] = (step_dims, stacked("branch_index").astype(np.int32))
    if directions is not None:
        from ncstab.operators.directional_work import directional_second_order_work, unstable_cone

        if int(directions) < 4:
            raise ValueError(f"directions must be at least 4, got {directions}")
        if n != 2:
            raise ValueError(f"second-order work maps over directions need a two-dof system, this one has {n} dofs")
        theta = np.linspace(0.0, np.pi, int(directions), endpoint=False)
        data["d2W_dir"] = (step_dims + ["theta"], directional_second_order_work(K, theta))
        width, lower, upper = unstable_cone(K)
        data["cone_width"] = (step_dims, width)
        data["cone_lower"] = (step_dims, lower)
        data["cone_upper"] = (step_dims, upper)
    first = result.results[0]
    n_cycles = first.cycles["work"].shape[1] if first.cycles else 0
    if n_cycles:
        def cycle_array(key: str) -> np.ndarray:
            array = np.stack([r.cycles[key] for r in result.results])
            return array.reshape(shape + array.shape[2:])

        work = cycle_array("work")
        drift = cycle_array("tangential_drift")
        drift_dim = [members["T"][0]] if "T" in members and members["T"][0] else []
        data["cycle_work"] = ([*sweep_dims, "cycle"], work)
        data["cumulative_work"] = ([*sweep_dims, "cycle"], np.cumsum(work, axis=-1))
        data["cycle_force_gap"] = ([*sweep_dims, "cycle", "dof"], cycle_array("force_gap"))
        data["cycle_T_drift"] = ([*sweep_dims, "cycle", *drift_dim], drift)
    overrides = _system_descriptions(result)
    if result.model.definition.mass is None:
        overrides["flutter"] = FLUTTER_WITHOUT_INERTIA
    rigid = result.model.normal == "rigid"
    for name, (dims, values) in list(data.items()):
        units, long_name, description = overrides.get(name, VARIABLES[name])
        if rigid and name in ("F", "N", "T"):
            description = description.replace("2R k_n", "2R k_t") + " (pure-shear limit: forces in units of 2R k_t, seed Eq. 62)"
            long_name = long_name.replace("*", "^")
        attrs = {"long_name": long_name, "description": description}
        if units:
            attrs["units"] = units
        data[name] = (dims, values, attrs)
    for event in EVENTS:
        for suffix, dims in event_field_dims(result.model.definition).items():
            values = _over_laws([r.events[event][suffix] for r in result.results])
            values = values.reshape(shape + values.shape[2:])
            if suffix == "stage":
                values = values.astype(np.int32)
            data[f"{event}_{suffix}"] = (sweep_dims + dims, values, event_variable_attributes(event, suffix))
    if result.model.definition.mass is not None:
        frequency = dynamics_at_states(
            result,
            _over_laws([r.events["flutter_onset"]["u"] for r in result.results]).reshape(shape + (n,)),
            _over_laws([r.events["flutter_onset"]["K"] for r in result.results]).reshape(shape + (n, n)),
            critical=True,
        )
        data["flutter_onset_frequency"] = (sweep_dims, frequency, event_variable_attributes("flutter_onset", "frequency"))
    return xr.Dataset(data, coords=_coordinates(result, length, directions, n_cycles), attrs=_attributes(result))


def _over_laws(arrays: list[np.ndarray]) -> np.ndarray:
    """The laws' arrays along a first axis: for one law a view (the result's own
    arrays, not a copy: 65,536 cases' event tables cost 25 ms to copy), else a stack."""
    return arrays[0][None] if len(arrays) == 1 else np.stack(arrays)


def event_field_dims(definition: "SystemDefinition") -> dict[str, list[str]]:
    """The fields of every event's table (``<event>_<field>``) and their dimensions after
    the sweep's: those of every system (:data:`COMMON_EVENT_FIELDS`), the interaction
    variables (along their member dimension where a family has several) and ``load``."""
    fields: dict[str, list[str]] = {name: [] for name in COMMON_EVENT_FIELDS}
    fields.update(u=["dof"], F=["dof"], K=["i", "j"])
    fields.update(member_field_dims(definition))
    return fields


def event_variable_attributes(event: str, field: str) -> dict[str, str]:
    """``units``, ``long_name`` and ``description`` of ``<event>_<field>`` (``field``
    ``"frequency"``: ``flutter_onset_frequency``)."""
    if field == "frequency":
        units, long_name, description = FLUTTER_FREQUENCY
    elif field in EVENT_FIELDS:
        units, long_name, description = EVENT_FIELDS[field]
    else:
        units, long_name, description = (
            VARIABLES[field][0], f"{field} at {{event}}", f"{VARIABLES[field][1]} at the first {{event}}"
        )
    return {"units": units, "long_name": long_name.format(event=event), "description": description.format(event=event)}


def _coordinates(result: "PathResult", length: int, directions: int | None, n_cycles: int) -> dict:
    classes = result.law_classes()
    dofs = np.array(result.dof_names, dtype=str)
    plane = "the (Delta_1*, Delta_2*) plane" if result.model.is_reduced_diamond else f"the ({dofs[0]}, {dofs[-1]}) plane"
    coords = {
        "law": ("law", np.array(result.laws, dtype=str), {"long_name": "interaction law"}),
        "law_class": ("law", np.array([classes[law] for law in result.laws], dtype=str), {
            "long_name": "computed class of the law",
            "description": "hyperelastic, weakly hypoelastic or strongly hypoelastic (ncstab.symbolic.classify)",
        }),
        "step": ("step", np.arange(length, dtype=np.int32), {"units": "1", "long_name": "stored state index"}),
        "dof": ("dof", dofs, {
            "long_name": "degree of freedom",
            "description": "the system's generalized displacements; their conjugate forces are the coordinate force",
        }),
        "force": ("dof", np.array(result.force_names, dtype=str), {
            "long_name": "generalized force", "description": "the force conjugate to each dof",
        }),
        "i": ("i", dofs, {"long_name": "matrix row (dof)"}),
        "j": ("j", dofs, {"long_name": "matrix column (dof)"}),
    }
    for family, _, dimension in family_fields(result.model.definition):
        if family.size > 1:
            coords[dimension] = (dimension, np.array(family.members, dtype=str), {
                "long_name": f"member of the {family.name}", "description": f"the {family.size} {family.kind}s of family {family.name}",
            })
    for name, values in result.grid.sweep.items():
        coords[name] = (name, values, parameter_attributes(name, result))
    if directions is not None:
        coords["theta"] = ("theta", np.linspace(0.0, np.pi, int(directions), endpoint=False), {
            "units": "rad", "long_name": "loading direction theta",
            "description": f"direction of du = (cos theta, sin theta) in {plane}; d2W is pi-periodic"})
    if n_cycles:
        cycles = result.results[0].cycles
        coords["cycle"] = ("cycle", np.arange(1, n_cycles + 1, dtype=np.int32), {
            "units": "1", "long_name": "cycle number", "description": "turns of the cycle stages, in programme order"})
        units, long_name, description = VARIABLES["cycle_stage"]
        coords["cycle_stage"] = ("cycle", cycles["stage"].astype(np.int32), {
            "units": units, "long_name": long_name, "description": description})
        stage_direction = [getattr(st, "direction", 0) for st in result.programme.stages]
        coords["cycle_direction"] = (
            "cycle",
            np.array([stage_direction[k] for k in cycles["stage"]], dtype=np.int32),
            {"units": "1", "long_name": "direction of each cycle",
             "description": f"1 counterclockwise, -1 clockwise in {plane if result.model.is_reduced_diamond else 'the plane of its dofs (first to second)'}"},
        )
    return coords


def _attributes(result: "PathResult") -> dict:
    classes = result.law_classes()
    definition = result.model.definition
    settings = ", ".join(f"{k}={v}" for k, v in definition.settings)
    attrs = {
        "Conventions": "CF-1.10",
        "title": "ncstab path study",
        "ncstab_version": ncstab.__version__,
        "created": _dt.datetime.now(_dt.timezone.utc).isoformat(timespec="seconds"),
        # CF 2.6.2: an audit trail (the time is in ``created``, so that two runs of a
        # study give identical attributes but that one)
        "history": f"ncstab {ncstab.__version__}: the study's cases followed along its loading programme",
        "study": result.study_text,
        "system": definition.name,
        "system_settings": settings,
        "secondary_contacts": result.model.secondary_contacts,
        "normal": result.model.normal,
        "law_class": "; ".join(f"{law}: {classes[law]}" for law in result.laws),
        "engine": "; ".join(f"{law}: {case.engine}" for law, case in zip(result.laws, result.results)),
        "force_unit": result.force_unit,
        "source": definition.reference or definition.title,
    }
    if definition.load is not None:
        attrs["load_parameter"] = definition.load.parameter
        attrs["load_kind"] = definition.load.kind
    attrs["stage_drives"] = "; ".join(_stage_drives(stage) for stage in result.programme.stages)
    for name, value in result.grid.fixed.items():
        attrs[f"parameter_{name}"] = value
    return attrs


def _stage_drives(stage) -> str:
    """``"D_top,D_bottom"`` (the driven quantities), ``"cycle:D1,D2"`` (a cycle's plane)."""
    from ncstab.paths.programme import CycleStage

    if isinstance(stage, CycleStage):
        return "cycle:" + ",".join(stage.dofs)
    return ",".join(stage.drive)


def parameter_attributes(name: str, result: "PathResult | None" = None) -> dict[str, str]:
    """Attributes of the coordinate of a swept parameter (units, long_name, description)."""
    from ncstab.laws.definition import ALPHA0_SPEC, GAMMA_SPEC

    known = {
        "gamma": ("1", "stiffness ratio gamma", GAMMA_SPEC.description),
        "alpha0": ("rad", "initial orientation alpha0", ALPHA0_SPEC.description),
        "kappa": ("1", "secondary contact stiffness ratio kappa", "stiffness of the secondary-contact springs / k_n"),
        CASE_DIMENSION: ("1", "case index", "flat index of the case in the whole sweep (C order over the swept parameters)"),
        "branch": ("1", "branch followed at the bifurcation", "0: the path followed through the stage's first simple bifurcation point; +1, -1: the bifurcating branch, either way (at_bifurcation = \"branches\")"),
    }
    if result is not None:
        for spec in result.model.definition.parameters:
            known.setdefault(spec.name, (spec.units, spec.name, spec.description))
    units, long_name, description = known.get(name, ("1", name, f"study parameter {name}"))
    return {"units": units, "long_name": long_name, "description": description}
