"""How far each loading stage goes, known from the study file alone.

Every case starts from rest, where every displacement and force (and a load
parameter) is 0.  A stage that ends -- finished, not stopped -- leaves its
driven quantity at its target and its held quantities at their held values;
the other quantities of the system are then unknown until a later stage
prescribes them.  A cycle stage, made of whole turns, brings the
displacements back where they were.  :func:`stage_extents` follows this
through a programme: for each stage, the values its quantities are known to
start from (the same in every case that reaches the stage) and how far it
drives them, for every value of the swept parameters it refers to.

Two users: the study-file checks (a stage that drives a quantity to the value
it already has, a cycle of zero radius: nothing to compute) and the size
estimates of a run (:mod:`ncstab.studies.preflight`).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

__all__ = ["StageExtent", "stage_extents"]

#: Held value meaning "the value the quantity has when the stage starts".
_CURRENT = "current"


@dataclass(frozen=True)
class StageExtent:
    """What a study file says about one stage's start and length.

    Attributes
    ----------
    start
        Quantity -> value at the stage's start, for the quantities whose value
        is known there (the same in every case reaching the stage).
    driven
        The driven quantity (``"D1"``...) or the cycle's displacements
        (``"D1,D2"``).
    length
        The driven distance for each value of the swept parameters the target
        refers to (``|target - start|``, or ``2 pi turns radius`` for a
        cycle), shape ``(k,)``; NaN where the start is not known.
    measured_from_rest
        The same, taking an unknown start as 0 (rest): an estimate for sizes.
    """

    start: dict[str, float]
    driven: str
    length: np.ndarray
    measured_from_rest: np.ndarray

    @property
    def does_nothing(self) -> bool:
        """Known to drive nothing in every case: every length is exactly 0."""
        return bool(self.length.size) and bool(np.all(self.length == 0.0))


def _values(value: Any, parameters: Mapping[str, Any]) -> np.ndarray | None:
    """The values a stage value takes over the sweep (``(k,)``), or None (``"current"``, unknown name)."""
    if isinstance(value, str):
        if value == _CURRENT or value not in parameters:
            return None
        value = parameters[value]
    array = np.atleast_1d(np.asarray(value, dtype=float)).ravel()
    return array if array.size else None


def _single(values: np.ndarray | None) -> float | None:
    """A value known for every case: one distinct value."""
    if values is None:
        return None
    first = float(values[0])
    return first if bool(np.all(values == first)) else None


def stage_extents(stages: Sequence[Any], parameters: Mapping[str, Any]) -> list[StageExtent]:
    """The known start and the driven length of each stage, from rest.

    Parameters
    ----------
    stages
        The programme's stages: linear ones with ``hold`` and ``drive``
        mappings (quantity -> number, parameter name or ``"current"``), cycle
        ones with ``center`` (two values), ``turns`` and optionally ``dofs``
        (the two displacements, default ``("D1", "D2")``).
    parameters
        Parameter name -> a number or a list of numbers (a sweep).

    Returns
    -------
    list of StageExtent
        One per stage, in order.
    """
    known: dict[str, float | None] = {}  # quantity -> value; a missing quantity is still at rest (0)
    extents = []

    def start_of(name: str) -> float | None:
        return known[name] if name in known else 0.0

    for stage in stages:
        starts = {}
        center = getattr(stage, "center", None)
        if center is not None:
            dofs = tuple(getattr(stage, "dofs", ("D1", "D2")))
            offsets = []
            for dof, coordinate in zip(dofs, center):
                values = _values(coordinate, parameters)
                origin = start_of(dof)
                if origin is not None:
                    starts[dof] = origin
                offsets.append((values, origin))
            turns = float(getattr(stage, "turns", 1))
            length, estimate = _cycle_lengths(offsets, turns)
            extents.append(StageExtent(starts, ",".join(dofs), length, estimate))
            # Whole turns bring the displacements back where they were; forces drift.
            after = {dof: start_of(dof) for dof in dofs}
            known = {name: None for name in set(known) | _quantities(stages)} | after
            continue
        hold = dict(getattr(stage, "hold", {}) or {})
        drive = dict(getattr(stage, "drive", {}) or {})
        for name in {**hold, **drive}:
            origin = start_of(name)
            if origin is not None:
                starts[name] = origin
        driven, target = next(iter(drive.items())) if drive else ("", None)
        targets = _values(target, parameters)
        origin = start_of(driven) if driven else None
        if targets is None:
            length = estimate = np.full(1, np.nan)
        else:
            estimate = np.abs(targets - (origin if origin is not None else 0.0))
            length = estimate if origin is not None else np.full(targets.shape, np.nan)
        extents.append(StageExtent(starts, driven, length, estimate))
        after: dict[str, float | None] = {}
        for name, value in hold.items():
            after[name] = start_of(name) if value == _CURRENT else _single(_values(value, parameters))
        if driven:
            after[driven] = _single(targets)
        # Every quantity the stage does not prescribe moves with the path: unknown now.
        known = {name: None for name in set(known) | _quantities(stages)} | after
    return extents


def _quantities(stages: Sequence[Any]) -> set[str]:
    """Every quantity some stage prescribes (the others are never known to differ from rest)."""
    names: set[str] = set()
    for stage in stages:
        names |= set(getattr(stage, "hold", {}) or {}) | set(getattr(stage, "drive", {}) or {})
        names |= set(getattr(stage, "dofs", ("D1", "D2")) if getattr(stage, "center", None) is not None else ())
    return names


def _cycle_lengths(
    offsets: list[tuple[np.ndarray | None, float | None]], turns: float
) -> tuple[np.ndarray, np.ndarray]:
    """Arc lengths ``2 pi turns r`` of a cycle over the centre's values, and from rest."""
    exact_known = all(values is not None and origin is not None for values, origin in offsets)
    axes = [values if values is not None else np.zeros(1) for values, _ in offsets]
    origins = [origin if origin is not None else 0.0 for _, origin in offsets]
    grids = np.meshgrid(*[a - o for a, o in zip(axes, origins)], indexing="ij")
    radius = np.sqrt(sum(g**2 for g in grids)).ravel()
    estimate = 2.0 * math.pi * turns * radius
    return (estimate if exact_known else np.full(estimate.shape, np.nan)), estimate
