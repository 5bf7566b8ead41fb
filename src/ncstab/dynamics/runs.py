"""A dynamic stage over every case of a study: where each motion starts, and its Dataset.

:func:`follow_motions` takes the followed paths of the programme's earlier stages
(a :class:`~ncstab.paths.result.PathResult`; from rest where there is none),
starts every case's motion where its path ended -- displacements, forces, load
parameter and internal variables of its last stored state -- and integrates it
(:func:`~ncstab.dynamics.motion.integrate_motion`).  :func:`motion_dataset`
labels the motions as the Dataset's ``time`` variables and their located events as
``motion_<event>_time``, ``motion_<event>_u``... (docs/dynamics-after-loss.md).  A case
whose path failed gets no motion (NaN, status ``not_run``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.dynamics.equations import MotionEquations
from ncstab.dynamics.motion import Motion, integrate_motion
from ncstab.dynamics.motion_events import event_watch
from ncstab.dynamics.stage import DynamicStage
from ncstab.paths.programme import CURRENT

if TYPE_CHECKING:  # pragma: no cover
    import xarray as xr

    from ncstab.paths.result import PathResult

__all__ = ["MOTION_VARIABLES", "follow_motions", "motion_dataset", "motion_equations", "motion_event_variables"]

#: Status of a case whose path failed before its dynamic stage.
NOT_RUN = "not_run"


def _time_unit(definition: Any) -> str:
    if definition.family("contact") is not None:
        return "sqrt(m / k_n) (m the mass of a grain)"
    return "sqrt(m l^2 / k) (m the mass unit, l the bar length, k the joint spring)"


def _energy_unit(definition: Any) -> str:
    if definition.family("contact") is not None:
        return "k_n (2R)^2 per contact (seed Eq. 5, 37)"
    return f"{definition.units.force_unit} (the system's unit of work)"


def motion_variables(definition: Any) -> dict[str, tuple[str, str, str]]:
    """name -> (units, long_name, description) of the Dataset's motion variables."""
    time, energy = _time_unit(definition), _energy_unit(definition)
    return {
        "time": ("1", "time since the dynamic stage began", f"in units of {time}"),
        "u_t": (definition.units.displacement, "displacements during the motion", f"{definition.units.displacement_description} at each stored time"),
        "velocity": ("1", "velocities during the motion", f"du/dt of each dof at each stored time, dof units per unit of time ({time})"),
        "kinetic_energy": ("1", "kinetic energy", f"w u'^T M(u) u' / 2, w the system's work factor, in units of {energy}"),
        "external_work": ("1", "work of the controls and loads", f"int w (F + lambda Q_ext(u)) . du since the stage began (held forces and the load parameter's loads, followers included; held displacements do none), in units of {energy}"),
        "internal_work": ("1", "work of the interactions", f"int w R_int(u, z) . du since the stage began (the interactions' generalized forces; not a function of u alone for a hypoelastic law: Green's paradox), in units of {energy}"),
        "dissipated_work": ("1", "work of the dashpots", f"int w u'^T C u' dt since the stage began (>= 0), in units of {energy}; kinetic_energy = external_work - internal_work - dissipated_work at every time"),
        "motion_status": ("", "status of the motion", "finished, stopped:left_domain (the motion left the admissible domain; later times NaN), stopped:contact_closing or stopped:kinetic_energy (the motion ended at an event the stage's stop_at names; later times NaN), failed:<reason>, or not_run (the path before it failed)"),
        "motion_message": ("", "what happened to the motion", "in words"),
        "motion_steps": ("1", "accepted integrator steps of the motion", "accepted steps of the adaptive Runge-Kutta integrator (scipy.integrate DOP853 or Radau)"),
    }


#: The motion variables' names.
MOTION_VARIABLES = ("u_t", "velocity", "kinetic_energy", "external_work", "internal_work", "dissipated_work",
                    "motion_status", "motion_message", "motion_steps")


def _end_states(result: Any, n: int) -> dict[str, np.ndarray]:
    """Each case's last stored state (zeros from rest where the path stored none)."""
    size = result.n_steps.shape[0]
    last = np.maximum(result.n_steps - 1, 0)
    cases = np.arange(size)
    out = {}
    for key, width in (("u", n), ("F", n), ("internal", None), ("load", 0)):
        array = result.steps.get(key)
        if array is None:
            out[key] = np.zeros((size,) if width == 0 else (size, n))
            continue
        values = np.array(array[cases, last], dtype=float) if array.shape[1] else np.zeros((size,) + array.shape[2:])
        values[result.n_steps == 0] = 0.0
        out[key] = values
    return out


