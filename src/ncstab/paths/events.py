"""Event indicators along a path and their batched localisation.

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
on the step length sigma in (0, h), each evaluation re-taking the step from its
start with length sigma (same integrator, same Newton projection), so the
located state is as accurate as the path itself.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable

import numpy as np

from ncstab.operators.indicators import det_K, flutter_discriminant, hill_eigenvalue
from ncstab.paths.programme import EVENTS
from ncstab.paths.tangent_field import StageArrays, control_matrix

if TYPE_CHECKING:
    from ncstab.paths.model import Evaluation

__all__ = [
    "BIFURCATION_COLUMN",
    "CYCLE_COLUMN",
    "DIAMOND_COLUMNS",
    "INDICATOR_EVENTS",
    "INDICATOR_GAP",
    "IndicatorLayout",
    "STIFFNESS_COLUMNS",
    "TARGET_COLUMN",
    "TURNING_COLUMN",
    "indicator_values",
    "locate_sign_changes",
    "signs_kept",
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


def _signed_zero(values: np.ndarray, state: np.ndarray, bits: tuple[int, ...]) -> np.ndarray:
    """A contact indicator exactly at zero takes the sign of the branch the case is on
    (bit set: -TINY), so leaving the kink into the other side is a detected crossing."""
    if values.shape[-1] == 0:
        return values
    closed = np.stack([state & bit for bit in bits], -1) > 0
    return np.where(values == 0, np.where(closed, -TINY, TINY), values)


def indicator_values(
    evaluation: Evaluation,
    stage: StageArrays,
    lam: np.ndarray,
    dlam: np.ndarray,
    stiffness_columns: bool = True,
    layout: IndicatorLayout = DIAMOND_COLUMNS,
    branch: np.ndarray | None = None,
) -> np.ndarray:
    """All indicators at a batch of states, ``(B, layout.size)``.

    Parameters
    ----------
    evaluation
        Forces, K, Jacobians and gaps at the states.
    stage
        The cases' stage arrays.
    lam, dlam
        Driven parameter and its oriented rate along the path, ``(B,)``.
    stiffness_columns
        ``False``: leave the four indicators built on K (limit point, Hill,
        controllability, flutter) NaN, for a caller that needs none of them
        (event location of a gap or a target); the other columns are the same.
    layout
        The system's columns.
    branch
        The branch test of the path tangent (``PathTangent.branch``), for a
        general layout's ``bifurcation`` column (NaN where not given).
    """
    stiffness = evaluation.stiffness
    state = stage.secondary_state
    bits = layout.switch_bits
    # (a no_tension contact touching at rest is closed: overlap "+0").
    overlap = evaluation.normal_overlap.reshape(lam.shape[0], layout.normal_contacts)
    overlap = _signed_zero(overlap, state, bits[layout.normal_columns])
    gaps = _signed_zero(evaluation.gaps, state, bits[layout.gap_columns])
    target = (lam - stage.lam_end) * stage.target_sign
    with np.errstate(invalid="ignore"):
        cycle_end = np.where(stage.is_cycle, lam - 2 * np.pi * (stage.cycles_done + 1), np.nan)
    def significant(value: np.ndarray, size: np.ndarray) -> np.ndarray:
        # Values within rounding of zero carry no sign: K = 2I (gamma = 1 at
        # rest) has a flutter discriminant of +-1e-31 that must not be an event.
        return np.where(np.abs(value) <= SIGN_NOISE * size, 0.0, value)

    nothing = np.full(lam.shape, np.nan)
    dynamic = nothing
    if stiffness_columns:
        control = control_matrix(evaluation.du_dv, evaluation.dF_dv, stage.force_controlled)
        with np.errstate(invalid="ignore"):
            scale = np.nanmax(np.abs(np.concatenate([stiffness, control], axis=-1)), axis=(-2, -1))
        scale = np.where(np.isfinite(scale) & (scale > 0), scale, 1.0)
        control_determinant = significant(det_K(control), scale**2)
        if layout.general and evaluation.mass is not None:
            # M s^2 + C s + K: the onset of flutter (a pair through the imaginary
            # axis) and divergence (a real root through 0 under the stage's control).
            flutter = _flutter_onset(evaluation.mass, evaluation.damping, stiffness)
            dynamic = control_determinant
        else:
            flutter = significant(flutter_discriminant(stiffness), scale**2)
        stiffness_values = [
            significant(det_K(stiffness), scale**2),
            significant(hill_eigenvalue(stiffness), scale),
            control_determinant,
            flutter,
        ]
    else:
        stiffness_values = [nothing] * 4
    general = []
    if layout.general:
        general = [dynamic, nothing if branch is None else branch]
    elif layout.branch_test:
        general = [nothing if branch is None else branch]
    return np.column_stack(
        [
            *stiffness_values,
            gaps,
            dlam,
            overlap,
            *general,
            cycle_end,
            target,
        ]
    )


def _flutter_onset(mass: np.ndarray, damping: np.ndarray | None, stiffness: np.ndarray) -> np.ndarray:
    """The flutter-onset test of M s^2 + C s + K (:func:`ncstab.operators.flutter_onset_indicator`),
    with values within rounding of zero taken as zero (no sign)."""
    from ncstab.operators.dynamics import flutter_onset_indicator

    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        values = flutter_onset_indicator(mass, damping, stiffness)
    return values


def signs_kept(before: np.ndarray, after: np.ndarray, target: int) -> np.ndarray:
    """The indicators a case keeps for its next sign comparison: ``after``, except
    that a value without a sign (exactly 0: within rounding of zero, see
    :func:`indicator_values`) keeps the value before it, the last that had one.

    A stored state may land on an indicator's root (Ziegler's follower pendulum
    stepped by 0.01 in P meets Hill's condition's loss at P = 2 exactly): the
    signs along the path are then +, 0, -, and neither comparison of
    neighbours is a change.  With the last sign kept, the step that leaves the
    zero is one (+ before, - after), and its crossing is located at the zero,
    the step's start.  An indicator that returns to its sign after zeros
    (a double root touched) changes nothing.  The stage target's column
    (``target``) is compared as it is (reached at 0).

    Parameters
    ----------
    before, after
        ``(B, columns)``: the values kept at the step's start, and the values at its end.
    target
        Column of the stage target.
    """
    unsigned = after == 0
    unsigned[:, target] = False
    return np.where(unsigned, before, after)


def locate_sign_changes(
    evaluate: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]],
    h: np.ndarray,
    phi0: np.ndarray,
    phi1: np.ndarray,
    tol: float,
    max_iter: int = 200,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Locate roots of phi(sigma) on (0, h) for a batch, by Illinois regula falsi.

    Parameters
    ----------
    evaluate
        ``(index, sigma) -> (phi, payload)``: re-takes the step of cases
        ``index`` with lengths ``sigma`` and returns the indicator and the
        state there (``payload``, shape ``(len(index), ...)``).
    h
        Step lengths with ``phi0 * phi1 < 0``, ``(B,)``.
    phi0, phi1
        Indicator at sigma = 0 and sigma = h.
    tol
        Stop when the bracket is narrower than ``tol`` (or phi is exactly 0, or
        +-TINY, the indicators' signed zero).

    Returns
    -------
    (sigma, lower, upper, phi, payload)
        Root estimate, final bracket, indicator and payload at the root estimate.
    """
    size = h.shape[0]
    lower = np.zeros(size)
    upper = h.astype(float).copy()
    f_lower = phi0.astype(float).copy()
    f_upper = phi1.astype(float).copy()
    side = np.zeros(size, dtype=int)
    sigma = np.full(size, np.nan)
    phi = np.full(size, np.nan)
    payload = None
    done = np.zeros(size, dtype=bool)
    last_width = upper - lower
    for iteration in range(max_iter):
        width = upper - lower
        with np.errstate(divide="ignore", invalid="ignore"):
            candidate = (lower * f_upper - upper * f_lower) / (f_upper - f_lower)
        bisect = ~np.isfinite(candidate) | (candidate <= lower) | (candidate >= upper)
        if iteration % 5 == 4:  # safeguard: bisect where the bracket stalls
            bisect |= width > 0.5 * last_width
            last_width = width.copy()
        candidate = np.where(bisect, 0.5 * (lower + upper), candidate)
        active = np.flatnonzero(~done)
        values, state = evaluate(active, candidate[active])
        if payload is None:
            payload = np.full((size,) + state.shape[1:], np.nan)
        payload[active] = state
        sigma[active] = candidate[active]
        phi[active] = values
        f_c = np.full(size, np.nan)
        f_c[active] = values
        a_side = active[np.sign(values) == np.sign(f_lower[active])]
        b_side = active[np.sign(values) == np.sign(f_upper[active])]
        # TINY is the indicators' exact zero (signed by the branch): a root hit
        # exactly.  Taking it as one end of the bracket instead would stall
        # regula falsi there and leave ~15 bisections to close the bracket.
        exact = active[(np.abs(values) <= TINY) | ~np.isfinite(values)]
        # Illinois: halve the retained end's value when the same side moves twice.
        halve_upper = a_side[side[a_side] == 1]
        f_upper[halve_upper] *= 0.5
        lower[a_side], f_lower[a_side], side[a_side] = candidate[a_side], f_c[a_side], 1
        halve_lower = b_side[side[b_side] == -1]
        f_lower[halve_lower] *= 0.5
        upper[b_side], f_upper[b_side], side[b_side] = candidate[b_side], f_c[b_side], -1
        lower[exact] = upper[exact] = candidate[exact]
        width = upper - lower
        done[active] |= width[active] <= tol
        done[exact] = True
        if done.all():
            break
    assert payload is not None
    return sigma, lower, upper, phi, payload
