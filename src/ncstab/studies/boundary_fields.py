"""The ``[boundary]`` section of a study file: a stability boundary traced as a curve.

```toml
[boundary]
event = "flutter_onset"   # limit_point, hill_loss, bifurcation, flutter_onset, divergence
parameter = "b1"          # a parameter of the study; the curve runs along it
start = 0.001
stop = 1.0
```

Read into a :class:`BoundarySpec`; every mistake is recorded with its field
(``boundary.event``, ``boundary.parameter``, ``boundary.start``,
``boundary.stop``), including an event the system cannot have and a rate-form
law (:func:`ncstab.boundaries.check_boundary`).
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

from ncstab.studies.study_fields import (
    FieldErrors,
    check_keys,
    did_you_mean,
    read_number,
    read_table,
    toml_type,
)

__all__ = ["BOUNDARY_KEYS", "BoundarySpec", "boundary_section", "check_boundary_model"]

BOUNDARY_KEYS = ("event", "parameter", "start", "stop")


@dataclass(frozen=True)
class BoundarySpec:
    """``[boundary]``: the event, the parameter the curve runs along, and its range."""

    event: str
    parameter: str
    start: float
    stop: float


def boundary_section(data: Mapping[str, Any], errors: FieldErrors, parameters: Mapping[str, Any] | None) -> BoundarySpec | None:
    """The ``[boundary]`` table read and checked against the study's parameters (``None`` if absent or wrong)."""
    table = read_table(data, "boundary", errors)
    if table is None:
        return None
    from ncstab.boundaries.conditions import BOUNDARY_EVENTS  # (the engine: only for a study with [boundary])

    before = len(errors)
    check_keys(table, BOUNDARY_KEYS, "boundary", errors, "[boundary]")
    for key in BOUNDARY_KEYS:
        if key not in table:
            errors.add(f"boundary.{key}", f"missing; [boundary] takes: {', '.join(BOUNDARY_KEYS)}")
    event = table.get("event")
    if "event" in table and (not isinstance(event, str) or event not in BOUNDARY_EVENTS):
        shown = repr(event) if isinstance(event, str) else toml_type(event)
        hint = did_you_mean(event, BOUNDARY_EVENTS) if isinstance(event, str) else ""
        errors.add("boundary.event", f"unknown event {shown}{hint}; allowed: {', '.join(BOUNDARY_EVENTS)}")
    parameter = table.get("parameter")
    if "parameter" in table:
        if not isinstance(parameter, str):
            errors.add("boundary.parameter", f"expected the name of a parameter of the study, got {toml_type(parameter)}")
        elif parameters is not None and parameter not in parameters:
            errors.add(
                "boundary.parameter",
                f"{parameter!r} is not a parameter of the study{did_you_mean(parameter, parameters)}; "
                f"parameters: {', '.join(parameters) or 'none (set it in [parameters] or [system])'}",
            )
    start = read_number(table["start"], "boundary.start", errors) if "start" in table else None
    stop = read_number(table["stop"], "boundary.stop", errors) if "stop" in table else None
    if start is not None and stop is not None and start == stop:
        errors.add("boundary.stop", f"stop = start = {start}: the curve needs a range (start != stop)")
    if len(errors) > before or start is None or stop is None:
        return None
    return BoundarySpec(event, parameter, start, stop)


def check_boundary_model(spec: BoundarySpec, system: Any, laws: list, programme: Any, parameters: Mapping[str, Any], errors: FieldErrors) -> None:
    """What needs the model: an event the system cannot have, a rate-form law, stage values."""
    from ncstab.boundaries.conditions import BoundaryError
    from ncstab.boundaries.trace import check_boundary
    from ncstab.paths.api import resolve_model

    try:
        model = resolve_model(system, laws or None)
        check_boundary(model, programme, parameters, spec.event, spec.parameter, spec.start, spec.stop)
    except BoundaryError as error:
        errors.add(error.field, str(error).split(": ", 1)[1])
    except ValueError as error:  # a model the engine refuses: reported by the other sections
        errors.add("boundary", str(error))


#: The figure kinds of a boundary study.
BOUNDARY_FIGURES = ("boundary",)


def boundary_figures(data: Mapping[str, Any], errors: FieldErrors, spec: BoundarySpec | None, figures: tuple[str, ...]) -> tuple[str, ...]:
    """The figures of a study: ``("boundary",)`` by default with a ``[boundary]``; the kind needs one."""
    output = data.get("output") if isinstance(data.get("output"), dict) else {}
    given = "figures" in output
    if "boundary" not in data:
        if "boundary" in figures:
            errors.add("output.figures", "figure kind 'boundary' needs a [boundary] section")
        return figures
    if not given:
        return BOUNDARY_FIGURES
    other = [kind for kind in figures if kind not in BOUNDARY_FIGURES]
    if other:
        errors.add(
            "output.figures",
            f"a study with [boundary] traces a curve, not paths: it draws {', '.join(BOUNDARY_FIGURES)} only, not {', '.join(other)}",
        )
    return tuple(kind for kind in figures if kind in BOUNDARY_FIGURES)