def _value(value: Any, current: float, values: dict[str, np.ndarray], case: int) -> float:
    if isinstance(value, str):
        return current if value == CURRENT else float(np.asarray(values[value]).reshape(-1)[case])
    return float(value)


def motion_equations(
    batch: Any, stage: DynamicStage, end: dict[str, np.ndarray], values: dict[str, np.ndarray], case: int
) -> tuple[MotionEquations, np.ndarray]:
    """The equations of case ``case`` of ``batch`` (a :class:`~ncstab.paths.model_batch.ModelBatch`)
    started from its path's end ``end`` under ``stage``, and its internal variables there."""
    definition = batch.definition
    n = definition.n_dof
    u = np.array(end["u"][case], dtype=float)
    forces = np.array(end["F"][case], dtype=float)
    free = np.ones(n, dtype=bool)
    for i, (dof, force) in enumerate(zip(definition.dofs, definition.forces)):
        if dof in stage.hold:
            free[i] = False
            u[i] = _value(stage.hold[dof], u[i], values, case)
        elif force in stage.hold:
            forces[i] = _value(stage.hold[force], forces[i], values, case)
        u[i] += stage.perturbation.get(dof, 0.0)
    load_name = definition.load_parameter
    load = float(end["load"][case]) if definition.load is not None else 0.0
    if load_name is not None and load_name in stage.hold:
        load = _value(stage.hold[load_name], load, values, case)
    equations = MotionEquations(batch.take(np.array([case])), free, forces, load, u)
    return equations, np.asarray(end["internal"][case], dtype=float).reshape(-1)


def follow_motions(path: PathResult, stage: DynamicStage, keep_solution: bool = False) -> list[list[Motion | None]]:
    """Every case's motion: per law, per flat case (``None`` where its path failed)."""
    from ncstab.paths.api import Model, case_batch

    model = path.model
    definition = model.definition
    # every system as a ModelBatch (the reduced diamond too: its symbolic definition, the same mechanics)
    plain = Model(definition, model.laws, None, model.secondary_contacts)
    values = path.grid.case_values()
    size = path.grid.size
    scale = max([abs(v) for v in stage.perturbation.values() if v != 0.0], default=1e-3)
    motions: list[list[Motion | None]] = []
    for law, result in zip(model.laws, path.results):
        batch = case_batch(law, plain, values, size)
        _ = batch._rows  # computed once for the whole batch, kept by each case's take
        end = _end_states(result, definition.n_dof)
        per_case: list[Motion | None] = []
        for case in range(size):
            if str(result.status[case]).startswith("failed"):
                per_case.append(None)
                continue
            equations, internal = motion_equations(batch, stage, end, values, case)
            watch = event_watch(equations, stage.kinetic_energy_threshold, stage.stop_at)
            per_case.append(
                integrate_motion(equations, internal, stage.duration, stage.samples, stage.method, stage.rtol,
                                 scale, keep_solution, watch)
            )
        motions.append(per_case)
    return motions


def motion_dataset(path: PathResult, stage: DynamicStage, motions: list[list[Motion | None]]) -> xr.Dataset:
    """The ``time`` variables of every case (dims: ``law``, the sweep, ``time``[, ``dof``])."""
    import xarray as xr

    definition = path.model.definition
    n = definition.n_dof
    shape = path.shape
    samples = stage.samples
    sweep_dims = ["law", *path.grid.sweep]
    flat = [motion for per_law in motions for motion in per_law]
    arrays: dict[str, np.ndarray] = {
        "u_t": np.full((len(flat), samples, n), np.nan),
        "velocity": np.full((len(flat), samples, n), np.nan),
        **{name: np.full((len(flat), samples), np.nan) for name in ("kinetic_energy", "external_work", "internal_work", "dissipated_work")},
    }
    status = np.full(len(flat), NOT_RUN, dtype=object)
    message = np.full(len(flat), "the path before the dynamic stage failed", dtype=object)
    steps = np.zeros(len(flat), dtype=np.int32)
    for k, motion in enumerate(flat):
        if motion is None:
            continue
        arrays["u_t"][k], arrays["velocity"][k] = motion.u, motion.velocity
        for name in ("kinetic_energy", "external_work", "internal_work", "dissipated_work"):
            arrays[name][k] = getattr(motion, name)
        status[k], message[k], steps[k] = motion.status, motion.message, motion.steps
    attributes = motion_variables(definition)
    time_dims = [*sweep_dims, "time"]
    data = {
        "u_t": (time_dims + ["dof"], arrays["u_t"].reshape(shape + (samples, n))),
        "velocity": (time_dims + ["dof"], arrays["velocity"].reshape(shape + (samples, n))),
        **{name: (time_dims, arrays[name].reshape(shape + (samples,)))
           for name in ("kinetic_energy", "external_work", "internal_work", "dissipated_work")},
        "motion_status": (sweep_dims, status.astype(str).reshape(shape)),
        "motion_message": (sweep_dims, message.astype(str).reshape(shape)),
        "motion_steps": (sweep_dims, steps.reshape(shape)),
    }
    attributes.update(motion_event_variables(definition, stage))
    data.update(_event_data(definition, stage, flat, shape, sweep_dims))
    dataset = xr.Dataset(
        {name: xr.Variable(dims, values, dict(zip(("units", "long_name", "description"), attributes[name])))
         for name, (dims, values) in data.items()}
    )
    time = np.linspace(0.0, stage.duration, samples)
    dataset = dataset.assign_coords(time=xr.Variable("time", time, dict(zip(("units", "long_name", "description"), attributes["time"]))))
    return dataset


