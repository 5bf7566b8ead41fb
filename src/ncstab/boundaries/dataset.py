"""The Dataset of a boundary: dimension ``point`` after ``law`` and the sweep dimensions."""

from __future__ import annotations

import datetime
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import xarray as xr

import ncstab

__all__ = ["boundary_dataset"]

EVENT_WORDS = {
    "limit_point": "limit point (det K = 0, seed Eq. 36)",
    "bifurcation": "simple bifurcation (the stage's equations singular)",
    "hill_loss": "loss of Hill's condition (smallest eigenvalue of K_sym = 0)",
    "flutter_onset": "flutter onset (a pair s = +-i omega of M s^2 + C s + K)",
    "divergence": "divergence (a real root s = 0 of M s^2 + C s + K)",
}


def _parameter_attrs(model, parameter: str) -> dict[str, str]:
    for spec in model.definition.parameters:
        if spec.name == parameter:
            return {"units": "1", "description": spec.description}
    for law in model.laws:
        for spec in getattr(law, "parameters", ()):
            if getattr(spec, "name", None) == parameter:
                return {"units": "1", "description": getattr(spec, "description", parameter)}
    return {"units": "1", "description": f"the study parameter {parameter}"}


def boundary_dataset(
    model,
    curves: Sequence[Any],
    problems: Sequence[Any],
    sweep: Mapping[str, Sequence[float]],
    parameter: str,
    event: str,
    start: float,
    stop: float,
) -> xr.Dataset:
    """Assemble the curves (one per law and sweep case, in order) into a labelled Dataset.

    Curves of different lengths are padded with NaN (``""`` for notes) along
    ``point``; ``n_points`` says how many each has.
    """
    definition = model.definition
    n = len(definition.dofs)
    shape = (len(model.laws),) + tuple(len(v) for v in sweep.values())
    length = max(1, max(curve.X.shape[0] for curve in curves))
    p = np.full(shape + (length,), np.nan)
    load = np.full(shape + (length,), np.nan)
    u = np.full(shape + (length, n), np.nan)
    F = np.full(shape + (length, n), np.nan)
    omega = np.full(shape + (length,), np.nan)
    notes = np.full(shape + (length,), "", dtype=object)
    count = np.zeros(shape, dtype=np.int32)
    status = np.empty(shape, dtype=object)
    message = np.empty(shape, dtype=object)
    for index, curve, problem in zip(np.ndindex(shape), curves, problems):
        m = curve.X.shape[0]
        count[index], status[index], message[index] = m, curve.status, curve.message
        if not m:
            continue
        X = curve.X
        p[index][:m] = X[:, 0]
        u[index][:m] = X[:, 1 : 1 + n]
        if curve.forces is not None:  # shot along paths: F and the load as located
            F[index][:m] = curve.forces
            load[index][:m] = curve.loads
        else:
            evaluation, _ = problem.evaluate(X)
            F[index][:m] = evaluation.forces
            if definition.load_parameter is not None:
                load[index][:m] = X[:, 1 + n] if problem.controls.load_stage else _held(problem, X)
        if event == "flutter_onset":
            omega[index][:m] = X[:, 2 + n]
        notes[index][:m] = curve.notes
    dims = ("law",) + tuple(sweep) + ("point",)
    words = EVENT_WORDS[event]
    p_attrs = _parameter_attrs(model, parameter)
    units = definition.units
    variables: dict[str, Any] = {
        f"boundary_{parameter}": (dims, p, {
            "units": p_attrs["units"], "long_name": f"{parameter} along the {event} boundary",
            "description": f"{p_attrs['description']}: the parameter the boundary of the {words} runs along",
        }),
        "boundary_u": (dims + ("dof",), u, {
            "units": getattr(units, "displacement", "1") if units else "1", "long_name": f"u at the {event} boundary",
            "description": f"generalized displacements at the {words} on the boundary",
        }),
        "boundary_F": (dims + ("dof",), F, {
            "units": getattr(units, "force", "1") if units else "1", "long_name": f"F at the {event} boundary",
            "description": f"generalized forces F(u) at the {words} on the boundary",
        }),
        "boundary_note": (dims, notes.astype(str), {
            "units": "1", "long_name": "special point of the boundary",
            "description": "start, fold (the curve turns back in the parameter), end, or how the curve ended; empty elsewhere",
        }),
        "n_points": (dims[:-1], count, {
            "units": "1", "long_name": "points of the boundary", "description": "number of points of each curve (the rest is NaN)",
        }),
        "n_steps": (dims[:-1], np.zeros(shape, dtype=np.int32), {
            "units": "1", "long_name": "stored path states",
            "description": "number of path states stored per case: 0, a boundary stores its curve along point (n_points)",
        }),
        "status": (dims[:-1], status.astype(str), {
            "units": "1", "long_name": "status", "description": "finished, stopped:<why> or failed:<why>, per curve",
        }),
        "message": (dims[:-1], message.astype(str), {
            "units": "1", "long_name": "message", "description": "what happened to each curve",
        }),
    }
    if definition.load_parameter is not None:
        variables["boundary_load"] = (dims, load, {
            "units": getattr(definition.load, "units", "1"),
            "long_name": f"load parameter {definition.load_parameter} at the {event} boundary",
            "description": f"the load parameter ({definition.load.description}) at the {words}",
        })
    if event == "flutter_onset":
        variables["boundary_frequency"] = (dims, omega, {
            "units": "1", "long_name": "flutter frequency at the boundary",
            "description": "omega of the pair s = +-i omega of M s^2 + C s + K at the boundary (units of sqrt(k/(m l^2)) for bars)",
        })
    law_names = [law.name for law in model.laws]
    from ncstab.symbolic.class_cache import class_summary

    classes = {law.name: class_summary(law).kind for law in model.laws}
    coords = {"law": law_names, "law_class": ("law", [classes[law] for law in law_names]), **{k: list(v) for k, v in sweep.items()}, "point": np.arange(length, dtype=np.int32),
              "dof": list(definition.dofs), "force": ("dof", list(definition.forces))}
    dataset = xr.Dataset(variables, coords=coords)
    dataset["point"].attrs.update(units="1", long_name="point index", description="index of the point along the boundary curve")
    dataset["dof"].attrs.update(units="1", long_name="degree of freedom", description="name of each generalized displacement")
    dataset["force"].attrs.update(units="1", long_name="generalized force", description="name of the force conjugate to each dof")
    dataset["law"].attrs.update(units="1", long_name="law", description="interaction law")
    dataset["law_class"].attrs.update(units="1", long_name="law class", description="hyperelastic, weakly or strongly hypoelastic")
    for name in sweep:
        dataset[name].attrs.update(units="1", long_name=name, description=f"swept parameter {name}")
    dataset.attrs.update({
        "Conventions": "CF-1.10",
        "ncstab_version": ncstab.__version__,
        "created": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "system": definition.name,
        "law_class": "; ".join(f"{law}: {classes[law]}" for law in law_names),
        "boundary_event": event,
        "boundary_parameter": parameter,
        "boundary_start": start,
        "boundary_stop": stop,
    })
    if definition.load_parameter is not None:
        dataset.attrs["load_parameter"] = definition.load_parameter
    return dataset


def _held(problem, X: np.ndarray) -> np.ndarray:
    held = problem.controls.held_load
    if held is None:
        return np.full(X.shape[0], np.nan)
    return np.full(X.shape[0], float(problem.values[held]) if isinstance(held, str) else float(held))
