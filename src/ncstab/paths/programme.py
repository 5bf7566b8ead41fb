"""Loading programmes: lists of stages that prescribe, for every dof, u_i or F_i.

A *linear* stage holds some prescribed quantities and drives one or several
to their targets: one driven quantity is the stage's parameter lambda
itself; several move together, proportionally, lambda running from 0 to 1.
A *load-parameter stage* drives the system's load parameter (``P``) with
every dof free -- its force held at the value it has when the stage starts,
zero from rest -- unless the stage holds it.  A *cycle* stage drives two
displacements around a circle through the current state, in the plane of
the dofs it names (the first two for a two-dof system), the others free
(docs/study-files.md).  Values are numbers, names of parameters,
or ``"current"`` (held at the value the quantity has when the stage starts).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Mapping, Sequence

__all__ = [
    "AT_BIFURCATION",
    "BRANCH_DIMENSION",
    "EVENTS",
    "CURRENT",
    "ProgrammeError",
    "Stage",
    "CycleStage",
    "LoadingProgramme",
    "parse_programme",
]

#: Events the engine detects and locates (see ``ncstab.paths.events``).
EVENTS = (
    "limit_point",
    "hill_loss",
    "controllability_loss",
    "flutter_onset",
    "secondary_contact",
    "turning_point",
    "bifurcation",
    "divergence",
)

#: Held value meaning "the value the quantity has when the stage starts".
CURRENT = "current"

#: What a stage does at a simple bifurcation point (``Stage.at_bifurcation``).
AT_BIFURCATION = ("continue", "switch", "branches")
#: The sweep dimension of the branches of a stage with ``at_bifurcation = "branches"``.
BRANCH_DIMENSION = "branch"

#: Names that are load parameters of some system (for error messages on the others).
LOAD_PARAMETER_NAMES = ("P",)

Value = float | str


class ProgrammeError(ValueError):
    """A loading programme that cannot be followed; names the stage and the field.

    Attributes
    ----------
    stage
        1-based stage number (as a user counts ``[[loading]]`` tables), or
        ``None`` for the programme as a whole.
    field
        The offending field (``"hold.F2"``, ``"drive"``, ``"stop_at"``...).
    """

    def __init__(self, stage: int | None, field_name: str, message: str) -> None:
        self.stage = stage
        self.field = field_name
        where = f"loading stage {stage}" if stage is not None else "loading programme"
        super().__init__(f"{where}, field {field_name!r}: {message}")


@dataclass(frozen=True)
class Stage:
    """A linear stage: every dof held or driven through u_i or F_i.

    Attributes
    ----------
    hold
        Prescribed quantities kept constant, e.g. ``{"F2": "current"}``.
    drive
        The driven quantities and their targets, e.g. ``{"D1": 0.6}`` or
        ``{"D_top": 0.4, "D_bottom": 0.4}`` (proportionally) or ``{"P": 3.0}``.
    stop_at
        Events that end the stage (and the case) when located.
    at_bifurcation
        What the path does at a located simple bifurcation point:
        ``"continue"`` (default) goes on along the branch it was on;
        ``"switch"`` leaves along the bifurcating branch (in ``direction``);
        ``"branches"`` follows both: the study gets a ``branch`` sweep
        dimension (0: continued, +1 and -1: the bifurcating branch either way).
    direction
        +1 or -1: which way along the bifurcating branch (``"switch"``).
    """

    hold: Mapping[str, Value] = field(default_factory=dict)
    drive: Mapping[str, Value] = field(default_factory=dict)
    stop_at: tuple[str, ...] = ()
    at_bifurcation: str = "continue"
    direction: int = 1

    @property
    def drives(self) -> tuple[tuple[str, Value], ...]:
        """The driven quantities and their targets, in order."""
        return tuple(self.drive.items())

    @property
    def driven(self) -> tuple[str, Value]:
        """The driven quantity of a stage that drives one."""
        ((name, target),) = self.drive.items()
        return name, target

    def controls(self) -> dict[str, Value]:
        return {**self.hold, **self.drive}


@dataclass(frozen=True)
class CycleStage:
    """Two displacements driven around a circle through the current state.

    Attributes
    ----------
    center
        Centre of the circle in the plane of ``dofs``.
    turns
        Number of full turns (a positive integer).
    direction
        +1 counterclockwise, -1 clockwise (from the first dof toward the second).
    stop_at
        Events that end the stage when located.
    dofs
        The two dofs of the cycle's plane (``("D1", "D2")``); the others are free.
    """

    center: tuple[Value, ...] = (0.0, 0.0)
    turns: int = 1
    direction: int = 1
    stop_at: tuple[str, ...] = ()
    dofs: tuple[str, str] = ("D1", "D2")


@dataclass(frozen=True)
class LoadingProgramme:
    """An ordered list of stages, validated against a system's dofs.

    ``dynamic``: the programme's last stage when it is a dynamic one (a
    :class:`ncstab.dynamics.DynamicStage`, integrated in time from where the
    other stages end), else ``None``.
    """

    stages: tuple[Stage | CycleStage, ...]
    dynamic: Any = None

    def __len__(self) -> int:
        return len(self.stages)

    @property
    def follows_branches(self) -> bool:
        """Whether a stage follows every branch of its bifurcation (a ``branch`` dimension)."""
        return any(getattr(stage, "at_bifurcation", "continue") == "branches" for stage in self.stages)

    def parameter_references(self) -> set[str]:
        """Names of parameters that held or driven values refer to."""
        names: set[str] = set()
        for stage in self.stages:
            values: list[Any] = (
                list(stage.controls().values()) if isinstance(stage, Stage) else list(stage.center)
            )
            names |= {v for v in values if isinstance(v, str) and v != CURRENT}
        if self.dynamic is not None:
            names |= self.dynamic.parameter_references()
        return names


def _check_value(stage: int, field_name: str, value: Any, allow_current: bool) -> Value:
    if isinstance(value, bool):
        raise ProgrammeError(stage, field_name, f"expected a number or a parameter name, got {value!r}")
    if isinstance(value, (int, float)):
        if not math.isfinite(value):
            raise ProgrammeError(stage, field_name, f"value {value!r} is not finite")
        return float(value)
    if isinstance(value, str):
        if value == CURRENT and not allow_current:
            raise ProgrammeError(stage, field_name, "a driven target cannot be 'current'")
        if not value.isidentifier() and value != CURRENT:
            raise ProgrammeError(
                stage, field_name, f"{value!r} is neither a number, 'current', nor a parameter name"
            )
        return value
    raise ProgrammeError(stage, field_name, f"expected a number or a parameter name, got {value!r}")


def _check_stop_at(stage: int, stop_at: Any) -> tuple[str, ...]:
    if stop_at is None:
        return ()
    if isinstance(stop_at, str):
        stop_at = [stop_at]
    if not isinstance(stop_at, Sequence):
        raise ProgrammeError(stage, "stop_at", f"expected a list of event names, got {stop_at!r}")
    for name in stop_at:
        if name not in EVENTS:
            raise ProgrammeError(
                stage, "stop_at", f"unknown event {name!r}; events are: {', '.join(EVENTS)}"
            )
    return tuple(stop_at)


def _parse_linear(
    number: int, raw: Mapping[str, Any], dofs: Sequence[str], forces: Sequence[str], load: str | None,
    hold_others: bool = False,
) -> Stage:
    quantities = list(dofs) + list(forces) + ([load] if load else [])
    hold = raw.get("hold", {}) or {}
    drive = raw.get("drive", {}) or {}
    for label, table in (("hold", hold), ("drive", drive)):
        if not isinstance(table, Mapping):
            raise ProgrammeError(number, label, f"expected a table of quantity = value, got {table!r}")
        for name in table:
            if name not in quantities:
                if load is None and name in LOAD_PARAMETER_NAMES:
                    message = (
                        f"{name!r} is a load parameter, and this system has none; "
                        f"quantities are: {', '.join(quantities)}"
                    )
                else:
                    message = f"unknown quantity {name!r}; quantities are: {', '.join(quantities)}"
                raise ProgrammeError(number, f"{label}.{name}", message)
    if len(drive) == 0:
        raise ProgrammeError(number, "drive", "the stage drives nothing: give at least one quantity and its target")
    controlled = {**{k: "hold" for k in hold}, **{k: "drive" for k in drive}}
    both = set(hold) & set(drive)
    if both:
        name = sorted(both)[0]
        raise ProgrammeError(number, f"drive.{name}", f"{name} is both held and driven")
    load_stage = load is not None and load in drive
    for dof, force in zip(dofs, forces):
        if dof in controlled and force in controlled:
            raise ProgrammeError(
                number, f"{controlled[force]}.{force}",
                f"dof {dof}/{force} is controlled twice: prescribe either {dof} or {force}",
            )
        if dof not in controlled and force not in controlled and not load_stage and not hold_others:
            raise ProgrammeError(
                number, "hold", f"dof {dof}/{force} is not controlled: hold or drive {dof} or {force}"
            )
    hold_values = {k: _check_value(number, f"hold.{k}", v, True) for k, v in hold.items()}
    drive_values = {k: _check_value(number, f"drive.{k}", v, False) for k, v in drive.items()}
    at_bifurcation, direction = _check_at_bifurcation(number, raw.get("at_bifurcation", "continue"))
    return Stage(hold_values, drive_values, _check_stop_at(number, raw.get("stop_at")), at_bifurcation, direction)


def _check_at_bifurcation(stage: int, value: Any) -> tuple[str, int]:
    """``"continue"``, ``"switch"``, ``"branches"`` or ``{switch = true, direction = +-1}``."""
    allowed = "\"continue\", \"switch\", \"branches\" or a table { switch = true, direction = 1 or -1 }"
    if isinstance(value, str):
        if value not in AT_BIFURCATION:
            raise ProgrammeError(stage, "at_bifurcation", f"{value!r} is not allowed; allowed: {allowed}")
        return value, 1
    if isinstance(value, Mapping):
        unknown = set(value) - {"switch", "direction"}
        if unknown:
            raise ProgrammeError(stage, f"at_bifurcation.{sorted(unknown)[0]}", f"unknown key; allowed: {allowed}")
        switch = value.get("switch", True)
        if not isinstance(switch, bool):
            raise ProgrammeError(stage, "at_bifurcation.switch", f"expected true or false, got {switch!r}")
        direction = value.get("direction", 1)
        if isinstance(direction, bool) or direction not in (1, -1):
            raise ProgrammeError(stage, "at_bifurcation.direction", f"expected 1 or -1, got {direction!r}")
        return ("switch" if switch else "continue"), int(direction)
    raise ProgrammeError(stage, "at_bifurcation", f"expected {allowed}, got {value!r}")


def _parse_cycle(number: int, raw: Mapping[str, Any], dofs: Sequence[str]) -> CycleStage:
    cycle = raw["cycle"]
    if not isinstance(cycle, Mapping):
        raise ProgrammeError(number, "cycle", f"expected a table (center, turns, direction, dofs), got {cycle!r}")
    extra = set(raw) - {"cycle", "stop_at"}
    if extra:
        raise ProgrammeError(number, sorted(extra)[0], "a cycle stage takes only 'cycle' and 'stop_at'")
    unknown = set(cycle) - {"center", "turns", "direction", "dofs"}
    if unknown:
        raise ProgrammeError(
            number, f"cycle.{sorted(unknown)[0]}", "unknown key; a cycle takes center, turns, direction, dofs"
        )
    if len(dofs) < 2:
        raise ProgrammeError(number, "cycle", "cycle stages need a system with at least two displacements")
    plane = cycle.get("dofs")
    if plane is None:
        if len(dofs) != 2:
            raise ProgrammeError(
                number, "cycle.dofs",
                f"this system has {len(dofs)} dofs: name the two of the cycle's plane, e.g. "
                f"dofs = [\"{dofs[0]}\", \"{dofs[1]}\"]",
            )
        plane = list(dofs)
    if (
        isinstance(plane, str)
        or not isinstance(plane, Sequence)
        or len(plane) != 2
        or not all(isinstance(d, str) for d in plane)
    ):
        raise ProgrammeError(number, "cycle.dofs", f"expected the names of two dofs, got {plane!r}")
    for name in plane:
        if name not in dofs:
            raise ProgrammeError(number, "cycle.dofs", f"unknown dof {name!r}; dofs are: {', '.join(dofs)}")
    if plane[0] == plane[1]:
        raise ProgrammeError(number, "cycle.dofs", f"give two different dofs, got {plane[0]!r} twice")
    center = cycle.get("center", [0.0, 0.0])
    if not isinstance(center, Sequence) or isinstance(center, str) or len(center) != 2:
        raise ProgrammeError(number, "cycle.center", f"expected two numbers [{plane[0]}, {plane[1]}], got {center!r}")
    center_values = tuple(_check_value(number, "cycle.center", c, False) for c in center)
    turns = cycle.get("turns", 1)
    if isinstance(turns, bool) or not isinstance(turns, int) or turns < 1:
        raise ProgrammeError(number, "cycle.turns", f"expected a positive whole number, got {turns!r}")
    direction = cycle.get("direction", 1)
    if isinstance(direction, bool) or direction not in (1, -1):
        raise ProgrammeError(number, "cycle.direction", f"expected 1 (counterclockwise) or -1, got {direction!r}")
    return CycleStage(
        center_values, turns, int(direction), _check_stop_at(number, raw.get("stop_at")), (plane[0], plane[1])
    )


def parse_programme(
    stages: Sequence[Mapping[str, Any] | Stage | CycleStage],
    dofs: Sequence[str] = ("D1", "D2"),
    forces: Sequence[str] = ("F1", "F2"),
    load: str | None = None,
    hold_others: bool = False,
) -> LoadingProgramme:
    """Validate raw stage tables (as in a study file) into a programme.

    Parameters
    ----------
    stages
        Mappings with ``hold``/``drive``/``stop_at`` or ``cycle``/``stop_at``
        (or already-built stages, re-validated).
    dofs, forces
        The system's displacement and force names.
    load
        The system's load parameter (``"P"``), or ``None``.
    hold_others
        A linear stage may leave dofs uncontrolled: their forces are held at their
        values when it starts (a system of many dofs, such as a packing, whose
        :attr:`~ncstab.systems.assembled.AssembledSystem.hold_other_forces` says so).

    Raises
    ------
    ProgrammeError
        Naming the stage (1-based) and the field.
    """
    if isinstance(stages, (str, bytes)) or not isinstance(stages, Sequence) or len(stages) == 0:
        raise ProgrammeError(None, "loading", "give at least one loading stage")
    parsed: list[Stage | CycleStage] = []
    for number, raw in enumerate(stages, start=1):
        if isinstance(raw, Stage):
            raw = {
                "hold": dict(raw.hold), "drive": dict(raw.drive), "stop_at": list(raw.stop_at),
                "at_bifurcation": (
                    {"switch": True, "direction": raw.direction} if raw.at_bifurcation == "switch" else raw.at_bifurcation
                ),
            }
        elif isinstance(raw, CycleStage):
            raw = {
                "cycle": {
                    "center": list(raw.center), "turns": raw.turns, "direction": raw.direction,
                    "dofs": list(raw.dofs),
                },
                "stop_at": list(raw.stop_at),
            }
        if not isinstance(raw, Mapping):
            raise ProgrammeError(number, "loading", f"expected a table, got {raw!r}")
        if "cycle" in raw:
            parsed.append(_parse_cycle(number, raw, dofs))
            continue
        unknown = set(raw) - {"hold", "drive", "stop_at", "at_bifurcation"}
        if unknown:
            raise ProgrammeError(
                number, sorted(unknown)[0], "unknown key; a stage takes hold, drive, stop_at, at_bifurcation (or cycle)"
            )
        parsed.append(_parse_linear(number, raw, dofs, forces, load, hold_others))
    return LoadingProgramme(tuple(parsed))
