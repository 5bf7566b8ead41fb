"""A dynamic stage: what happens after the loss of stability, in time.

A dynamic stage starts from the state where the previous stage of the programme
ended (or from rest), displaces it by a ``perturbation`` (per dof, in the dofs'
units) with zero velocity, and integrates the nonlinear equations of motion

    M(u) u'' + Gamma(u, u') + C u' + R(u, lambda) = F_control              (1)

for ``duration`` units of time under the stage's controls: every dof's force is
held (at the value it has when the stage starts unless the stage says otherwise)
or its displacement is held (``hold = { D1 = "current" }``: u_D1 stays put and
its reaction does no work); the load parameter lambda is held.  Gamma is the
Christoffel (centripetal and Coriolis) term of a configuration-dependent mass
(:mod:`ncstab.dynamics.equations`).

Events during the motion (:data:`MOTION_EVENTS`, located by
:mod:`ncstab.dynamics.motion_events`): ``contact_closing``, a secondary contact
closing (a gap of the system reaching 0 from open), and ``kinetic_energy``, the
kinetic energy reaching the stage's ``kinetic_energy_threshold``.  Each is
located and recorded; the stage's ``stop_at`` (a stage key, as for the other
stages) ends the motion at the ones it names.

:class:`DynamicStage` is the stage as a value; :func:`parse_dynamic_stage`
validates a raw table against a system's names and raises
:class:`~ncstab.paths.programme.ProgrammeError` naming the field.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

from ncstab.paths.programme import CURRENT, ProgrammeError

__all__ = ["DYNAMIC_KEYS", "METHODS", "MOTION_EVENTS", "DynamicStage", "parse_dynamic_stage"]

#: Keys of a stage's ``dynamic`` table.
DYNAMIC_KEYS = ("duration", "perturbation", "samples", "method", "rtol", "kinetic_energy_threshold")

#: Events located during a motion, the names ``stop_at`` takes in a dynamic stage.
MOTION_EVENTS = ("contact_closing", "kinetic_energy")

#: Integrators (scipy.integrate): an explicit Runge-Kutta of order 8 for non-stiff motions,
#: an implicit Runge-Kutta (Radau IIA, order 5) for stiff ones.
METHODS = ("DOP853", "Radau")

#: Stored times of a motion when the stage does not say (the ends included).
DEFAULT_SAMPLES = 2001
#: The most stored times of one motion.
MAX_SAMPLES = 1_000_000

Value = float | str


@dataclass(frozen=True)
class DynamicStage:
    """The last stage of a programme, integrated in time (see the module docstring).

    Attributes
    ----------
    duration
        Time to integrate, in the system's units (Ziegler: sqrt(m l^2 / k);
        grains: sqrt(m / k_n)), > 0.
    perturbation
        ``dof -> displacement`` added to the starting state (dof units).
    hold
        The controls: ``quantity -> value`` for forces, displacements and the
        load parameter (numbers, parameter names or ``"current"``).  A dof not
        named has its force held at its current value.
    samples
        Stored times, equally spaced from 0 to ``duration`` (both included).
    method
        ``"DOP853"`` (default) or ``"Radau"`` (stiff).
    rtol
        Relative tolerance of the integrator (the absolute tolerances scale
        with the perturbation, :func:`ncstab.dynamics.motion.integrate_motion`).
    kinetic_energy_threshold
        The kinetic energy (> 0, in the units of the ``kinetic_energy``
        variable) whose first reaching is the ``kinetic_energy`` event, or
        ``None`` (no such event).
    stop_at
        Events of :data:`MOTION_EVENTS` that end the motion where they are
        located (the others are located and recorded only).
    """

    duration: float
    perturbation: Mapping[str, float] = field(default_factory=dict)
    hold: Mapping[str, Value] = field(default_factory=dict)
    samples: int = DEFAULT_SAMPLES
    method: str = "DOP853"
    rtol: float = 1e-11
    kinetic_energy_threshold: float | None = None
    stop_at: tuple[str, ...] = ()

    def parameter_references(self) -> set[str]:
        """Names of parameters the held values refer to."""
        return {v for v in self.hold.values() if isinstance(v, str) and v != CURRENT}

    def held_displacements(self, dofs: Sequence[str]) -> tuple[str, ...]:
        """The dofs whose displacement the stage holds."""
        return tuple(d for d in dofs if d in self.hold)


def _number(stage: int, field_name: str, value: Any, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise ProgrammeError(stage, field_name, f"expected {what}, got {value!r}")
    return float(value)


def parse_dynamic_stage(
    number: int,
    raw: Mapping[str, Any],
    dofs: Sequence[str],
    forces: Sequence[str],
    load: str | None,
    has_inertia: bool,
    system: str = "the system",
    gaps: Sequence[str] = (),
) -> DynamicStage:
    """Validate a ``[[loading]]`` table with a ``dynamic`` table into a :class:`DynamicStage`.

    Parameters
    ----------
    number
        The stage's 1-based number.
    raw
        ``{"dynamic": {...}, "hold": {...}, "stop_at": [...]}`` with numbers
        already evaluated (``hold`` and ``stop_at`` optional).
    dofs, forces, load
        The system's names.
    has_inertia
        Whether the system has a mass matrix (a dynamic stage needs one).
    system
        The system's name in messages.
    gaps
        The names of the system's secondary-contact gaps (``contact_closing``
        needs one).

    Raises
    ------
    ProgrammeError
        Naming the stage and the field (``dynamic.duration``,
        ``dynamic.perturbation.phi3``, ``hold.F2``, ``stop_at``...).
    """
    extra = sorted(set(raw) - {"dynamic", "hold", "stop_at"})
    if extra:
        raise ProgrammeError(number, extra[0], "a dynamic stage takes only hold, dynamic and stop_at (it drives nothing)")
    table = raw["dynamic"]
    if not isinstance(table, Mapping):
        raise ProgrammeError(number, "dynamic", f"expected a table {{ duration = ..., perturbation = {{ ... }} }}, got {table!r}")
    if not has_inertia:
        raise ProgrammeError(
            number, "dynamic",
            f"{system} declares no inertia (no mass matrix): it has no motion in time; dynamic stages need a "
            "system with masses (diamond, ring, ziegler)",
        )
    unknown = sorted(set(table) - set(DYNAMIC_KEYS))
    if unknown:
        raise ProgrammeError(number, f"dynamic.{unknown[0]}", f"unknown key; a dynamic stage takes {', '.join(DYNAMIC_KEYS)}")
    if "duration" not in table:
        raise ProgrammeError(
            number, "dynamic.duration", "missing: give the time to integrate (a number > 0, in the system's units of time)"
        )
    duration = _number(number, "dynamic.duration", table["duration"], "a time > 0")
    if duration <= 0:
        raise ProgrammeError(number, "dynamic.duration", f"expected a time > 0, got {duration!r}")
    hold = raw.get("hold", {}) or {}
    if not isinstance(hold, Mapping):
        raise ProgrammeError(number, "hold", f"expected a table of quantity = value, got {hold!r}")
    quantities = list(dofs) + list(forces) + ([load] if load else [])
    held: dict[str, Value] = {}
    for name, value in hold.items():
        if name not in quantities:
            raise ProgrammeError(number, f"hold.{name}", f"unknown quantity {name!r}; quantities are: {', '.join(quantities)}")
        if isinstance(value, str):
            if value != CURRENT and not value.isidentifier():
                raise ProgrammeError(number, f"hold.{name}", f"{value!r} is neither a number, 'current', nor a parameter name")
            held[name] = value
        else:
            held[name] = _number(number, f"hold.{name}", value, "a number, a parameter name or 'current'")
    for dof, force in zip(dofs, forces):
        if dof in held and force in held:
            raise ProgrammeError(number, f"hold.{force}", f"dof {dof}/{force} is controlled twice: hold either {dof} or {force}")
    perturbation = table.get("perturbation", {})
    if not isinstance(perturbation, Mapping):
        raise ProgrammeError(
            number, "dynamic.perturbation", f"expected a table of dof = displacement such as {{ {dofs[0]} = 1e-6 }}, got {perturbation!r}"
        )
    displaced: dict[str, float] = {}
    for name, value in perturbation.items():
        if name not in dofs:
            raise ProgrammeError(number, f"dynamic.perturbation.{name}", f"unknown dof {name!r}; dofs are: {', '.join(dofs)}")
        if name in held:
            raise ProgrammeError(
                number, f"dynamic.perturbation.{name}", f"{name} is held by the stage: it cannot be perturbed"
            )
        displaced[name] = _number(number, f"dynamic.perturbation.{name}", value, "a finite number (a displacement)")
    samples = table.get("samples", DEFAULT_SAMPLES)
    if isinstance(samples, bool) or not isinstance(samples, int) or not 2 <= samples <= MAX_SAMPLES:
        raise ProgrammeError(number, "dynamic.samples", f"expected a whole number of stored times from 2 to {MAX_SAMPLES:,}, got {samples!r}")
    method = table.get("method", "DOP853")
    if method not in METHODS:
        raise ProgrammeError(number, "dynamic.method", f"{method!r} is not allowed; allowed: {', '.join(METHODS)}")
    rtol = _number(number, "dynamic.rtol", table.get("rtol", 1e-11), "a relative tolerance from 1e-14 to 1e-3")
    if not 1e-14 <= rtol <= 1e-3:
        raise ProgrammeError(number, "dynamic.rtol", f"expected a relative tolerance from 1e-14 to 1e-3, got {rtol!r}")
    threshold = table.get("kinetic_energy_threshold")
    if threshold is not None:
        threshold = _number(number, "dynamic.kinetic_energy_threshold", threshold, "a kinetic energy > 0")
        if threshold <= 0:
            raise ProgrammeError(number, "dynamic.kinetic_energy_threshold", f"expected a kinetic energy > 0, got {threshold!r}")
    stop_at = _motion_stop_at(number, raw.get("stop_at", []), threshold, tuple(gaps), system)
    return DynamicStage(duration, displaced, held, samples, method, rtol, threshold, stop_at)


def _motion_stop_at(number: int, raw: Any, threshold: float | None, gaps: tuple[str, ...], system: str) -> tuple[str, ...]:
    """The events of :data:`MOTION_EVENTS` a dynamic stage stops at, each possible on the system."""
    names = [raw] if isinstance(raw, str) else raw
    if not isinstance(names, Sequence) or not all(isinstance(name, str) for name in names):
        raise ProgrammeError(number, "stop_at", f"expected a list of event names ({', '.join(MOTION_EVENTS)}), got {raw!r}")
    for name in names:
        if name not in MOTION_EVENTS:
            raise ProgrammeError(
                number, "stop_at", f"unknown event {name!r}; a dynamic stage stops at: {', '.join(MOTION_EVENTS)}"
            )
        if name == "kinetic_energy" and threshold is None:
            raise ProgrammeError(
                number, "stop_at", "kinetic_energy needs the threshold: give dynamic.kinetic_energy_threshold (> 0)"
            )
        if name == "contact_closing" and not gaps:
            raise ProgrammeError(number, "stop_at", f"{system} has no secondary contacts (gaps): no contact_closing")
    return tuple(dict.fromkeys(names))
