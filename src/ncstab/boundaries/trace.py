"""``ncstab.boundary``: a stability boundary traced as a curve in (parameter, state, load).

For each case (law and sweep values other than the boundary parameter), one
path is followed at ``parameter = start`` (:func:`ncstab.follow`, the
programme's last stage stopping at the event) and its located event is the
first point; from there the event's condition appended to the equilibrium
equations (:mod:`ncstab.boundaries.conditions`) is continued by
pseudo-arclength (:mod:`ncstab.boundaries.continuation`) to ``stop``.  A
rate-form (hypoelastic) law has no total form to append the condition to: its
curve is shot along paths, one per point (:mod:`ncstab.boundaries.shooting`).
"""

from __future__ import annotations

import dataclasses
import itertools
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ncstab.boundaries.conditions import (
    BOUNDARY_EVENTS,
    DYNAMIC_EVENTS,
    BoundaryError,
    BoundaryProblem,
    stage_controls,
)
from ncstab.boundaries.coalescence import coalescing_pair, is_undamped
from ncstab.boundaries.continuation import ContinuationOptions, CurvePoint, trace_curve
from ncstab.paths.api import case_batch, follow, resolve_model
from ncstab.paths.programme import LoadingProgramme, parse_programme

__all__ = ["BoundaryCurve", "boundary", "check_boundary", "trace_case"]


@dataclasses.dataclass(frozen=True)
class BoundaryCurve:
    """One traced curve: its points ``X`` ``(m, N)``, notes, status and message.

    ``forces`` and ``loads`` are given where they are not evaluated from ``X``
    (a curve shot along paths of a rate-form law, :mod:`ncstab.boundaries.shooting`).
    """

    X: np.ndarray
    notes: tuple[str, ...]
    status: str
    message: str
    forces: np.ndarray | None = None
    loads: np.ndarray | None = None


def _programme(model, programme) -> LoadingProgramme:
    definition = model.definition
    if isinstance(programme, LoadingProgramme):
        return programme
    return parse_programme(programme, definition.dofs, definition.forces, definition.load_parameter,
                           getattr(definition, "hold_other_forces", False))


def check_boundary(model, programme: LoadingProgramme, parameters: Mapping[str, Any], event: str, parameter: str, start: float, stop: float) -> None:
    """Reject a boundary that cannot be traced, naming the field (``boundary.event``, ...).

    Raises
    ------
    BoundaryError
        An unknown event or one the system cannot have (flutter or divergence
        without inertia; det K that never vanishes), a parameter the study does
        not have, ``start == stop``, or stage values that depend on the path.
    """
    if event not in BOUNDARY_EVENTS:
        raise BoundaryError("boundary.event", f"unknown event {event!r}; allowed: {', '.join(BOUNDARY_EVENTS)}")
    definition = model.definition
    if event in DYNAMIC_EVENTS and not definition.has_inertia:
        raise BoundaryError("boundary.event", f"{event} needs inertia (M, C), and system {definition.name!r} has none")
    if parameter not in parameters:
        raise BoundaryError(
            "boundary.parameter", f"{parameter!r} is not a parameter of the study; parameters: {', '.join(parameters) or 'none'}"
        )
    if not (np.isfinite(start) and np.isfinite(stop)):
        raise BoundaryError("boundary.start", "start and stop must be finite numbers")
    if start == stop:
        raise BoundaryError("boundary.stop", f"stop = start = {start}: the curve needs a range")
    stage_controls(programme, definition.dofs, definition.forces, definition.load_parameter)
    if event in ("limit_point", "divergence") and _constant_det(model, parameters, parameter, start, stop):
        raise BoundaryError("boundary.event", f"det K of system {definition.name!r} is constant and nonzero: it has no {event}")


def _fixed(parameters: Mapping[str, Any], parameter: str, value: float) -> dict[str, float]:
    """The first value of every parameter, ``parameter`` set to ``value``."""
    out = {k: (v[0] if isinstance(v, (list, tuple)) else v) for k, v in parameters.items()}
    out[parameter] = value
    return out


def _constant_det(model, parameters, parameter, start, stop) -> bool:
    """Whether det K takes the same nonzero value at random states, loads and parameter values."""
    generator = np.random.default_rng(0)
    size, n = 8, len(model.definition.dofs)
    values = {k: np.full(size, float(v)) for k, v in _fixed(parameters, parameter, start).items()}
    values[parameter] = generator.uniform(min(start, stop), max(start, stop), size)
    batch = case_batch(model.laws[0], model, values, size)
    u = generator.uniform(-0.05, 0.05, (size, n))
    load = generator.uniform(0.0, 5.0, size) if model.definition.load_parameter else None
    det = np.linalg.det(batch.evaluate(u, np.zeros((size, batch.n_internal)), None, load=load).stiffness)
    return bool(np.all(np.isfinite(det)) and abs(det[0]) > 1e-8 and np.ptp(det) <= 1e-10 * abs(det[0]))


