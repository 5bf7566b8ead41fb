"""Events during a motion, located on the integrator's dense output.

Each event is the first time a scalar indicator of the state, positive before
it, reaches zero:

===================  ===============================================================
event                indicator
===================  ===============================================================
``contact_closing``  each gap g_k(u) of the system's secondary contacts (the
                     diamond's 2 (cos alpha0 - Delta_1) - 1 and 2 (sin alpha0 -
                     Delta_2) - 1, a ring's centre distances minus 2R): a contact
                     closes where an open gap (> 0) reaches 0            (1)
``kinetic_energy``   E - w u'^T M(u) u' / 2, E the stage's
                     ``kinetic_energy_threshold``: the kinetic energy reaches E
                     from below                                            (2)
===================  ===============================================================

The gaps are the model kernel's gap column (:mod:`ncstab.operators.model_kernel`,
from the system definition's ``gaps``), the functions whose sign changes are the
path engine's ``secondary_contact`` event; the kinetic energy is the one stored
along the motion (:meth:`~ncstab.dynamics.equations.MotionEquations.kinetic_energy`).
Both come from one kernel evaluation of the state.

After each accepted step [t0, t1] of the integrator the indicators are
evaluated on the step's dense output (DOP853's interpolant of order 7, Radau's
of order 3) at :data:`SUBDIVISIONS` equal parts of the step, its end included,
and compared with their values at the part's start: an indicator > 0 at the
start of a part and <= 0 at its end is located by Brent's method on the dense
output, the bracket shrunk to a few units in the last place of t, so the
located time is as accurate as the motion itself and the indicator there is
zero to rounding.  The parts matter: an excursion shorter than a step, both
ends on one side, is real (Ziegler's pendulum under a dead load P = 0.2
released from phi1 = 0.3 has its kinetic energy above 0.0806 over
[6.4302, 6.4898], inside one step of this DOP853 at its default tolerance,
[6.3898, 6.4957], and of scipy's ``solve_ivp`` at rtol = 1e-12, [6.4274,
6.4929], whose event location compares the step ends only); one shorter than
a part is still not seen.  An event is located once, at its
first occurrence (for ``contact_closing``, the first gap of the system to
close).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np
from scipy.optimize import brentq

from ncstab.dynamics.equations import MotionEquations
from ncstab.dynamics.stage import MOTION_EVENTS

__all__ = ["EventWatch", "MotionEvent", "event_watch"]

#: Relative tolerance of the located time (Brent's method): a few units in the last place.
TIME_RTOL = 4 * np.finfo(float).eps
#: Equal parts of each accepted step at whose ends the indicators are compared.
SUBDIVISIONS = 4


@dataclass(frozen=True)
class MotionEvent:
    """One located event of a motion.

    Attributes
    ----------
    name
        ``contact_closing`` or ``kinetic_energy`` (:data:`~ncstab.dynamics.stage.MOTION_EVENTS`).
    time
        The located time since the stage began.
    u, velocity
        ``(n,)`` displacements and velocities there (held dofs included).
    kinetic_energy
        w u'^T M(u) u' / 2 there.
    gap
        The name of the gap that closed (``contact_closing``), else ``""``.
    """

    name: str
    time: float
    u: np.ndarray
    velocity: np.ndarray
    kinetic_energy: float
    gap: str = ""


class EventWatch:
    """The indicators (1), (2) of one motion, checked after each accepted step on
    :data:`SUBDIVISIONS` parts of it.

    Parameters
    ----------
    equations
        The motion's equations (the kernel, the state's layout, the gaps).
    threshold
        The kinetic energy of the ``kinetic_energy`` event, or ``None`` (not watched).
    stop_at
        The events that end the motion.
    """

    def __init__(self, equations: MotionEquations, threshold: float | None, stop_at: Sequence[str] = ()) -> None:
        self.equations = equations
        self.threshold = threshold
        self.stop_at = tuple(stop_at)
        layout = equations.layout
        self.gaps = slice(layout.gaps, layout.gaps + layout.n_gaps)
        self.gap_names = tuple(g.name for g in equations.batch.definition.gaps)
        #: The event of each indicator column: the kinetic energy's first (if watched), then one per gap.
        self.columns = (("kinetic_energy",) if threshold is not None else ()) + ("contact_closing",) * layout.n_gaps
        #: The events located so far, by name.
        self.located: dict[str, MotionEvent] = {}
        self._previous: np.ndarray | None = None

    def indicators(self, y: np.ndarray) -> np.ndarray:
        """The indicators (2), (1) at a state ``y`` of the motion, positive before their event."""
        equations = self.equations
        u, velocity, internal, _ = equations.split(y)
        row = equations.evaluate(u, internal)
        values = []
        if self.threshold is not None:
            values.append(self.threshold - equations.kinetic_energy_of_row(row, velocity))
        values.extend(row[self.gaps])
        return np.array(values, dtype=float)

    def start(self, y0: np.ndarray) -> None:
        """The indicators at the motion's start (an event at t = 0 is not one: nothing crossed)."""
        self._previous = self.indicators(y0)

    def check_step(self, t0: float, t1: float, y1: np.ndarray, interpolant: Callable[[float], np.ndarray]) -> list[MotionEvent]:
        """The events located in the accepted step [t0, t1] (ending at ``y1``; ``interpolant``
        its dense output), in time order, up to the first that ends the motion.

        Records them in :attr:`located`; an event already located is not looked for again.
        """
        times = np.linspace(t0, t1, SUBDIVISIONS + 1)
        times[-1] = t1
        values = np.array([self._previous] + [self.indicators(interpolant(t)) for t in times[1:-1]]
                          + [self.indicators(y1)])
        self._previous = values[-1]
        found: dict[str, MotionEvent] = {}
        for column, name in enumerate(self.columns):
            # the first part whose start is > 0 and end <= 0 (NaN compares False: no event)
            parts = np.flatnonzero((values[:-1, column] > 0) & (values[1:, column] <= 0))
            if name in self.located or not parts.size:
                continue
            a, b = times[parts[0]], times[parts[0] + 1]
            time = b if values[parts[0] + 1, column] == 0 else self._locate(column, a, b, interpolant)
            if name in found and found[name].time <= time:
                continue
            gap = self.gap_names[column - (len(self.columns) - len(self.gap_names))] if name == "contact_closing" else ""
            found[name] = self._event(name, time, interpolant(time), gap)
        events = sorted(found.values(), key=lambda event: event.time)
        stop = self.first_stop(events)
        if stop is not None:  # what follows the stop within the step does not happen
            events = [event for event in events if event.time <= stop.time]
        self.located.update({event.name: event for event in events})
        return events

    def _locate(self, column: int, t0: float, t1: float, interpolant: Callable[[float], np.ndarray]) -> float:
        """The zero of indicator ``column`` in [t0, t1] on the dense output (Brent's method)."""
        return float(brentq(lambda t: self.indicators(interpolant(t))[column], t0, t1,
                            xtol=TIME_RTOL * max(abs(t1), 1.0), rtol=TIME_RTOL, maxiter=200))

    def _event(self, name: str, time: float, y: np.ndarray, gap: str) -> MotionEvent:
        u, velocity, internal, _ = self.equations.split(y)
        kinetic = self.equations.kinetic_energy(u, velocity, internal)
        return MotionEvent(name, float(time), u, velocity, kinetic, gap)

    def first_stop(self, events: Sequence[MotionEvent]) -> MotionEvent | None:
        """The first of ``events`` (in time order) that ends the motion, or ``None``."""
        return next((event for event in events if event.name in self.stop_at), None)


def event_watch(equations: MotionEquations, threshold: float | None, stop_at: Sequence[str] = ()) -> EventWatch | None:
    """The watch of a motion's events, or ``None`` where there is nothing to watch (no
    threshold and no gap)."""
    if threshold is None and not equations.layout.n_gaps:
        return None
    unknown = set(stop_at) - set(MOTION_EVENTS)
    if unknown:
        raise ValueError(f"unknown motion events {sorted(unknown)}; events are: {', '.join(MOTION_EVENTS)}")
    return EventWatch(equations, threshold, stop_at)
