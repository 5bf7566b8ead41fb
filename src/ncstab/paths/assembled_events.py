"""Which events a step of the sparse engine crossed, from the signs of its indicators
(:mod:`ncstab.paths.assembled_path`): a sign within rounding of zero is no sign, and a
change found certain late is located in the step where the computed sign changed, by the
Illinois iteration the compiled loop uses too (:mod:`ncstab.paths.bracket`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.operators.sparse_indicators import critical_eigenvalue
from ncstab.paths.assembled_engine import Point
from ncstab.paths.events import SIGN_NOISE
from ncstab.plain_python import plain_import

__all__ = ["SAME_POINT", "SECANT_NOISE", "SWITCHED", "bracket_ends", "computed_indicators",
           "indicator_value", "locate", "segment_end"]

#: The Illinois iteration's two steps, run as plain Python (the same text the compiled loop runs).
_BRACKET = plain_import("ncstab.paths.bracket")


#: Events located this part of a step apart are at the same point (Hill's eigenvalue and det K
#: vanish together on a symmetric path; eigvalsh locates the first to 1e-8 of a step, the LU 1e-12).
SAME_POINT = 1e-6
#: Below this part of |lambda / scale| a step's change of lambda carries no sign: just past a
#: bifurcation dR/dlambda is proportional to the small amplitude, and the corrector's lambda on
#: a column of 2,000 links jitters by 2e-12 of itself (1e-12 gave spurious turning points).
SECANT_NOISE = 1e-10
#: Marks the indicators of a located bifurcation point where the path switched branch.  The first
#: step's secant from it carries no sign: the point's lambda is the pencil's Rayleigh quotient
#: (:func:`~ncstab.paths.assembled_path.refine_critical_load`) and the next one's is Newton's, two
#: roundings of lambda of relative size eps (n/pi)^2 on a column of n links (1.4e-10 at 5,001 links),
#: while the branch itself rises by O(h^2) (P1 theta^2 / 8, 1e-18 there).  The secant's sign is
#: taken from the steps after it, so that rounding is not read as a turning point.
SWITCHED = "switched_here"


@dataclass(frozen=True)
class _Segment:
    """One accepted step: from ``start`` along ``tangent`` over ``h``; ``s`` the arclength at
    its start, ``index`` the start's place in the stored points."""

    start: Point
    tangent: np.ndarray
    h: float
    s: float
    index: int


def _crossed_segment(trail: list[_Segment], step: _Segment, key: str, before: float) -> _Segment:
    """The step in which ``key``'s computed sign left ``before``.

    A change of sign found certain at the end of ``step`` may have happened in an earlier
    step where the value was within rounding of zero (its sign then carried,
    :func:`_steady`): the computed sign is still the best there is, so the crossing is
    located in the last step whose start still had the computed sign ``before`` (a Hencky
    column of 2,000 links: the critical eigenvalue is 6e-12 x (1 - P / P1) against entries
    of K of order 6, within rounding for 10 % of P1 on either side).
    """
    if key not in ("det", "det_SS", "hill", "divergence"):
        return step
    for segment in reversed([*trail, step]):
        raw = segment.start.raw if segment.start.raw is not None else segment.start.indicators
        if _sign(raw.get(key, before)) == before:
            return segment
    return trail[0] if trail else step


def _steady(stepper, p: Point, q: Point) -> dict:
    """q's computed indicators (``q.raw``), with the sign of p kept where q's value is within rounding of zero.

    A sign within rounding is no sign: just past a bifurcation the buckled column's
    critical eigenvalue is 1e-16 against entries of K of order 6, and dlambda/ds is
    1e-7 with errors of the same size.  Keeping the last sign that was certain means
    a true crossing is still a change, found where the sign becomes certain and located
    where the computed sign changed (:func:`_crossed_segment`).
    """
    a, b = p.indicators, dict(q.raw)
    K = q.state.K
    scale = float(abs(K).max()) if K.shape[0] else 1.0
    noise = SIGN_NOISE * max(scale, 1e-300)  # (the compiled loop's, ncstab.paths.events)
    rise = float(q.y[-1] - p.y[-1])  # the secant's dlambda: robust where the tangent is not
    if a.get(SWITCHED):  # the first step off a switched bifurcation: no sign yet (see SWITCHED)
        b["secant"] = 0.0
    else:
        b["secant"] = a.get("secant", 0.0) if abs(rise) <= SECANT_NOISE * max(1.0, abs(q.y[-1])) else rise
    if b.get("exact"):  # signs computed without K's rounding (ncstab.paths.trivial_path): nothing to carry
        return b
    if abs(b["hill"]) <= noise:
        b["hill"] = a["hill"]
    for key, matrix in (("det", K), ("det_SS", None)):
        if _sign(a[key]) != _sign(b[key]):
            if matrix is None:
                matrix = stepper.run.blocks(stepper.control, q.state, stepper.lam(q.y))[0]
            if abs(critical_eigenvalue(matrix)[0]) <= noise:
                b[key] = a[key]
                if key == "det":
                    b["bordered"] = a["bordered"]
    if "divergence" in b:  # the dynamic divergence test is det K_SS's sign, carried alike
        b["divergence"] = b["det_SS"]
    return b


def _sign(x: float) -> float:
    return 0.0 if x == 0 or not np.isfinite(x) else float(np.sign(x))


def _changed(a: dict, b: dict, key: str) -> bool:
    return key in a and key in b and _sign(a[key]) * _sign(b[key]) < 0


