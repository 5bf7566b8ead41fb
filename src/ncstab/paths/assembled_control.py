"""A stage's control of an assembled system: which dofs are driven through u or F, as affine maps of lambda.

For the sparse engine (:mod:`ncstab.paths.assembled_engine`).  A linear stage
prescribes every dof's displacement or its force (docs/study-files.md); one driven quantity is lambda itself, several move together with
lambda from 0 to 1; a load-parameter stage drives P = lambda with every dof
not held free (its force held at its value when the stage starts).  The
unknowns are y = (u_S, lambda), S the force-controlled dofs; the displacement-
controlled ones follow u_D = base_D + slope_D lambda, and the equations are

    G(y) = R_S(u, P) - (baseF_S + slopeF_S lambda) = 0.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.paths.programme import CURRENT, ProgrammeError, Stage
from ncstab.paths.status import held_away, held_away_message

__all__ = ["CYCLE_REFUSED", "StageControl", "StageStartError", "refuse_cycles", "stage_control"]


@dataclass(frozen=True)
class StageControl:
    """The affine control of one stage (see the module docstring)."""

    force_dofs: np.ndarray
    displacement_dofs: np.ndarray
    u_base: np.ndarray
    u_slope: np.ndarray
    f_base: np.ndarray
    f_slope: np.ndarray
    lam_start: float
    lam_end: float
    load_stage: bool
    load_held: float
    #: A load stage's load is load_base + load_slope lambda: lambda itself where the load is the
    #: only driven quantity, else it moves from its current value to its target as lambda runs
    #: from 0 to 1 with the others (as on the compiled route).
    load_base: float = 0.0
    load_slope: float = 1.0
    #: Whether every driven quantity is at its target when the stage starts: the stage is
    #: skipped, as on the compiled route (its ``target_sign`` 0).
    zero_length: bool = False

    @property
    def scale(self) -> float:
        """|lambda_end - lambda_start| (1 if zero): lambda's unit in the arclength."""
        extent = abs(self.lam_end - self.lam_start)
        return extent if extent > 0 else 1.0

    def displacements(self, y: np.ndarray, n: int) -> np.ndarray:
        u = np.empty(n)
        m = len(self.force_dofs)
        u[self.force_dofs] = y[:m]
        u[self.displacement_dofs] = self.u_base + self.u_slope * y[m]
        return u

    def load(self, lam: float) -> float:
        return self.load_base + self.load_slope * lam if self.load_stage else self.load_held


#: Why a cycle stage is refused on an assembled system (checked before any work:
#: :func:`refuse_cycles`, and by the study loader).
CYCLE_REFUSED = ("cycle stages are followed on systems derived whole (at most 8 dofs): this system is "
                 "assembled from elements (the sparse engine follows linear stages)")


def refuse_cycles(programme) -> None:
    """Raise :class:`ProgrammeError` naming the first cycle stage of ``programme``, if any."""
    for number, stage in enumerate(programme.stages, start=1):
        if not isinstance(stage, Stage):
            raise ProgrammeError(number, "cycle", CYCLE_REFUSED)


class StageStartError(ArithmeticError):
    """A case that cannot start a stage: a held quantity is not at its held value there
    (the case fails with ``bad_stage_start``, as on the compiled route)."""


def stage_control(stage: Stage, number: int, dofs: tuple[str, ...], forces: tuple[str, ...],
                  load_name: str | None, u: np.ndarray, F: np.ndarray, load: float,
                  values: dict[str, float]) -> StageControl:
    """The control of ``stage`` entered at the state (u, F, load); ``values``: the case's parameters."""
    if not isinstance(stage, Stage):
        raise ProgrammeError(number, "cycle", CYCLE_REFUSED)
    current = {**dict(zip(dofs, u)), **dict(zip(forces, F))}
    if load_name is not None:
        current[load_name] = load

    def value(name: str, given) -> float:
        if given == CURRENT:
            return float(current[name])
        if isinstance(given, str):
            return float(values[given])
        return float(given)

    drives = [(name, value(name, target)) for name, target in stage.drive.items()]
    single = len(drives) == 1
    lam_start, lam_end = (current[drives[0][0]], drives[0][1]) if single else (0.0, 1.0)
    slopes = {name: (1.0 if single else target - current[name]) for name, target in drives}
    bases = {name: (0.0 if single else current[name]) for name, _ in drives}
    for name, given in stage.hold.items():
        slopes[name], bases[name] = 0.0, value(name, given)
        if held_away(bases[name], float(current[name])):
            raise StageStartError(held_away_message(number, name, given))
    load_stage = load_name is not None and load_name in stage.drive
    force_dofs, displacement_dofs = [], []
    for i, (dof, force) in enumerate(zip(dofs, forces)):
        if dof in slopes:
            displacement_dofs.append(i)
        else:
            force_dofs.append(i)
            if force not in slopes:  # free in a load-parameter stage: held at its current force
                slopes[force], bases[force] = 0.0, float(F[i])
    return StageControl(
        force_dofs=np.array(force_dofs, dtype=np.intp),
        displacement_dofs=np.array(displacement_dofs, dtype=np.intp),
        u_base=np.array([bases[dofs[i]] for i in displacement_dofs]),
        u_slope=np.array([slopes[dofs[i]] for i in displacement_dofs]),
        f_base=np.array([bases[forces[i]] for i in force_dofs]),
        f_slope=np.array([slopes[forces[i]] for i in force_dofs]),
        lam_start=float(lam_start),
        lam_end=float(lam_end),
        load_stage=load_stage,
        load_held=float(load),
        load_base=float(bases[load_name]) if load_stage else 0.0,
        load_slope=float(slopes[load_name]) if load_stage else 1.0,
        zero_length=all(target == current[name] for name, target in drives),
    )
