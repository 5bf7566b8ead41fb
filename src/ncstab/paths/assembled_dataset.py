"""The Dataset of an assembled system's paths (see :mod:`ncstab.paths.assembled_result`)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.paths.programme import EVENTS
from ncstab.paths.variables import FLUTTER_WITHOUT_INERTIA, VARIABLES, family_fields, member_field_dims

if TYPE_CHECKING:  # pragma: no cover
    import xarray

    from ncstab.paths.assembled_result import AssembledPathResult

__all__ = ["ASSEMBLED_VARIABLES", "assembled_dataset", "assembled_event_fields"]

#: Variables only the assembled route writes: name -> (units, long_name, description).
ASSEMBLED_VARIABLES = {
    "det_K_sign": ("1", "sign of det K", "+1 or -1: the sign of det K from one LU factorization (0 if singular)"),
    "log_abs_det_K": ("1", "log |det K|", "natural logarithm of |det K| (det K itself over- or underflows for large n)"),
    "negative_eigenvalues": ("1", "negative eigenvalues of K_sym", "Sylvester's inertia of K_sym: the number of "
                             "independent directions of negative second-order work (0 while Hill's condition holds)"),
}


def assembled_event_fields(definition) -> dict[str, list[str]]:
    """The fields of every event's table and their dims after the sweep's (K where n is small)."""
    from ncstab.paths.assembled_result import STORED_K_LIMIT

    fields: dict[str, list[str]] = {"s": [], "s_lower": [], "s_upper": [], "stage": [], "u": ["dof"], "F": ["dof"]}
    if definition.n_dof <= STORED_K_LIMIT:
        fields["K"] = ["i", "j"]
    fields.update(member_field_dims(definition))
    return fields


def _members(point, definition) -> dict[str, np.ndarray]:
    out = {}
    for family, names, _ in family_fields(definition):
        key = "contacts" if family.kind == "contact" else "springs"
        values = np.concatenate([point.state.members[key]["q"], point.state.members[key]["f"]], axis=1)
        for k, name in enumerate(names):
            out[name] = values[:, k] if family.size > 1 else values[0, k]
    return out


#: The indicators stored at every state (:func:`_indicators`), in the Dataset's order.
INDICATOR_NAMES = ("det_K", "det_K_sign", "log_abs_det_K", "hill", "d2W", "mixed_control", "negative_eigenvalues",
                   "flutter")


def _indicators(point, definition, stored_K: bool):
    """The stored indicators of one state, and K dense where the Dataset keeps it."""
    from ncstab.operators.sparse_indicators import negative_pivots

    K = point.state.K
    dense = (K.toarray() if hasattr(K, "toarray") else np.asarray(K)) if stored_K else None
    found = point.indicators

    def value(sign: float, log: float) -> float:
        return sign * np.exp(log) if log < 709.0 else sign * np.inf

    values = {
        "det_K": value(found["det"], found["log_det"]), "det_K_sign": found["det"], "log_abs_det_K": found["log_det"],
        "hill": found["hill"], "d2W": found["d2W"], "mixed_control": value(found["det_SS"], found["log_det_SS"]),
        "negative_eigenvalues": float(negative_pivots(0.5 * (K + K.T))), "flutter": np.nan,
    }
    if "growth" in found:  # M(u) and C of the system's inertia (ncstab.paths.assembled_dynamics)
        values["flutter"] = found["growth"]
    elif dense is not None and definition.masses is not None:
        roots = np.sqrt(-np.linalg.eigvals(dense / definition.masses[:, None]).astype(complex))
        values["flutter"] = float(np.max(np.abs(roots.real)))
    return values, dense


def assembled_dataset(result: "AssembledPathResult") -> "xarray.Dataset":
    """The labelled Dataset of every law and case (names and attributes of the contract)."""
    import xarray as xr

    from ncstab.paths.assembled_result import STORED_K_LIMIT
    from ncstab.paths.dataset import _attributes, _coordinates, _system_descriptions, event_variable_attributes

    definition = result.model.definition
    n = definition.n_dof
    stored_K = n <= STORED_K_LIMIT
    outcomes = [o for r in result.results for o in r.outcomes]
    length = max(len(o.points) for o in outcomes)
    shape = result.shape
    sweep_dims = ["law", *result.grid.sweep]
    step_dims = [*sweep_dims, "step"]
    fields = family_fields(definition)
    member_dims = {name: ([dimension] if family.size > 1 else []) for family, names, dimension in fields
                   for name in names}
    member_sizes = {name: family.size for family, names, _ in fields for name in names}
    arrays: dict[str, np.ndarray] = {}

    def blank(name: str, *tail: int, fill=np.nan, dtype=float) -> np.ndarray:
        if name not in arrays:
            arrays[name] = np.full((len(outcomes), length, *tail), fill, dtype=dtype)
        return arrays[name]

    # every variable, even where no case stored a state (each failed at its first stage's start)
    blank("u", n), blank("F", n), blank("s"), blank("stage", fill=-1, dtype=np.int32), blank("lam")
    blank("branch_index", fill=-1, dtype=np.int32)  # (padded with -1 as on the compiled route; n_steps says where)
    if definition.load is not None:
        blank("load")
    for name in member_dims:
        blank(name, *([member_sizes[name]] if member_dims[name] else []))
    for name in INDICATOR_NAMES:
        blank(name)
    if stored_K:
        blank("K", n, n)
    for c, outcome in enumerate(outcomes):
        for k, point in enumerate(outcome.points):
            blank("u", n)[c, k] = point.u
            blank("F", n)[c, k] = point.state.R
            blank("s")[c, k] = outcome.arclength[k]
            blank("stage", fill=-1, dtype=np.int32)[c, k] = outcome.stages[k]
            blank("lam")[c, k] = point.y[-1]
            blank("branch_index", fill=-1, dtype=np.int32)[c, k] = point.branch
            if definition.load is not None:
                blank("load")[c, k] = point.load
            for name, values in _members(point, definition).items():
                blank(name, *([member_sizes[name]] if member_dims[name] else []))[c, k] = values
            indicators, dense = _indicators(point, definition, stored_K)
            for name, values in indicators.items():
                blank(name)[c, k] = values
            if dense is not None:
                blank("K", n, n)[c, k] = dense
    if stored_K:
        K = arrays["K"]
        arrays["K_sym"], arrays["K_skew"] = 0.5 * (K + np.swapaxes(K, -1, -2)), 0.5 * (K - np.swapaxes(K, -1, -2))
    overrides = _system_descriptions(result)
    if definition.mass is None:
        overrides["flutter"] = FLUTTER_WITHOUT_INERTIA
    overrides["lam"] = ("1", "driven quantity lambda / its stage extent",
                        "the stage's driven quantity divided by |target - start| (the sparse engine's arclength coordinate)")
    overrides["s"] = ("1", "arclength of the path", "pseudo-arclength in (u_S, lambda / |target - start|) "
                      "from the start of the programme (u_S the force-controlled dofs)")
    table = {**VARIABLES, **ASSEMBLED_VARIABLES}
    data = {}
    for name, values in arrays.items():
        dims = step_dims + {"u": ["dof"], "F": ["dof"], "K": ["i", "j"], "K_sym": ["i", "j"],
                            "K_skew": ["i", "j"]}.get(name, member_dims.get(name, []))
        units, long_name, description = overrides.get(name, table[name])
        attrs = {"long_name": long_name, "description": description}
        if units:
            attrs["units"] = units
        data[name] = (dims, values.reshape(shape + values.shape[1:]), attrs)

    def per_case(name: str, values, dtype) -> tuple:
        units, long_name, description = table[name]
        return (sweep_dims, np.array(values, dtype=dtype).reshape(shape),
                {"long_name": long_name, "description": description, **({"units": units} if units else {})})

    data["n_steps"] = per_case("n_steps", [len(o.points) for o in outcomes], np.int32)
    data["status"] = per_case("status", [o.status for o in outcomes], str)
    data["message"] = per_case("message", [o.message for o in outcomes], str)
    data["accepted_steps"] = per_case("accepted_steps", [o.accepted for o in outcomes], np.int32)
    data["rejected_steps"] = per_case("rejected_steps", [o.rejected for o in outcomes], np.int32)
    event_fields = assembled_event_fields(definition)
    for event in EVENTS:
        for suffix, dims in event_fields.items():
            tail = [n if d in ("dof", "i", "j") else member_sizes[suffix] for d in dims]
            integer = suffix == "stage"
            values = np.full((len(outcomes), *tail), -1 if integer else np.nan, dtype=np.int32 if integer else float)
            for c, outcome in enumerate(outcomes):
                found = outcome.events.get(event)
                if found is None:
                    continue
                point = found["point"]
                entry = {"s": found["s"], "s_lower": found["s_lower"], "s_upper": found["s_upper"],
                         "stage": found["stage"], "u": point.u, "F": point.state.R, "load": point.load,
                         **_members(point, definition)}
                if suffix == "K":
                    entry["K"] = point.state.K.toarray() if hasattr(point.state.K, "toarray") else point.state.K
                values[c] = entry[suffix]
            data[f"{event}_{suffix}"] = (sweep_dims + dims, values.reshape(shape + values.shape[1:]),
                                         event_variable_attributes(event, suffix))
    if getattr(definition, "inertia", None) is not None:  # omega of the critical pair at the onset
        frequency = [o.events["flutter_onset"]["point"].indicators.get("frequency", np.nan)
                     if "flutter_onset" in o.events else np.nan for o in outcomes]
        data["flutter_onset_frequency"] = (sweep_dims, np.array(frequency, dtype=float).reshape(shape),
                                           event_variable_attributes("flutter_onset", "frequency"))
    coords = _coordinates(result, length, None, 0)
    if not stored_K:
        coords.pop("i"), coords.pop("j")
    dataset = xr.Dataset(data, coords=coords, attrs=_attributes(result))
    dataset.attrs["K_stored"] = "yes" if stored_K else f"no: {n} dofs (K is stored up to {STORED_K_LIMIT})"
    return dataset