def _event_names(a: dict, b: dict) -> list[str]:
    names = []
    if _changed(a, b, "det"):
        names.append("bifurcation" if _changed(a, b, "bordered") else "limit_point")
    if _changed(a, b, "det_SS"):
        names.append("controllability_loss")
    if _changed(a, b, "hill"):
        names.append("hill_loss")
    if _changed(a, b, "secant"):
        names.append("turning_point")
    if _changed(a, b, "onset"):  # a system with inertia (ncstab.paths.assembled_dynamics)
        names.append("flutter_onset")
    if _changed(a, b, "divergence"):
        names.append("divergence")
    if "gap" in a and a["gap"] > 0 and b.get("gap", np.inf) < 0:
        names.append("secondary_contact")
    return names


def _indicator_key(event: str) -> str:
    return {"bifurcation": "det", "limit_point": "det", "controllability_loss": "det_SS", "hill_loss": "hill",
            "turning_point": "turning", "secondary_contact": "gap", "flutter_onset": "onset",
            "divergence": "divergence"}[event]


def locate(stepper, p: Point, t: np.ndarray, h: float, value, ends: tuple[float, float], tol: float):
    """The sign change of ``value(point)`` on sigma in (0, h), from ``ends`` (its values at
    0 and h, of opposite signs), by the Illinois iteration (:mod:`ncstab.paths.bracket`, the
    compiled loop's), each trial re-corrected onto the path; to ``tol`` of the step.

    Returns (sigma, lower, upper, point at sigma).  A trial whose bordered Jacobian is
    singular (the secant's zero on the very bifurcation point of a trivial path) is taken
    at the bracket's middle instead; where a trial's corrector fails, the state is
    re-corrected at the bracket's middle and the iteration ends, as bisection's would.
    """
    lower, upper = 0.0, h
    (f_lower, f_upper), side, last_width = ends, 0, h
    sigma, found = np.nan, None
    for iteration in range(200):
        if upper - lower <= tol * max(h, 1e-300):
            break
        trial, last_width = _BRACKET.illinois_trial(lower, upper, f_lower, f_upper, iteration, last_width)
        q = _corrected(stepper, p, t, trial)
        if q is _SINGULAR:
            trial = 0.5 * (lower + upper)
            q = _corrected(stepper, p, t, trial)
        if q is None or q is _SINGULAR:
            found = None
            break
        sigma, found = trial, q
        lower, upper, f_lower, f_upper, side, exact = _BRACKET.illinois_update(
            lower, upper, f_lower, f_upper, side, trial, value(q))
        if exact:
            break
    if found is None:
        sigma = 0.5 * (lower + upper)
        found = _corrected(stepper, p, t, sigma)
        found = None if found is _SINGULAR else found
    return sigma, lower, upper, found


#: What :func:`_corrected` returns where the bordered Jacobian is singular.
_SINGULAR = object()


def _corrected(stepper, p: Point, t: np.ndarray, sigma: float):
    """The state at sigma along t from p, corrected onto the path, with its tangent and
    indicators; None where the corrector fails, ``_SINGULAR`` where a solve is singular."""
    try:
        q = stepper.correct(p.y + sigma * t, t, p)
        if q is not None:
            q.tangent = stepper.tangent(q, t)
            q.indicators = stepper.indicators(q)
    except (np.linalg.LinAlgError, RuntimeError):  # numpy's singular solve; SuperLU's exactly singular factor
        return _SINGULAR
    return q


def computed_indicators(point: Point) -> dict:
    """A point's indicators as computed (``raw``, where :func:`_steady` carried some signs)."""
    return point.indicators if point.raw is None else point.raw


def indicator_value(key: str, start: Point):
    """The signed value at a point whose zero is the crossing of ``key``, for the Illinois
    iteration: the computed indicator itself, or for a determinant (kept as its sign and
    log |det|) its sign times |det| / |det at the bracket's start| (a determinant is linear
    through a simple zero, and the exponent of the ratio is clipped to +-700, in float64's range)."""
    logs = {"det": "log_det", "det_SS": "log_det_SS", "divergence": "log_det_SS"}
    if key not in logs:
        return lambda x: float(computed_indicators(x)[key])
    log = logs[key]
    reference = float(computed_indicators(start)[log])

    def determinant_ratio(x: Point) -> float:
        values = computed_indicators(x)
        return float(values[key]) * float(np.exp(np.clip(float(values[log]) - reference, -700.0, 700.0)))
    return determinant_ratio


def segment_end(trail: list[_Segment], step: _Segment, q: Point, where: _Segment) -> Point:
    """The point where segment ``where`` (one of ``trail``, or ``step`` ending at ``q``) ends."""
    segments = [*trail, step]
    index = next(k for k, segment in enumerate(segments) if segment is where)
    return segments[index + 1].start if index + 1 < len(segments) else q


def bracket_ends(first: float, last: float, before: float) -> tuple[float, float]:
    """The values at a bracket's ends, ``first`` of sign ``before`` and ``last`` of the other.
    An end whose value has not that sign (a turning point detected by the secant's sign, the
    tangent's already turned at the step's start) takes the other end's size with its sign: the
    iteration then closes on that end, as bisection on the sign would."""
    size = next((abs(v) for v in (first, last) if np.isfinite(v) and v != 0.0), 1.0)
    first = first if _sign(first) == before else before * size
    last = last if _sign(last) == -before else -before * size
    return first, last