def _watched_events(definition: Any, stage: DynamicStage) -> tuple[str, ...]:
    """The events a motion of ``stage`` looks for: a contact closing where the system has gaps,
    the kinetic energy where the stage gives a threshold."""
    return (("contact_closing",) if definition.gaps else ()) + (
        ("kinetic_energy",) if stage.kinetic_energy_threshold is not None else ()
    )


def motion_event_variables(definition: Any, stage: DynamicStage) -> dict[str, tuple[str, str, str]]:
    """name -> (units, long_name, description) of the variables of the located motion events
    (:mod:`ncstab.dynamics.motion_events`): ``motion_<event>_time``, ``_u``, ``_velocity``,
    ``_kinetic_energy``, and ``motion_contact_closing_gap``."""
    time, energy = _time_unit(definition), _energy_unit(definition)
    what = {
        "contact_closing": "secondary contact closing (an open gap between non-neighbour grains reaching 0)",
        "kinetic_energy": f"kinetic energy reaching the stage's kinetic_energy_threshold = {stage.kinetic_energy_threshold!r}",
    }
    out: dict[str, tuple[str, str, str]] = {}
    for event in _watched_events(definition, stage):
        prefix, first = f"motion_{event}", f"the first {what[event]} during the motion"
        located = "located by root finding on the integrator's dense output; NaN if none"
        out[f"{prefix}_time"] = ("1", f"time of motion event {event}", f"time since the dynamic stage began of {first}, in units of {time}; {located}")
        out[f"{prefix}_u"] = (definition.units.displacement, f"displacements at motion event {event}", f"{definition.units.displacement_description} at {first}; NaN if none")
        out[f"{prefix}_velocity"] = ("1", f"velocities at motion event {event}", f"du/dt of each dof at {first}, dof units per unit of time ({time}); NaN if none")
        out[f"{prefix}_kinetic_energy"] = ("1", f"kinetic energy at motion event {event}", f"w u'^T M(u) u' / 2 at {first}, in units of {energy}; NaN if none")
    if definition.gaps:
        names = ", ".join(g.name for g in definition.gaps)
        out["motion_contact_closing_gap"] = ("", "gap that closed", f"the name of the first gap to close during the motion ({names}); empty if none")
    return out


def _event_data(definition: Any, stage: DynamicStage, flat: list[Motion | None], shape: tuple[int, ...],
                sweep_dims: list[str]) -> dict[str, tuple[list[str], np.ndarray]]:
    """The arrays of :func:`motion_event_variables`, NaN (empty gap name) where an event is not met."""
    n = definition.n_dof
    data: dict[str, tuple[list[str], np.ndarray]] = {}
    for event in _watched_events(definition, stage):
        time, kinetic = np.full(len(flat), np.nan), np.full(len(flat), np.nan)
        u, velocity = np.full((len(flat), n), np.nan), np.full((len(flat), n), np.nan)
        gap = np.full(len(flat), "", dtype=object)
        for k, motion in enumerate(flat):
            located = None if motion is None else motion.events.get(event)
            if located is not None:
                time[k], kinetic[k], u[k], velocity[k], gap[k] = (located.time, located.kinetic_energy, located.u,
                                                                  located.velocity, located.gap)
        prefix = f"motion_{event}"
        data[f"{prefix}_time"] = (sweep_dims, time.reshape(shape))
        data[f"{prefix}_u"] = (sweep_dims + ["dof"], u.reshape(shape + (n,)))
        data[f"{prefix}_velocity"] = (sweep_dims + ["dof"], velocity.reshape(shape + (n,)))
        data[f"{prefix}_kinetic_energy"] = (sweep_dims, kinetic.reshape(shape))
        if event == "contact_closing":
            data[f"{prefix}_gap"] = (sweep_dims, gap.astype(str).reshape(shape))
    return data
