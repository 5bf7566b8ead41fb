"""Which closed form of the seed a computed case can be compared with, and its curves.

Decided per case from the Dataset alone: the law, gamma and alpha0 (swept or
fixed), the normal (deformable or rigid), the secondary-contact mode, and the
lateral force F2 during the last loading stage (a closed form is drawn only if
F2 is held constant there).

=========================  ====================  =====================================
case                       F1(alpha)             Delta1*(alpha)
=========================  ====================  =====================================
mcnamara, deformable       Eq. (53) both signs   l* Eq. (46), Delta1* Eq. (46)
turco, deformable, F2 = 0  Eq. (57) both signs   l* Eq. (55), Delta1* Eq. (3)
rigid, rotational laws     Eq. (62), (66)        Eq. (61); blocking Eq. (66)-(67)
rigid, turco               Eq. (65)              Eq. (64); blocking Eq. (68)
hypoelastic, deformable    none (the seed has no closed form)
=========================  ====================  =====================================
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ncstab.plotting.cases import Case
from ncstab.systems.closed_forms import (
    diamond_displacements,
    mcnamara_branch_length,
    mcnamara_load_rotation,
    pure_shear_blocking_alpha,
    pure_shear_displacement,
    pure_shear_load_rotation,
    pure_shear_max_displacement,
    turco_branch_length,
    turco_load_rotation,
)

__all__ = ["Blocking", "ClosedFormBranch", "ClosedFormOverlay", "closed_form_overlay"]

#: Points per closed-form branch (before the domain edges are added).
GRID_POINTS = 400
#: Relative spread of F2 over the last stage below which F2 counts as held
#: (held forces are kept to 1e-12 by the Newton projection, to ~1e-10 by the
#: integrator of rate-form laws).
HELD_FORCE_TOL = 1e-8
#: Laws whose pure-shear limit is the rotational shear spring model (seed Eq. 60).
ROTATIONAL_LAWS = ("mcnamara", "cundall_strack", "weakly_hypoelastic")


@dataclass(frozen=True)
class ClosedFormBranch:
    """One branch of a closed form, sampled on a grid of alpha.

    Attributes
    ----------
    name
        ``"-"`` / ``"+"`` (sign before the square root) or ``"first"``.
    alpha, F1, D1
        Shape (n,): orientation (rad), vertical force and displacement; NaN
        where the branch has no real value.
    """

    name: str
    alpha: np.ndarray
    F1: np.ndarray
    D1: np.ndarray


@dataclass(frozen=True)
class Blocking:
    """The blocking branch of the pure-shear limit (seed Eq. 66-68): alpha = alpha_max."""

    alpha: float
    D1: float


@dataclass(frozen=True)
class ClosedFormOverlay:
    """The closed form a case is compared with.

    Attributes
    ----------
    rotation_equations, displacement_equations
        Seed equations of the load-rotation and load-displacement curves
        (``"seed Eq. 46, 53"``), for the legend.
    branches
        The branches to draw.
    blocking
        The blocking branch, if the path reaches it.
    path_branch
        Shape (n_steps,): the branch each stored state of the path is on, -1
        (``"-"``) or +1 (``"+"``), the one whose F1(alpha) is nearer; 0 for
        states the closed form does not describe (earlier stages, past the
        secondary contact).  None for closed forms with one branch.
    """

    rotation_equations: str
    displacement_equations: str
    branches: tuple[ClosedFormBranch, ...]
    blocking: Blocking | None = None
    path_branch: np.ndarray | None = None

    @property
    def branch_equation(self) -> str:
        """The load-rotation equation whose two roots are the branches (``"Eq. 48"``)."""
        return "Eq. " + self.rotation_equations.removeprefix("seed Eq. ").split(", ")[-1]

    @property
    def equations(self) -> str:
        """Every equation used (3-D figures)."""
        numbers = set()
        for text in (self.rotation_equations, self.displacement_equations):
            numbers.update(int(n) for n in text.removeprefix("seed Eq. ").split(", "))
        return _equations(*numbers)


def _equations(*numbers: int) -> str:
    return "seed Eq. " + ", ".join(str(n) for n in sorted(set(numbers)))


def _alpha_grid(lower: float, upper: float, f: Callable[[np.ndarray], np.ndarray]) -> np.ndarray:
    """A grid on [lower, upper] with the ends of f's real domain added exactly.

    Where f turns from finite to NaN between two grid points (a discriminant
    crossing zero: the two branches meet there), the edge is located by
    bisection to rounding and inserted, so that the drawn branches join.
    """
    grid = np.linspace(lower, upper, GRID_POINTS)
    finite = np.isfinite(f(grid))
    edges = []
    for k in np.flatnonzero(finite[:-1] != finite[1:]):
        inside, outside = (grid[k], grid[k + 1]) if finite[k] else (grid[k + 1], grid[k])
        for _ in range(64):
            middle = (inside + outside) / 2
            if middle in (inside, outside):
                break
            if np.isfinite(f(np.array([middle])))[0]:
                inside = middle
            else:
                outside = middle
        edges.append(inside)
    return np.unique(np.concatenate([grid, edges])) if edges else grid


def _last_stage(case: Case) -> np.ndarray:
    """Boolean mask of the stored states of the last loading stage."""
    stage = case.stage
    if not np.isfinite(stage).any():
        return np.ones(case.n_steps, dtype=bool)
    return stage == np.nanmax(stage)


def _held_lateral_force(case: Case, where: np.ndarray) -> float | None:
    """F2 during the states ``where`` if it is held constant there, else None."""
    F2 = case.F[where, 1]
    if F2.size == 0 or not np.isfinite(F2).all():
        return None
    scale = max(1.0, float(np.max(np.abs(F2))))
    if float(np.ptp(F2)) > HELD_FORCE_TOL * scale:
        return None
    return float(np.median(F2))


def closed_form_overlay(
    case: Case, normal: str = "deformable", secondary_contacts: str = "activate"
) -> ClosedFormOverlay | None:
    """The seed's closed form for a case, or None where the seed has none.

    Parameters
    ----------
    case
        A computed case (see :func:`ncstab.plotting.cases.path_cases`).
    normal
        ``"deformable"`` or ``"rigid"`` (Dataset attribute ``normal``).
    secondary_contacts
        ``"activate"``, ``"ignore"`` or ``"stop"`` (Dataset attribute): with
        ``"activate"`` a deformable path leaves the closed form at the
        secondary contact, and the rigid one is blocked there (Eq. 66-68).

    Returns
    -------
    ClosedFormOverlay or None
        Branches over the alpha range of the last loading stage of the path.
    """
    if case.failed or case.n_steps < 2:
        return None
    base, *modifiers = case.law.split("+")
    alpha0 = case.parameter("alpha0")
    if alpha0 is None:
        return None
    where = _last_stage(case)
    lateral = _held_lateral_force(case, where)
    if lateral is None:
        return None
    contact = case.events.get("secondary_contact")
    if (
        normal != "rigid"
        and secondary_contacts == "activate"
        and contact is not None
        and np.isfinite(contact.s)
    ):
        where = where & (case.s <= contact.s + 1e-12)
    alpha = case.alpha[where]
    alpha = alpha[np.isfinite(alpha)]
    if alpha.size < 2 or float(np.ptp(alpha)) < 1e-9:
        return None
    lower, upper = float(alpha.min()), float(alpha.max())

    if normal == "rigid":
        return _pure_shear_overlay(case, base, alpha0, lateral, lower, upper, secondary_contacts)

    if "no_tension" in modifiers and np.nanmin(case.N[where]) < 0:
        return None  # the closed forms hold while the contact is in compression
    gamma = case.parameter("gamma")
    if gamma is None:
        return None
    if base == "mcnamara":
        number = 48 if abs(lateral) <= HELD_FORCE_TOL else 53

        def load(a: np.ndarray, sign: int) -> np.ndarray:
            return mcnamara_load_rotation(a, gamma, alpha0, lateral, branch=sign)

        def length(a: np.ndarray, F1: np.ndarray) -> np.ndarray:
            return mcnamara_branch_length(a, F1, lateral)

        rotation, displacement = _equations(number), _equations(46, number)
    elif base == "turco":
        if abs(lateral) > HELD_FORCE_TOL:
            return None  # the seed gives Eq. (57) for F2 = 0 only

        def load(a: np.ndarray, sign: int) -> np.ndarray:
            return turco_load_rotation(a, gamma, alpha0, branch=sign)

        def length(a: np.ndarray, F1: np.ndarray) -> np.ndarray:
            return turco_branch_length(a, F1, 0.0, alpha0)

        rotation, displacement = _equations(57), _equations(55, 57)
    else:
        return None  # hypoelastic laws: no closed form in the seed

    grid = _alpha_grid(lower, upper, lambda a: load(a, -1))
    branches = []
    for sign, name in ((-1, "-"), (1, "+")):
        F1 = load(grid, sign)
        D1, _ = diamond_displacements(grid, length(grid, F1), alpha0)
        branches.append(ClosedFormBranch(name=name, alpha=grid, F1=F1, D1=D1))
    # The branch of each state: the root nearer its F1 (they meet where alpha turns).
    distance = [np.abs(case.F[:, 0] - load(case.alpha, sign)) for sign in (-1, 1)]
    on_plus = np.nan_to_num(distance[1], nan=np.inf) < np.nan_to_num(distance[0], nan=np.inf)
    path_branch = np.where(where, np.where(on_plus, 1, -1), 0)
    return ClosedFormOverlay(rotation, displacement, tuple(branches), path_branch=path_branch)


def _pure_shear_overlay(
    case: Case,
    base: str,
    alpha0: float,
    lateral: float,
    lower: float,
    upper: float,
    secondary_contacts: str,
) -> ClosedFormOverlay | None:
    """Seed Eq. (61)-(68): first branch and, if reached, the blocking branch."""
    if base in ROTATIONAL_LAWS:
        model = "rotational"
        rotation, displacement = [62], [61, 62]
        blocking_numbers = ([66], [67])
    elif base == "turco":
        model = "translational"
        rotation, displacement = [65], [64, 65]
        blocking_numbers = ([68], [68])
    else:
        return None
    blocking = None
    if secondary_contacts != "ignore":
        alpha_max = float(pure_shear_blocking_alpha(alpha0, model))
        if np.isfinite(alpha_max) and upper >= alpha_max - 1e-9:
            blocking = Blocking(alpha=alpha_max, D1=float(pure_shear_max_displacement(alpha0)))
            upper = min(upper, alpha_max)
            rotation += blocking_numbers[0]
            displacement += blocking_numbers[1]
    grid = np.linspace(lower, upper, GRID_POINTS)
    branch = ClosedFormBranch(
        name="first",
        alpha=grid,
        F1=pure_shear_load_rotation(grid, alpha0, lateral, model),
        D1=pure_shear_displacement(grid, alpha0, model),
    )
    return ClosedFormOverlay(_equations(*rotation), _equations(*displacement), (branch,), blocking)
