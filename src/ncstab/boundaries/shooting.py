"""Boundaries of rate-form (hypoelastic) laws by shooting: each point a path solved to the event.

A rate-form law's state at the event depends on the loading history, so the
event's condition cannot be appended to equilibrium equations in total form.
Instead each point of the curve is the event located on a whole path
(:func:`ncstab.follow`, root finding along the path, the engine's event
tolerance) at one value of the parameter, the paths of a round in one batch.
The points are placed adaptively: ``min_points`` evenly over the range, then
rounds of bisection where the curve bends (the midpoint's predicted load, the
mean of its neighbours', misses the located one by more than ``tolerance``
relative) and where the event appears or vanishes (an edge of the curve,
located to the bisection's resolution and noted ``edge``).  A fold cannot be
followed: the curve is the first event on each path.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any

import numpy as np

from ncstab.paths.api import follow
from ncstab.paths.programme import LoadingProgramme

__all__ = ["ShootingOptions", "shoot_curve"]


@dataclasses.dataclass(frozen=True)
class ShootingOptions:
    """Adaptive placement of the points of a shot curve (see the module docstring)."""

    min_points: int = 41
    rounds: int = 8
    tolerance: float = 1e-4


def _located(model, law, programme: LoadingProgramme, values: Mapping[str, float], event: str, parameter: str,
             p: np.ndarray, quantity) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """u, F, load and the plotted quantity of the first event in the last stage at each value of ``p``."""
    stages = list(programme.stages)
    last = stages[-1]
    if event not in last.stop_at:
        stages[-1] = dataclasses.replace(last, stop_at=tuple(last.stop_at) + (event,))
    parameters = {**{k: v for k, v in values.items() if k != parameter}, parameter: [float(x) for x in p]}
    dataset = follow(model, [law], LoadingProgramme(tuple(stages), None), parameters).to_dataset()
    if "law" in dataset.dims:  # a model of several laws follows them all: this case's law
        dataset = dataset.sel(law=law.name)
    n = len(model.definition.dofs)
    u = dataset[f"{event}_u"].values.reshape(p.size, n)
    F = dataset[f"{event}_F"].values.reshape(p.size, n)
    load = dataset[f"{event}_load"].values.reshape(p.size) if f"{event}_load" in dataset else np.full(p.size, np.nan)
    stage = dataset[f"{event}_stage"].values.reshape(p.size)
    in_last = stage == len(programme.stages) - 1
    u[~in_last], F[~in_last], load[~in_last] = np.nan, np.nan, np.nan
    return u, F, load, quantity(u, F, load)


def shoot_curve(model, law, programme: LoadingProgramme, values: Mapping[str, float], event: str, parameter: str,
                start: float, stop: float, options: ShootingOptions | None = None) -> dict[str, Any]:
    """The boundary of ``event`` along ``parameter`` by shooting (one path per point).

    Returns
    -------
    dict
        ``p`` ``(m,)``, ``u``, ``F`` ``(m, n)``, ``load`` ``(m,)`` at the points where
        the event is met, in the order of ``p`` from start to stop, and ``notes``.
    """
    options = options or ShootingOptions()
    has_load = model.definition.load_parameter is not None

    def quantity(u, F, load):
        return load if has_load else F[:, int(np.nanargmax(np.nanmax(np.abs(F), axis=0)))] if np.isfinite(F).any() else F[:, 0]

    p = np.linspace(start, stop, options.min_points)
    u, F, load, q = _located(model, law, programme, values, event, parameter, p, quantity)
    for _ in range(options.rounds):
        found = np.isfinite(q)
        middle = 0.5 * (p[:-1] + p[1:])
        edge = found[:-1] != found[1:]
        bend = np.zeros_like(edge)
        if p.size >= 3:
            both = found[:-2] & found[1:-1] & found[2:]
            scale = np.maximum(np.abs(q[1:-1]), 1e-12)
            misses = np.abs(q[1:-1] - 0.5 * (q[:-2] + q[2:])) > options.tolerance * scale
            flagged = np.where(both, misses, False)
            bend[:-1] |= flagged
            bend[1:] |= flagged
        refine = edge | bend
        if not refine.any():
            break
        new = middle[refine]
        u_new, F_new, load_new, q_new = _located(model, law, programme, values, event, parameter, new, quantity)
        order = np.argsort(np.concatenate([p, new]) * np.sign(stop - start), kind="stable")
        p = np.concatenate([p, new])[order]
        u, F = np.concatenate([u, u_new])[order], np.concatenate([F, F_new])[order]
        load, q = np.concatenate([load, load_new])[order], np.concatenate([q, q_new])[order]
    found = np.isfinite(q)
    notes = np.full(p.size, "", dtype=object)
    change = np.flatnonzero(found[:-1] != found[1:])
    for k in change:  # the found neighbour of an edge
        notes[k if found[k] else k + 1] = "edge"
    kept = np.flatnonzero(found)
    if kept.size:
        notes[kept[0]] = "start" if kept[0] == 0 else notes[kept[0]]
        notes[kept[-1]] = "end" if kept[-1] == p.size - 1 else notes[kept[-1]]
    return {"p": p[kept], "u": u[kept], "F": F[kept], "load": load[kept], "notes": tuple(notes[kept])}
