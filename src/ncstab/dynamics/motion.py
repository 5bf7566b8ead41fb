"""Integrating one case's motion in time: :func:`integrate_motion` -> :class:`Motion`.

The first-order system of :class:`~ncstab.dynamics.equations.MotionEquations` is
integrated by one of scipy's adaptive Runge-Kutta solvers (``DOP853``, explicit,
order 8 with a 7th-order dense output; ``Radau``, implicit, for stiff motions),
stepped by hand so that each accepted step's dense output fills the stored
times it covers and a motion that leaves the model's admissible domain (a
contact length through zero, a bar at right angles) stops there with what it
has: the right-hand side is NaN outside the domain, so the solver cannot step
across it and ends with a step-size failure at its edge, recorded as
``stopped:left_domain``.  The events of a motion (a secondary contact closing,
a kinetic-energy threshold) are located after each accepted step on its dense
output (:mod:`ncstab.dynamics.motion_events`); one the stage stops at ends the
motion there (``stopped:<event>``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.integrate import DOP853, OdeSolution, Radau

from ncstab.dynamics.equations import MotionEquations
from ncstab.dynamics.motion_events import EventWatch, MotionEvent

__all__ = ["MAX_STEPS", "Motion", "integrate_motion"]

#: The solvers of :data:`ncstab.dynamics.stage.METHODS`.
SOLVERS = {"DOP853": DOP853, "Radau": Radau}
#: The most accepted steps of one motion.
MAX_STEPS = 2_000_000


@dataclass
class Motion:
    """One case's motion at the stored times (NaN after it stopped).

    Attributes
    ----------
    time
        ``(S,)`` stored times.
    u, velocity
        ``(S, n)`` displacements and velocities.
    internal
        ``(S, n_internal)`` internal variables of rate-form laws.
    kinetic_energy, external_work, internal_work, dissipated_work
        ``(S,)``: w u'^T M u' / 2 and the works of Eq. (5) of
        :mod:`ncstab.dynamics.equations` since the stage began.
    status, message
        ``finished``, ``stopped:left_domain``, ``stopped:<event>`` (an event the
        stage stops at) or ``failed:<reason>``, and what happened.
    steps, evaluations
        Accepted steps and right-hand-side evaluations.
    solution
        The dense output over the whole motion (:class:`scipy.integrate.OdeSolution`
        of the state ``[u_f, u_f', z, W_ext, W_int, W_diss]``), or ``None``.
    events
        The located events by name (:class:`~ncstab.dynamics.motion_events.MotionEvent`;
        an event the motion never met is absent).
    """

    time: np.ndarray
    u: np.ndarray
    velocity: np.ndarray
    internal: np.ndarray
    kinetic_energy: np.ndarray
    external_work: np.ndarray
    internal_work: np.ndarray
    dissipated_work: np.ndarray
    status: str
    message: str
    steps: int = 0
    evaluations: int = 0
    solution: OdeSolution | None = field(default=None, repr=False)
    events: dict[str, MotionEvent] = field(default_factory=dict)

    @property
    def energy_balance(self) -> np.ndarray:
        """``(S,)`` kinetic_energy - (external_work - internal_work - dissipated_work): 0 exactly."""
        return self.kinetic_energy - (self.external_work - self.internal_work - self.dissipated_work)


def _tolerances(equations: MotionEquations, scale: float, rtol: float) -> np.ndarray:
    """Absolute tolerances per state: rtol times the motion's scale (its perturbation) for u, u'
    and z, times its square for the works."""
    m, k = equations.m, equations.n_internal
    return np.concatenate([np.full(2 * m + k, rtol * scale), np.full(3, rtol * scale * scale)])


def integrate_motion(
    equations: MotionEquations,
    internal: np.ndarray,
    duration: float,
    samples: int,
    method: str = "DOP853",
    rtol: float = 1e-11,
    scale: float = 1.0,
    keep_solution: bool = False,
    watch: EventWatch | None = None,
) -> Motion:
    """Integrate Eq. (2), (4), (5) of :mod:`ncstab.dynamics.equations` from rest at the start.

    Parameters
    ----------
    equations
        The case's equations (starting displacements included).
    internal
        ``(n_internal,)`` the internal variables at the start.
    duration, samples
        Integrate over [0, duration]; store ``samples`` equally spaced times.
    method, rtol
        The solver and its relative tolerance.
    scale
        The motion's size (the largest perturbation): the absolute tolerances
        are ``rtol * scale`` (``rtol * scale**2`` for the works).
    keep_solution
        Keep the dense output (:attr:`Motion.solution`) of the whole motion.
    watch
        The motion's events (:func:`~ncstab.dynamics.motion_events.event_watch`),
        located after each accepted step; ``None``: none.

    Returns
    -------
    Motion
    """
    times = np.linspace(0.0, duration, samples)
    y0 = equations.initial_state(internal)
    states = np.full((samples, y0.size), np.nan)
    states[0] = y0
    solver = SOLVERS[method](
        equations, 0.0, y0, duration, rtol=rtol, atol=_tolerances(equations, scale, rtol)
    )
    stored, steps = 1, 0
    knots, interpolants = [0.0], []
    status, message = "finished", f"integrated to t = {duration:g}"
    if watch is not None:
        watch.start(y0)
    while solver.status == "running":
        failure = solver.step()
        if solver.status == "failed":
            if equations.left_domain:  # the solver cannot step across the domain's edge (NaN beyond it)
                status = "stopped:left_domain"
                message = f"the motion left the admissible domain near t = {solver.t:.6g}"
            else:
                status, message = "failed:step_size_underflow", f"the integrator failed at t = {solver.t:.6g}: {failure}"
            break
        steps += 1
        interpolant = solver.dense_output()
        if keep_solution:
            knots.append(solver.t)
            interpolants.append(interpolant)
        stop = None
        if watch is not None:
            stop = watch.first_stop(watch.check_step(solver.t_old, solver.t, solver.y, interpolant))
        reached = solver.t if stop is None else stop.time
        end = np.searchsorted(times, reached, side="right")
        if end > stored:
            states[stored:end] = interpolant(times[stored:end]).T
            stored = end
        if stop is not None:
            status = f"stopped:{stop.name}"
            message = _stop_message(stop, watch)
            break
        if steps >= MAX_STEPS and solver.status == "running":
            status, message = "failed:max_steps", f"more than {MAX_STEPS:,} steps before t = {duration:g}"
            break
    if status == "finished" and stored < samples:  # the last stored time is the end itself
        states[stored:] = solver.y
    u, velocity, z, works = equations.split(states)
    kinetic = np.full(samples, np.nan)
    for index in np.flatnonzero(np.isfinite(states).all(axis=1)):
        kinetic[index] = equations.kinetic_energy(u[index], velocity[index], z[index])
    solution = OdeSolution(np.array(knots), interpolants) if keep_solution and interpolants else None
    return Motion(
        time=times,
        u=u,
        velocity=velocity,
        internal=z,
        kinetic_energy=kinetic,
        external_work=works[:, 0],
        internal_work=works[:, 1],
        dissipated_work=works[:, 2],
        status=status,
        message=message,
        steps=steps,
        evaluations=equations.evaluations,
        solution=solution,
        events={} if watch is None else dict(watch.located),
    )


def _stop_message(event: MotionEvent, watch: EventWatch) -> str:
    """What stopped the motion, in words."""
    if event.name == "contact_closing":
        return f"the secondary contact {event.gap} closed at t = {event.time:.10g} (stop_at)"
    return f"the kinetic energy reached {watch.threshold:g} at t = {event.time:.10g} (stop_at)"
