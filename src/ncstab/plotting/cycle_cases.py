"""The cases of a path Dataset with closed kinematic cycles (Green's paradox), read from it alone.

A cycle stage drives (Delta_1*, Delta_2*) around a circle; the Dataset records
the work per contact over each turn (``cycle_work``, seed Eq. 5), and every
stored state (``u``, ``F``, ``T``, ``alpha``, ``l``, the turned angle ``lam``
and the ``stage`` it belongs to).  :func:`cycle_cases` restricts each case to
its cycle stages (:class:`CycleCase`) and describes the stages (:class:`CycleLayout`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

from ncstab.plotting.style import format_parameter

__all__ = ["CycleCase", "CycleLayout", "cycle_cases", "signed_area"]


@dataclass(frozen=True)
class CycleLayout:
    """The cycle stages of a Dataset's loading programme.

    Attributes
    ----------
    cycle_stage
        ``(C,)``: 0-based stage index of each cycle (turn), programme order.
    stages
        The cycle stages, in order.
    offset
        Stage index -> number of turns of the earlier cycle stages.
    turns
        Stage index -> number of turns of the stage.
    direction
        Stage index -> +1 (counterclockwise in the (Delta_1*, Delta_2*) plane)
        or -1, read from the signed area swept by the stored states.
    """

    cycle_stage: np.ndarray
    stages: tuple[int, ...]
    offset: dict[int, int]
    turns: dict[int, int]
    direction: dict[int, int]

    @property
    def n_cycles(self) -> int:
        return int(self.cycle_stage.size)

    def describe(self, stage: int) -> str:
        """``"stage 1: 3 turns counterclockwise"``."""
        sense = {1: "counterclockwise", -1: "clockwise"}.get(self.direction.get(stage, 0), "")
        turns = self.turns[stage]
        return f"stage {stage + 1}: {turns} turn{'s' if turns != 1 else ''} {sense}".rstrip()


@dataclass(frozen=True)
class CycleCase:
    """One case (a law and values of the swept parameters) restricted to its cycle stages.

    Attributes
    ----------
    law, law_class
        Law name and computed class (``hyperelastic``...).
    swept
        Swept parameter name -> value (law excluded).
    law_index, parameter_index
        Position along the ``law`` dimension; flat position over the other
        sweep dimensions (C order).
    status
        ``finished``, ``stopped:<event>`` or ``failed:<reason>``.
    work
        ``(C,)``: work per contact over each turn, ``cycle_work``.
    u, F
        ``(n, 2)``: Delta*, F* at the stored states of the cycle stages.
    T, alpha, l, lam, stage
        ``(n,)``: tangential force, orientation, length, turned angle (rad,
        from the start of its stage), stage index.
    turns
        ``(n,)``: cumulative number of turns over the cycle stages,
        ``offset[stage] + lam / 2 pi``.
    alpha0
        Initial orientation (alpha at the unloaded first state of the path).
    """

    law: str
    law_class: str
    swept: dict[str, float]
    law_index: int
    parameter_index: int
    status: str
    work: np.ndarray
    u: np.ndarray
    F: np.ndarray
    T: np.ndarray
    alpha: np.ndarray
    l: np.ndarray
    lam: np.ndarray
    stage: np.ndarray
    turns: np.ndarray
    alpha0: float

    @property
    def key(self) -> str:
        """A unique name of the case (artist ``gid`` suffix): ``"mcnamara|radius=0.05"``."""
        return "|".join([self.law] + [f"{k}={v:.12g}" for k, v in self.swept.items()])

    @property
    def parameter_label(self) -> str:
        """``"radius = 0.05"`` (empty without swept parameters)."""
        return ", ".join(format_parameter(k, v) for k, v in self.swept.items())

    def stage_slices(self) -> list[tuple[int, np.ndarray]]:
        """(stage, indices of its states) for every cycle stage the case reached."""
        return [(int(k), np.flatnonzero(self.stage == k)) for k in np.unique(self.stage)]


def signed_area(points: np.ndarray) -> float:
    """Shoelace area of a closed polygon (positive counterclockwise)."""
    x, y = points[:, 0], points[:, 1]
    return 0.5 * float(np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y))


def cycle_cases(dataset: xr.Dataset) -> tuple[list[CycleCase], CycleLayout]:
    """Every case of a path Dataset with cycle stages, in C order over the sweep.

    Parameters
    ----------
    dataset
        A Dataset of :meth:`ncstab.paths.PathResult.to_dataset` (or read back from
        its archive) whose programme has at least one cycle stage.

    Returns
    -------
    (cases, layout)

    Raises
    ------
    ValueError
        If the Dataset has no ``cycle`` dimension (no cycle stage) or lacks a
        variable the figures need.
    """
    if "cycle" not in dataset.dims or "cycle_work" not in dataset:
        raise ValueError(
            "the Dataset has no cycle stages (no 'cycle' dimension): cycle figures need a "
            "loading programme with a stage such as cycle = { center = [0.05, 0.0], turns = 3 }"
        )
    needed = ("n_steps", "u", "F", "T", "alpha", "l", "lam", "stage", "cycle_stage")
    missing = [name for name in needed if name not in dataset.variables]
    if missing:
        raise ValueError(
            f"not a path Dataset with cycles: missing variable(s) {', '.join(missing)}"
        )
    dims = list(dataset["n_steps"].dims)

    def values(name: str, tail: tuple[str, ...] = ()) -> np.ndarray:
        array = dataset[name]
        if "dof" in tail:
            array = array.isel(dof=[0, 1])
        return np.asarray(array.transpose(*dims, *tail).values)

    n_steps = values("n_steps")
    u, F = values("u", ("step", "dof")), values("F", ("step", "dof"))
    T, alpha, l, lam = (
        values(name, ("step",)).astype(float) for name in ("T", "alpha", "l", "lam")
    )
    stage = values("stage", ("step",)).astype(int)
    work = values("cycle_work", ("cycle",)).astype(float)
    status = (
        values("status").astype(str) if "status" in dataset else np.full(n_steps.shape, "finished")
    )
    cycle_stage = np.asarray(dataset["cycle_stage"].values).astype(int)
    stages = tuple(int(k) for k in np.unique(cycle_stage))
    offset = {k: int(np.sum(cycle_stage < k)) for k in stages}
    turns_per_stage = {k: int(np.sum(cycle_stage == k)) for k in stages}
    laws = [str(v) for v in dataset["law"].values] if "law" in dims else ["law"]
    classes = (
        [str(v) for v in dataset["law_class"].values]
        if "law_class" in dataset.coords
        else [""] * len(laws)
    )
    coords = {d: np.asarray(dataset[d].values) for d in dims if d != "law" and d in dataset.coords}
    other_shape = tuple(n_steps.shape[i] for i, d in enumerate(dims) if d != "law")

    cases: list[CycleCase] = []
    direction: dict[int, int] = {}
    for index in np.ndindex(n_steps.shape):
        n = max(int(n_steps[index]), 0)
        law_index = index[dims.index("law")] if "law" in dims else 0
        other = tuple(k for d, k in zip(dims, index) if d != "law")
        swept = {
            d: float(coords[d][k]) if d in coords else float(k)
            for d, k in zip([d for d in dims if d != "law"], other)
        }
        in_cycle = np.isin(stage[index][:n], stages)
        steps = np.flatnonzero(in_cycle)
        case_stage = stage[index][steps]
        case_lam = lam[index][steps]
        turns = np.array([offset[k] for k in case_stage], dtype=float) + case_lam / (2 * math.pi)
        alpha0 = float(alpha[index][0]) if n else math.nan
        case = CycleCase(
            law=laws[law_index],
            law_class=classes[law_index],
            swept=swept,
            law_index=int(law_index),
            parameter_index=int(np.ravel_multi_index(other, other_shape)) if other_shape else 0,
            status=str(status[index]),
            work=work[index],
            u=np.asarray(u[index][steps], dtype=float),
            F=np.asarray(F[index][steps], dtype=float),
            T=T[index][steps],
            alpha=alpha[index][steps],
            l=l[index][steps],
            lam=case_lam,
            stage=case_stage,
            turns=turns,
            alpha0=alpha0,
        )
        cases.append(case)
        for k, where in case.stage_slices():
            if k not in direction and where.size >= 3:
                area = signed_area(case.u[where])
                if area != 0:
                    direction[k] = 1 if area > 0 else -1
    layout = CycleLayout(cycle_stage, stages, offset, turns_per_stage, direction)
    return cases, layout