def _start_point(model, law, programme, values, event, problem: BoundaryProblem) -> np.ndarray:
    """The event located on the path at the start value: the first guess of the curve."""
    stages = list(programme.stages)
    last = stages[-1]
    if event not in last.stop_at and event != "divergence":
        stages[-1] = dataclasses.replace(last, stop_at=tuple(last.stop_at) + (event,))
    try:
        path = follow(model, [law], LoadingProgramme(tuple(stages), None), values)
    except ValueError:  # the engine does not stop at this event: follow the whole stage
        path = follow(model, [law], LoadingProgramme(tuple(programme.stages), None), values)
    dataset = path.to_dataset()
    if "law" in dataset.dims:  # a model of several laws follows them all: this case's law
        dataset = dataset.sel(law=law.name)
    name = f"{event}_u"
    if name not in dataset or not np.all(np.isfinite(dataset[name].values)):
        raise ValueError(f"the path meets no {event} at {problem.parameter} = {values[problem.parameter]}")
    stage = int(np.ravel(dataset[f"{event}_stage"].values)[0])
    if stage != len(programme.stages) - 1:
        raise ValueError(f"the first {event} at {problem.parameter} = {values[problem.parameter]} is in stage {stage + 1}, not in the last stage")
    u = np.ravel(dataset[name].values).astype(float)
    n = problem.n
    if problem.controls.load_stage:
        lam = float(np.ravel(dataset[f"{event}_load"].values)[0])
    else:
        i = problem.controls.first
        lam = float(u[i] if not problem.controls.force_controlled[i] else np.ravel(dataset[f"{event}_F"].values)[i])
    X = np.concatenate([[values[problem.parameter]], u, [lam], np.zeros(problem.n_extra)])
    if event == "flutter_onset":
        evaluation, _ = problem.evaluate(X[None, :])
        K, M = evaluation.stiffness[0], evaluation.mass[0]
        if _undamped_range(problem, X, evaluation):
            problem.coalescence = True
            omega, v, w = coalescing_pair(K, M)
            problem.normal = v.astype(complex)
            X[2 + n], X[3 + n : 3 + 2 * n], X[3 + 2 * n :] = omega, v, w
            problem.update(X)
            return X
        C = evaluation.damping[0] if evaluation.damping is not None else np.zeros_like(K)
        companion = np.block([[np.zeros((n, n)), np.eye(n)], [-np.linalg.solve(M, K), -np.linalg.solve(M, C)]])
        roots, vectors = np.linalg.eig(companion)
        upper = np.where(roots.imag > 0, np.abs(roots.real), np.inf)
        k = int(np.argmin(upper))
        v = vectors[:n, k]
        v = v / np.linalg.norm(v)
        problem.normal = v.copy()
        X[2 + n] = roots[k].imag
        X[3 + n : 3 + 2 * n], X[3 + 2 * n :] = v.real, v.imag
    problem.update(X)
    return X


def _undamped_range(problem: BoundaryProblem, X: np.ndarray, evaluation) -> bool:
    """Whether C vanishes at the start point and with the parameter at the other end of its range."""
    if not is_undamped(evaluation.damping):
        return False
    if problem.stop is None:
        return True
    other = X.copy()
    other[0] = problem.stop
    return is_undamped(problem.evaluate(other[None, :])[0].damping)


def trace_case(model, law, programme: LoadingProgramme, values: Mapping[str, float], event: str, parameter: str, start: float, stop: float, options: ContinuationOptions) -> tuple[BoundaryCurve, BoundaryProblem]:
    """The boundary curve of one case (``values``: every parameter as a float)."""
    definition = model.definition
    controls = stage_controls(programme, definition.dofs, definition.forces, definition.load_parameter)
    others = {k: v for k, v in values.items() if k != parameter}
    problem = BoundaryProblem(model, law, parameter, others, controls, event, stop=stop)
    if not _total_form(model, law, values):
        return _shot(model, law, programme, values, event, parameter, start, stop, problem), problem
    first = start
    try:
        X0 = _start_point(model, law, programme, {**others, parameter: start}, event, problem)
    except ValueError as error:
        first = _first_met(model, law, programme, others, event, parameter, start, stop, problem)
        if first is None:
            return BoundaryCurve(np.zeros((0, problem.size)), (), "failed:no_start", str(error)), problem
        X0 = _start_point(model, law, programme, {**others, parameter: first}, event, problem)
    points: list[CurvePoint] = trace_curve(problem.residual, X0, stop, options, problem.update, origin=start)
    if first != start and points[0].note == "start":
        points[0].note = f"start: no {event} in the last stage for {parameter} from {start} to here"
    X = np.array([point.X for point in points])
    notes = tuple(point.note for point in points)
    last = notes[-1]
    if last.startswith("failed") or "failed" in last:
        status, message = "failed:continuation", last
    elif last.startswith("max_points"):
        status, message = "failed:max_points", last
    else:
        status, message = "finished", f"{len(points)} points, {last}"
    return BoundaryCurve(X, notes, status, message), problem


