"""Cases that follow the same path: which, and what their legend says.

Two cases coincide when they are the same pure-shear law (seed Eq. 60: the
rotational shear spring model, whatever the law) or have the same stored
states to :data:`SAME_PATH_TOL`.  The curve figures
(:mod:`ncstab.plotting.curves`) say so in the later case's legend entry and
dash it over the first, so that both colours show.
"""

from __future__ import annotations

import numpy as np

from ncstab.plotting.cases import Case
from ncstab.plotting.closed_form_overlays import ROTATIONAL_LAWS
from ncstab.plotting.style import law_display_name
from ncstab.plotting.sweep_shape import MAX_CURVES

__all__ = ["SAME_PATH_TOL", "coincidence_note", "coincident_cases", "same_path"]

#: Two cases follow the same path if their stored (Delta*, alpha, F*) agree to this
#: (absolute, dimensionless): the same equations integrated with the same steps agree
#: to round-off (2e-16 measured for seed Figs. 14-15), far below the integrator's rtol.
#: (In pure shear the rotational laws coincide by seed Eq. 60 even where the engine
#: samples their paths at other arclengths.)
SAME_PATH_TOL = 1e-9


def same_path(a: Case, b: Case, rigid: bool) -> bool:
    """Whether two cases follow the same path: the same pure-shear law (seed Eq. 60), or the
    same stored states to :data:`SAME_PATH_TOL`."""
    if a.failed or b.failed or a.n_steps == 0 or b.n_steps == 0:
        return False
    (base_a, *modifiers_a), (base_b, *modifiers_b) = a.law.split("+"), b.law.split("+")
    if (rigid and {base_a, base_b} <= set(ROTATIONAL_LAWS) and sorted(modifiers_a) == sorted(modifiers_b)
            and a.swept == b.swept):
        return True  # the rotational shear spring model, whatever the law (seed Eq. 60)
    if a.n_steps != b.n_steps:
        return False
    first = np.column_stack([a.u, a.alpha, a.F])
    second = np.column_stack([b.u, b.alpha, b.F])
    return bool(np.allclose(first, second, rtol=0, atol=SAME_PATH_TOL, equal_nan=True))


def coincident_cases(cases: list[Case], rigid: bool) -> list[int | None]:
    """For each case, the first earlier case on the same path (None if there is none).

    Pairs are compared for up to :data:`MAX_CURVES` cases (what the curve figures draw);
    for more, no case is said to coincide.
    """
    same_as: list[int | None] = [None] * len(cases)
    if len(cases) > MAX_CURVES:
        return same_as
    for k, case in enumerate(cases):
        for j in range(k):
            if same_as[j] is None and same_path(cases[j], case, rigid):
                same_as[k] = j
                break
    return same_as


def coincidence_note(cases: list[Case], labels: list[str], k: int, first: int, rigid: bool) -> str:
    """``":\nsame path as Cundall–Strack in pure shear (seed Eq. 60)"``: appended to case k's label."""
    other = cases[first]
    if other.law != cases[k].law:
        name = law_display_name(other.law).split(" (")[0]  # without the class: short enough for a legend
        note = f"same path as {name}"
    else:
        note = f"same path as {labels[first]}"
    laws = {other.law.split("+")[0], cases[k].law.split("+")[0]}
    if rigid and laws <= set(ROTATIONAL_LAWS):
        note += " in pure shear (seed Eq. 60)"
    return ":\n" + note
