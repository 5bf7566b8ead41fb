"""Event indicators along a path: their columns, and what a crossing of each means.

Each event is the sign change of a scalar indicator of the state:

=====================  ==========================================================
event                  indicator
=====================  ==========================================================
limit_point            det K (seed Eq. 36)
hill_loss              smallest eigenvalue of K_sym (Hill's condition)
controllability_loss   det M = det K_SS of the stage's control matrix (Eq. 35)
flutter_onset          discriminant of K's characteristic polynomial
secondary_contact      top-bottom and left-right gaps 2 l cos a - 1, 2 l sin a - 1
turning_point          dlambda/ds, the driven quantity's rate along the path
=====================  ==========================================================

plus, located the same way, the end of each turn of a cycle stage
(lambda - 2 pi (k + 1)) and the stage target (lambda - lambda_end).  A sign
change over an accepted step is located by the Illinois variant of regula falsi
(:mod:`ncstab.paths.bracket`) on the step length sigma in (0, h), each
evaluation re-taking the step from its start with length sigma (same
integrator, same Newton projection), so the located state is as accurate as
the path itself.

Values within rounding of zero carry no sign (:data:`SIGN_NOISE` of the size of
what they are built on: K = 2I, gamma = 1 at rest, has a flutter discriminant
of +-1e-31 that must not be an event), and a case keeps, for its next
comparison, the last value that had one: a stored state may land on an
indicator's root (Ziegler's follower pendulum stepped by 0.01 in P meets Hill's
condition's loss at P = 2 exactly), and the step that leaves the zero is then a
change, located at the zero.  A contact indicator exactly at zero takes the
sign of the branch the case is on (:data:`TINY`), so leaving the kink into the
other side is a detected crossing.

The compiled loop computes and locates them (``indicators`` in the model parts,
the signs in :mod:`ncstab.paths.loop_signs`, ``locate`` in
:mod:`ncstab.paths.loop_steps`); this module holds their layout, their
constants and what a crossing of each column means (:func:`event_tables`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.paths.programme import EVENTS, LoadingProgramme

__all__ = [
    "BIFURCATION_COLUMN",
    "CYCLE_COLUMN",
    "DIAMOND_COLUMNS",
    "INDICATOR_EVENTS",
    "INDICATOR_GAP",
    "STIFFNESS_COLUMNS",
    "TARGET_COLUMN",
    "TURNING_COLUMN",
    "IndicatorLayout",
    "event_tables",
]

@dataclass(frozen=True)
class IndicatorLayout:
    """The indicator columns of a system: which event each column's sign change is.

    Columns, in order: the four built on K (limit point, Hill, controllability,
    flutter), one per unilateral gap (``secondary_contact``), the turning
    point, one per normal contact of a no_tension law (``normal_contact``),
    the dynamic divergence test and the branch test (``bifurcation``) where the
    layout has them, the end of a cycle turn and the stage target.

    Attributes
    ----------
    gaps
        Number of gaps of the system.
    normal_contacts
        Number of normal contacts that can open (no_tension laws).
    general
        Whether the ``divergence`` and ``bifurcation`` columns follow the normal
        contacts (every system followed as a general model).
    branch_test
        Whether a ``bifurcation`` column (the branch test of the path tangent)
        follows them where ``general`` is False (the seed's reduced diamond:
        eleven columns).
    """

    gaps: int
    normal_contacts: int
    general: bool = False
    branch_test: bool = False

    @property
    def events(self) -> tuple[str, ...]:
        """Event name of every column."""
        return (
            ("limit_point", "hill_loss", "controllability_loss", "flutter_onset")
            + ("secondary_contact",) * self.gaps
            + ("turning_point",)
            + ("normal_contact",) * self.normal_contacts
            + self._branch_events
            + ("cycle_end", "stage_target")
        )

    @property
    def switch_bits(self) -> tuple[int, ...]:
        """Contact-state bit each column toggles when it crosses zero (0: none):
        gap g is bit 2**g, normal contact j bit 2**(gaps + j)."""
        gaps = tuple(1 << g for g in range(self.gaps))
        normals = tuple(1 << (self.gaps + j) for j in range(self.normal_contacts))
        return (0, 0, 0, 0) + gaps + (0,) + normals + (0,) * len(self._branch_events) + (0, 0)

    @property
    def _branch_events(self) -> tuple[str, ...]:
        """The columns between the normal contacts and the cycle end."""
        if self.general:
            return ("divergence", "bifurcation")
        return ("bifurcation",) if self.branch_test else ()

    @property
    def size(self) -> int:
        return len(self.events)

    @property
    def target(self) -> int:
        """Column of the stage target (lambda - lambda_end, signed toward the target)."""
        return self.size - 1

    @property
    def cycle(self) -> int:
        """Column of the end of a cycle turn (lambda - 2 pi (k + 1))."""
        return self.size - 2

    @property
    def turning(self) -> int:
        """Column of dlambda/ds (the only one needing the path tangent)."""
        return STIFFNESS_COLUMNS + self.gaps

    @property
    def bifurcation(self) -> int | None:
        """Column of the branch test (``None`` where the layout has none)."""
        return self.size - 3 if self.general or self.branch_test else None

    @property
    def divergence(self) -> int | None:
        """Column of the dynamic divergence test (``None`` for the reduced diamond's layout)."""
        return self.size - 4 if self.general else None

    @property
    def gap_columns(self) -> slice:
        return slice(STIFFNESS_COLUMNS, STIFFNESS_COLUMNS + self.gaps)

    @property
    def normal_columns(self) -> slice:
        return slice(self.turning + 1, self.turning + 1 + self.normal_contacts)


#: The first columns, built on K (limit point, Hill, controllability, flutter).
STIFFNESS_COLUMNS = 4
#: The diamond's columns: two gaps (top-bottom, left-right), one normal contact.
DIAMOND_COLUMNS = IndicatorLayout(gaps=2, normal_contacts=1, branch_test=True)
#: Event name of every indicator column of the diamond.
INDICATOR_EVENTS = DIAMOND_COLUMNS.events
#: Which contact-state bit a diamond column switches when it crosses zero: 1
#: top-bottom and 2 left-right secondary contacts, 4 the normal contact of a
#: no_tension law (its overlap delta), 0 none.
INDICATOR_GAP = DIAMOND_COLUMNS.switch_bits
#: Relative size below which an indicator built on K is taken as zero (no sign):
#: a few hundred roundings of the entries of K.
SIGN_NOISE = 1e-13
#: Stand-in for an indicator exactly at zero, signed by the current branch.
TINY = 1e-300
#: Column of the end-of-cycle indicator of the diamond.
CYCLE_COLUMN = DIAMOND_COLUMNS.cycle
#: Column of the diamond's turning-point indicator.
TURNING_COLUMN = DIAMOND_COLUMNS.turning
#: Column of the diamond's stage-target indicator.
TARGET_COLUMN = DIAMOND_COLUMNS.target
#: Column of the diamond's branch test (a simple bifurcation point where it changes sign).
BIFURCATION_COLUMN = DIAMOND_COLUMNS.bifurcation
assert set(IndicatorLayout(1, 1, True).events) - {"normal_contact", "cycle_end", "stage_target"} == set(EVENTS)


def event_tables(
    programme: LoadingProgramme, secondary_contacts: str, columns: IndicatorLayout
) -> tuple[dict[str, list[int]], np.ndarray, np.ndarray]:
    """What a sign change of each indicator column means for the path.

    Returns
    -------
    event_column
        Per event name, its indicator columns.
    stop_table
        ``(stages, columns)`` bool: a crossing of the column stops the case in
        that stage (the stage's ``stop_at``; every secondary contact with
        ``secondary_contacts = "stop"``).
    break_columns
        ``(columns,)`` bool: a crossing switches the contact state, so the step
        is cut there (secondary contacts with ``"activate"``; the normal
        contact of a no_tension law, whose opening and closing switch smooth
        branch, seed Eq. 59).
    """
    names = columns.events
    event_column = {name: [i for i, e in enumerate(names) if e == name] for name in EVENTS}
    stop_table = np.zeros((len(programme), len(names)), dtype=bool)
    for k, stage in enumerate(programme.stages):
        for name in stage.stop_at:
            stop_table[k, event_column[name]] = True
        if secondary_contacts == "stop":
            stop_table[k, event_column["secondary_contact"]] = True
    break_columns = np.zeros(len(names), dtype=bool)
    if secondary_contacts == "activate":
        break_columns[event_column["secondary_contact"]] = True
    break_columns[[i for i, e in enumerate(names) if e == "normal_contact"]] = True
    return event_column, stop_table, break_columns