def _first_met(model, law, programme, others, event, parameter, start, stop, problem, samples: int = 41) -> float | None:
    """The first of ``samples`` values from start to stop where the path meets the event in its last stage."""
    from ncstab.boundaries.shooting import _located

    p = np.linspace(start, stop, samples)[1:]
    u = _located(model, law, programme, others, event, parameter, p, lambda u, F, load: u[:, 0])[0]
    met = np.flatnonzero(np.isfinite(u[:, 0]))
    if not met.size:
        return None
    try:
        _start_point(model, law, programme, {**others, parameter: float(p[met[0]])}, event, problem)
    except ValueError:
        return None
    return float(p[met[0]])


def _total_form(model, law, values: Mapping[str, float]) -> bool:
    batch = case_batch(law, model, {k: np.array([float(v)]) for k, v in values.items()}, 1)
    return bool(batch.has_total_form)


def _shot(model, law, programme, values, event, parameter, start, stop, problem: BoundaryProblem) -> BoundaryCurve:
    """The curve of a rate-form law, one path per point (:func:`ncstab.boundaries.shooting.shoot_curve`)."""
    from ncstab.boundaries.shooting import shoot_curve

    others = {k: v for k, v in values.items() if k != parameter}
    shot = shoot_curve(model, law, programme, others, event, parameter, start, stop)
    m, n = shot["p"].size, problem.n
    if not m:
        return BoundaryCurve(np.zeros((0, problem.size)), (), "failed:no_event",
                             f"the paths meet no {event} in the last stage for {parameter} in [{start}, {stop}]")
    X = np.full((m, problem.size), np.nan)
    X[:, 0], X[:, 1 : 1 + n], X[:, 1 + n] = shot["p"], shot["u"], shot["load"]
    message = f"{m} points, shot along the paths (rate-form law {law.name!r}: one path per point)"
    return BoundaryCurve(X, shot["notes"], "finished", message, forces=shot["F"], loads=shot["load"])


def boundary(
    system: Any,
    laws: Sequence[Any] | Any | None = None,
    programme: LoadingProgramme | Sequence[Mapping[str, Any]] = (),
    parameters: Mapping[str, Any] | None = None,
    *,
    event: str,
    parameter: str,
    start: float,
    stop: float,
    options: ContinuationOptions | None = None,
    secondary_contacts: str | None = None,
):
    """Trace the boundary of ``event`` along ``parameter`` from ``start`` to ``stop``.

    Parameters
    ----------
    system, laws, programme, parameters, secondary_contacts
        As for :func:`ncstab.follow`; the event is met in the programme's last stage.
        A swept parameter (a list) other than ``parameter`` gives one curve per value.
    event
        ``limit_point``, ``hill_loss``, ``bifurcation``, ``flutter_onset`` or ``divergence``.
    parameter
        The parameter the curve runs along (a key of ``parameters``).
    start, stop
        Its range.
    options
        Continuation options.

    Returns
    -------
    xarray.Dataset
        Dimension ``point`` (after ``law`` and the other sweep dimensions):
        ``boundary_<parameter>``, ``boundary_load`` (systems with a load
        parameter), ``boundary_u`` and ``boundary_F`` (point, dof),
        ``boundary_note``, ``n_points``, ``status``, ``message``
        (:func:`ncstab.boundaries.dataset.boundary_dataset`).

    Raises
    ------
    BoundaryError
        Input that cannot give a boundary, naming the field.
    """
    from ncstab.boundaries.dataset import boundary_dataset

    model = resolve_model(system, laws, secondary_contacts)
    programme = _programme(model, programme)
    parameters = dict(parameters or {})
    check_boundary(model, programme, parameters, event, parameter, float(start), float(stop))
    options = options or ContinuationOptions()
    sweep = {k: list(v) for k, v in parameters.items() if isinstance(v, (list, tuple)) and k != parameter}
    fixed = {k: float(v) for k, v in parameters.items() if not isinstance(v, (list, tuple)) and k != parameter}
    curves, problems = [], []
    for law in model.laws:
        for combination in itertools.product(*sweep.values()):
            values = {**fixed, **dict(zip(sweep, map(float, combination))), parameter: float(start)}
            curve, problem = trace_case(model, law, programme, values, event, parameter, float(start), float(stop), options)
            curves.append(curve)
            problems.append(problem)
    return boundary_dataset(model, curves, problems, sweep, parameter, event, float(start), float(stop))
