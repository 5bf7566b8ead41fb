"""Which events a step of the sparse engine crossed, from the signs of its indicators
(:mod:`ncstab.paths.assembled_path`): a sign within rounding of zero is no sign, and a
change found certain late is located in the step where the computed sign changed."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ncstab.operators.sparse_indicators import critical_eigenvalue
from ncstab.paths.assembled_engine import Point

__all__ = ["EIGENVALUE_NOISE", "SAME_POINT", "SECANT_NOISE", "SWITCHED"]


#: Below this part of max |K_ij| an eigenvalue (Hill's, the one nearest zero) carries no sign.
EIGENVALUE_NOISE = 1e-13
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
    noise = EIGENVALUE_NOISE * max(scale, 1e-300)
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
