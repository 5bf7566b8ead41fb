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

__all__ = ["DYNAMIC_KEYS", "METHODS", "DynamicStage", "parse_dynamic_stage"]

#: Keys of a stage's ``dynamic`` table.
DYNAMIC_KEYS = ("duration", "perturbation", "samples", "method", "rtol")

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
    """

    duration: float
    perturbation: Mapping[str, float] = field(default_factory=dict)
    hold: Mapping[str, Value] = field(default_factory=dict)
    samples: int = DEFAULT_SAMPLES
    method: str = "DOP853"
    rtol: float = 1e-11

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
) -> DynamicStage:
    """Validate a ``[[loading]]`` table with a ``dynamic`` table into a :class:`DynamicStage`.

    Parameters
    ----------
    number
        The stage's 1-based number.
    raw
        ``{"dynamic": {...}, "hold": {...}}`` with numbers already evaluated.
    dofs, forces, load
        The system's names.
    has_inertia
        Whether the system has a mass matrix (a dynamic stage needs one).

    Raises
    ------
    ProgrammeError
        Naming the stage and the field (``dynamic.duration``,
        ``dynamic.perturbation.phi3``, ``hold.F2``...).
    """
    extra = sorted(set(raw) - {"dynamic", "hold"})
    if extra:
        raise ProgrammeError(number, extra[0], "a dynamic stage takes only hold and dynamic (it drives nothing)")
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
    return DynamicStage(duration, displaced, held, samples, method, rtol)
