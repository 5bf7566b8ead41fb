"""Stepping, event location and branch switching of the sparse engine (see :mod:`ncstab.paths.assembled_engine`)."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ncstab.operators.assembly import energy_forms, gap_candidates
from ncstab.operators.sparse_indicators import critical_eigenvalue, determinant, hill_eigenvalue, is_symmetric
from ncstab.paths.assembled_control import StageControl, StageStartError, stage_control
from ncstab.paths.assembled_dynamics import dynamic_indicators, has_dynamics
from ncstab.paths.assembled_engine import GAP_REACH, MAX_LAMBDA_STEP, MAX_RELATIVE_MOVE, CaseRun, DomainError, Point
from ncstab.paths import assembled_events
from ncstab.paths.branch_switching import DERIVATIVE_STEP, bifurcation_coefficients, branch_direction
from ncstab.paths.assembled_mixed import ROUNDING_FLOOR, at_rounding_floor, mixed_solver
from ncstab.paths.assembled_events import (
    SAME_POINT, SWITCHED, _crossed_segment, _event_names, _indicator_key, _Segment, _sign, _steady, bracket_ends,
    indicator_value, locate, segment_end,
)
from ncstab.paths.programme import LoadingProgramme
from ncstab.paths.status import finished_message, max_steps_message, stopped_message
from ncstab.paths.trivial_path import is_trivial, trivial_path_signs

__all__ = ["ROUNDING_FLOOR", "CaseOutcome", "at_rounding_floor", "follow_case"]

#: The largest turn of the path's tangent over one step (radians): a step whose end's
#: tangent turns more is taken again shorter.
MAX_TURN = 0.2


def _failure_text(where: str, turned: bool, at_floor: bool) -> str:
    """Why the steps shrank below ``min_step``: the last one's tangent turned too far, or
    its corrector did not converge; and whether a corrector stopped at the rounding floor
    since the last accepted step (:func:`at_rounding_floor`)."""
    text = f"{where}: " + (f"the tangent turns by more than {MAX_TURN} rad over every step down to min_step"
                           if turned else "the corrector does not converge")
    if at_floor:
        text += "; the corrector's residual reached the rounding floor of the forces it balances " \
                "(the path is below float64's resolution there)"
    return text


def _last_unit(size: int) -> np.ndarray:
    """The unit vector along y's last coordinate, lambda / scale."""
    out = np.zeros(size)
    out[-1] = 1.0
    return out


@dataclass
class CaseOutcome:
    """What one case gives: its stored points (with stage and arclength), events, status."""

    points: list[Point] = field(default_factory=list)
    stages: list[int] = field(default_factory=list)
    arclength: list[float] = field(default_factory=list)
    events: dict[str, dict] = field(default_factory=dict)
    status: str = "finished"
    message: str = ""
    accepted: int = 0
    rejected: int = 0


class Stepper:
    """One stage of one case: predictor, corrector, tangent, indicators."""

    def __init__(self, run: CaseRun, control: StageControl) -> None:
        self.run, self.control = run, control
        self.m = len(control.force_dofs)
        #: Whether, since the last accepted step, a corrector that did not converge, or a step
        #: whose tangent turned too far, ended at the rounding floor (:func:`at_rounding_floor`).
        self.at_floor = False
        #: Whether the bordered systems are solved in mixed form (:mod:`ncstab.paths.assembled_mixed`):
        #: from a step that failed at the rounding floor to the stage's end.
        self.mixed = False

    def lam(self, y: np.ndarray) -> float:
        return float(y[self.m] * self.control.scale)

    def point(self, y: np.ndarray, start: Point | None, along: np.ndarray | None = None) -> Point:
        """The state at y, its internal variables advanced from ``start``; ``along``: the path's
        unit tangent at ``start`` in this stage's y (the step then follows a quadratic arc)."""
        u = self.control.displacements(np.append(y[: self.m], self.lam(y)), self.run.n)
        load = self.control.load(self.lam(y))
        velocity = None if along is None else float(along @ (y - start.y)) * self.displacement_rate(along)
        internal = self.run.advance(start, u, velocity)
        return Point(y.copy(), u, load, self.run.evaluate(u, load, internal), internal)

    def displacement_rate(self, direction: np.ndarray) -> np.ndarray:
        """du along ``direction`` in y = (u_S, lambda / scale)."""
        du = np.zeros(self.run.n)
        du[self.control.force_dofs] = direction[: self.m]
        du[self.control.displacement_dofs] = self.control.u_slope * self.control.scale * direction[self.m]
        return du

    def residual(self, p: Point) -> np.ndarray:
        c = self.control
        return p.state.R[c.force_dofs] - (c.f_base + c.f_slope * self.lam(p.y))

    def correct(self, predictor: np.ndarray, normal: np.ndarray, start: Point | None,
                fixed_lambda: float | None = None) -> Point | None:
        """Newton onto G = 0 and normal . (y - predictor) = 0 (or lambda = fixed_lambda)."""
        options = self.run.options
        y = predictor.copy()
        last = normal if fixed_lambda is None else _last_unit(self.m + 1)
        along = None
        if fixed_lambda is None and start is not None and start.tangent is not None \
                and start.tangent.shape == normal.shape and np.array_equal(start.tangent, normal):
            along = normal  # a step along the path from start: its arc, not its chord
        for _ in range(options.newton_max_iter):
            try:
                p = self.point(y, start, along)
            except DomainError:
                return None
            K_SS, column = self.run.blocks(self.control, p.state, self.lam(y))
            constraint = normal @ (y - predictor) if fixed_lambda is None else y[self.m] - fixed_lambda / self.control.scale
            G = self.residual(p)
            if not np.all(np.isfinite(G)):
                return None
            step = self.solve(p, K_SS, column, last, -np.append(G, constraint))
            y = y + step
            if np.max(np.abs(step)) <= options.newton_tol * (1.0 + np.max(np.abs(y))):
                try:
                    return self.point(y, start, along)
                except DomainError:
                    return None
        self.at_floor = self.at_floor or at_rounding_floor(G, p.state, p.u, p.load)
        return None

    def tangent(self, p: Point, previous: np.ndarray) -> np.ndarray:
        K_SS, column = self.run.blocks(self.control, p.state, self.lam(p.y))
        z = self.solve(p, K_SS, column, previous, _last_unit(self.m + 1), tangent=True)
        return z / np.linalg.norm(z)

    def solve(self, p: Point, K_SS, column: np.ndarray, last: np.ndarray, right: np.ndarray, tangent=False):
        """The bordered system [[K_SS, column], [last]] x = right at p: in mixed form once ``mixed``,
        else with K_SS (for a tangent, accurately next to a bifurcation)."""
        if self.mixed:
            return mixed_solver(self.run, self.control, p, column, last)(right)
        return (self.run.solve_tangent if tangent else self.run.solve)(self.run.bordered(K_SS, column, last), right)

    def indicators(self, p: Point) -> dict[str, float]:
        """Signed indicators at p (tangent known): det K, det K_SS, the bordered det, Hill, dlambda/ds, gaps,
        and the dynamic ones of a system with inertia (:mod:`ncstab.paths.assembled_dynamics`)."""
        K_SS, column = self.run.blocks(self.control, p.state, self.lam(p.y))
        sign, log = determinant(p.state.K)
        everything = self.m == self.run.n
        sign_SS, log_SS = (sign, log) if everything else determinant(K_SS) if self.m else (1.0, 0.0)
        bordered = self.run.bordered_sign(self.run.bordered(K_SS, column, p.tangent))
        du = self.displacement_rate(p.tangent)
        dF = p.state.K @ du
        size = np.linalg.norm(du) * np.linalg.norm(dF)
        out = {"det": sign, "log_det": log, "det_SS": sign_SS, "log_det_SS": log_SS, "bordered": bordered,
               "hill": hill_eigenvalue(p.state.K), "turning": float(p.tangent[self.m]),
               "d2W": float(du @ dF / size) if size > 0 else np.nan}
        if is_trivial(self, p):  # signs exact where K's rounding hides them (a long straight column)
            trivial_path_signs(self, p, out, assembled_events.SIGN_NOISE)
        if has_dynamics(self.run.system):  # M s^2 + C s + K: flutter onset, divergence (det K_SS)
            out.update(dynamic_indicators(self.run.system, p.u, p.state.K), divergence=out["det_SS"])
        if self.run.system.grains is not None:
            pairs, gaps = gap_candidates(self.run.system, p.u, GAP_REACH)
            closed = {tuple(x) for x in self.run.closed.tolist()}
            open_ = np.array([tuple(x) not in closed for x in pairs.tolist()], dtype=bool) if len(pairs) else np.zeros(0, bool)
            out["gap"] = float(gaps[open_].min()) if open_.any() else np.inf
            out["gap_pairs"], out["gap_values"] = pairs[open_], gaps[open_]
        return out


def _record(out: CaseOutcome, name: str, q: Point, stage: int, s: float, lower: float, upper: float, lam: float) -> None:
    if name in out.events:
        return
    out.events[name] = {"point": q, "s": s, "s_lower": lower, "s_upper": upper, "stage": stage, "lam": lam}


def _switch_direction(stepper: Stepper, e: Point, sense: int) -> np.ndarray:
    """The bifurcating branch's tangent at e, from the algebraic bifurcation equation the
    compiled route solves too (:func:`~ncstab.paths.branch_switching.branch_direction`):
    t0 the incoming tangent, t1 = (phi, 0) orthogonal to it (phi the null vector of K_SS,
    which with t0 spans the null space of A = dG/dy = [K_SS | column]), psi the left null
    vector, c_ij = psi^T D2G[t_i, t_j] by central differences of A (the same step).  On a
    symmetric pitchfork (Hencky's column) c00 = c11 = 0 and the branch leaves along t1; on
    a transcritical bifurcation along the other root."""
    control, run, m = stepper.control, stepper.run, stepper.m
    K_SS, _ = run.blocks(control, e.state, stepper.lam(e.y))
    _, phi = critical_eigenvalue(K_SS)
    psi = phi if is_symmetric(K_SS) else critical_eigenvalue(K_SS.T)[1]
    t0 = e.tangent
    t1 = np.append(phi, 0.0)
    t1 -= (t1 @ t0) * t0
    t1 /= np.linalg.norm(t1)
    if t1[np.argmax(np.abs(t1))] < 0:
        t1 = -t1

    def along(y: np.ndarray, a: np.ndarray) -> np.ndarray:
        """A(y) a = K_SS a_S + column a_lambda, the internal variables held at e's."""
        lam = stepper.lam(y)
        u = control.displacements(np.append(y[:m], lam), run.n)
        K, column = run.blocks(control, run.evaluate(u, control.load(lam), e.internal), lam)
        return K @ a[:m] + column * a[m]

    def second(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        h = DERIVATIVE_STEP
        return np.array([psi @ (along(e.y + h * b[0], a[0]) - along(e.y - h * b[0], a[0])) / (2 * h)])

    direction = branch_direction(*bifurcation_coefficients(second, t0[None], t1[None]), t0[None], t1[None])[0]
    return sense * direction


def refine_critical_load(stepper: Stepper, e: Point) -> Point:
    """On a trivial path of a load-parameter stage (u does not move with P), the located critical
    load refined by the two-sided Rayleigh quotient of the pencil K = K_int - P K_load, in element
    form (:func:`ncstab.operators.assembly.energy_forms`): stationary at the critical load, and free
    of the cancellation in K's assembled entries that limits a sign-change location at large n."""
    control, run, m = stepper.control, stepper.run, stepper.m
    if not control.load_stage or control.load_slope != 1.0 or control.load_base != 0.0 \
            or e.tangent is None or np.max(np.abs(e.tangent[:m]), initial=0.0) > 1e-10:  # (lambda = P only)
        return e
    K_SS, _ = run.blocks(control, e.state, stepper.lam(e.y))
    right, left = np.zeros(run.n), np.zeros(run.n)
    right[control.force_dofs] = critical_eigenvalue(K_SS)[1]
    left[control.force_dofs] = critical_eigenvalue(K_SS.T)[1]
    inner, outer = energy_forms(run.system, run.law, run.parameters, e.u, e.internal, left, right,
                                run.closed, run.kappa)
    if outer == 0 or not np.isfinite(inner / outer):
        return e
    refined = stepper.correct(e.y, e.tangent, None, fixed_lambda=inner / outer)
    if refined is None or abs(refined.load - e.load) > 1e-6 * max(abs(e.load), 1e-300):
        return e
    refined.internal = e.internal
    try:
        refined.tangent = stepper.tangent(refined, e.tangent)
    except np.linalg.LinAlgError:  # exactly critical: a chain of one dof, K = 0 and dR/dP = 0 there
        refined.tangent = e.tangent
    refined.indicators = e.indicators
    return refined


def _quiet(indicators: dict, keys) -> dict:
    """The indicators with the signs of ``keys`` cleared (a restart on their zero)."""
    return {**indicators, **{k: 0.0 for k in keys if k in indicators}}


def follow_case(run: CaseRun, programme: LoadingProgramme, values: dict[str, float], dofs, forces,
                load_name: str | None, progress=None) -> CaseOutcome:
    """Follow one case along ``programme``; never raises for a numerical failure (its status says it).
    ``progress(stage, fraction)``, if given, is told after every accepted step how far the stage
    (from 1) is along its driven quantity (0 at its start, 1 at its target)."""
    out = CaseOutcome(message=finished_message(len(programme.stages)))
    options = run.options
    u = np.zeros(run.n)
    state = run.evaluate(u, 0.0, run.initial_internal())
    previous = Point(np.zeros(0), u, 0.0, state, run.initial_internal())
    s, on_branch = 0.0, 0  # (the Dataset's branch_index of the states stored from here)
    for number, stage in enumerate(programme.stages):
        try:
            control = stage_control(stage, number + 1, dofs, forces, load_name, previous.u, previous.state.R,
                                    previous.load, values)
        except StageStartError as error:
            out.status, out.message = "failed:bad_stage_start", str(error)
            return out
        if control.zero_length:  # every driven quantity at its target: nothing to follow
            continue
        stepper = Stepper(run, control)
        m = stepper.m
        y0 = np.append(previous.u[control.force_dofs], control.lam_start / control.scale)
        sense = 1.0 if control.lam_end >= control.lam_start else -1.0
        p = stepper.correct(y0, _last_unit(m + 1), previous, fixed_lambda=control.lam_start)
        if p is None:
            out.status, out.message = "failed:newton", f"stage {number + 1}: no equilibrium at its start"
            return out
        p.tangent = stepper.tangent(p, sense * _last_unit(m + 1))
        p.indicators = {**stepper.indicators(p), "secant": sense}
        if not out.points:  # the programme's first state (after any zero-length stage)
            out.points.append(p), out.stages.append(number), out.arclength.append(0.0)
        p.branch = on_branch
        switching = getattr(stage, "at_bifurcation", "continue")
        sense_switch = getattr(stage, "direction", 1)
        if switching == "branches":
            branch = int(values.get("branch", 0))
            switching, sense_switch = ("switch", branch) if branch else ("continue", 1)
        switched = False
        trail: list[_Segment] = []  # this stage's accepted steps since its start or last disruption
        t = p.tangent
        h = 0.01 if options.initial_step == "auto" else float(options.initial_step)
        target = control.lam_end
        while True:
            if out.accepted >= options.max_steps:
                out.status, out.message = "failed:max_steps", max_steps_message(options.max_steps)
                return out
            h = min(h, MAX_LAMBDA_STEP / max(abs(t[m]), 1e-300),
                    MAX_RELATIVE_MOVE * max(1.0, np.max(np.abs(p.u))) / max(np.max(np.abs(t[:m]), initial=0.0), 1e-300))
            q = stepper.correct(p.y + h * t, t, p)
            turned = False  # (the corrector converged, but the tangent there turned too far)
            if q is not None:
                q.tangent = stepper.tangent(q, t)
                if q.tangent @ t < np.cos(MAX_TURN):  # (its residual may be at the floor: its tangent is rounding)
                    stepper.at_floor = stepper.at_floor or at_rounding_floor(stepper.residual(q), q.state, q.u, q.load)
                    q, turned = None, True
            if q is None:
                out.rejected += 1
                h *= 0.5
                stepper.mixed = stepper.mixed or stepper.at_floor  # K below float64's resolution
                if h < options.min_step:
                    where = f"stage {number + 1} at lambda = {stepper.lam(p.y):.6g}"
                    try:
                        stepper.point(p.y + 2 * options.min_step * t, p)
                        reason, text = "newton", _failure_text(where, turned, stepper.at_floor)
                    except ArithmeticError as error:
                        reason, text = "domain", f"{where}: the path leaves the domain ({error})"
                    out.status, out.message = f"failed:{reason}", text
                    return out
                continue
            q.raw = stepper.indicators(q)
            q.indicators = _steady(stepper, p, q)
            lam_p, lam_q = stepper.lam(p.y), stepper.lam(q.y)
            step = _Segment(p, t, h, s, len(out.points) - 1)
            crossings: list[tuple[float, str, float, float, Point, _Segment]] = []
            for name in _event_names(p.indicators, q.indicators):
                key = _indicator_key(name)
                before = 1.0 if key == "gap" else _sign(p.indicators["secant"]) if key == "turning" else _sign(p.indicators[key])
                where = _crossed_segment(trail, step, key, before)

                value = indicator_value(key, where.start)
                ends = bracket_ends(value(where.start), value(segment_end(trail, step, q, where)), before)
                sigma, lo, hi, e = locate(stepper, where.start, where.tangent, where.h, value, ends, options.event_tol)
                if e is not None:
                    if name in ("bifurcation", "limit_point"):
                        e = refine_critical_load(stepper, e)
                    crossings.append((where.s + sigma, name, where.s + lo, where.s + hi, e, where))
            if (lam_q - target) * sense >= 0 and (lam_p - target) * sense < 0:
                def past_target(x: Point) -> float:
                    return (stepper.lam(x.y) - target) * sense
                sigma, lo, hi, e = locate(stepper, p, t, h, past_target, bracket_ends(past_target(p), past_target(q), -1.0),
                                           options.event_tol)
                end = stepper.correct(p.y + sigma * t, t, p, fixed_lambda=target) if e is not None else None
                if end is not None:
                    end.tangent, end.indicators = e.tangent, e.indicators
                else:  # Newton at the target itself failed (a column of 5,000 links, buckled): the
                    end = e  # the located point, within event_tol of a step of the target
                if end is not None:
                    crossings.append((s + sigma, "<end>", s + lo, s + hi, end, step))
            crossings.sort(key=lambda c: c[0])
            disrupted = None
            for at, name, lower, upper, e, where in crossings:
                if disrupted is not None and lower > disrupted[0] + SAME_POINT * h:
                    break  # past the disruption: not on this path
                if name == "<end>":
                    disrupted = disrupted or (at, name, e, where)
                    continue
                _record(out, name, e, number, at, lower, upper, stepper.lam(e.y))
                if disrupted is not None:
                    continue  # an event at the same point as the disruption: recorded, nothing more
                if name in stage.stop_at or (name == "secondary_contact" and run.mode == "stop"):
                    disrupted = (at, "stop:" + name, e, where)
                elif name == "bifurcation" and switching == "switch" and not switched:
                    disrupted = (at, "switch", e, where)
                elif name == "secondary_contact" and run.mode == "activate":
                    disrupted = (at, "activate", e, where)
            stepper.at_floor = False  # (a step is accepted)
            if disrupted is None:
                out.accepted += 1
                trail.append(step)
                s += h
                q.branch = on_branch
                out.points.append(q), out.stages.append(number), out.arclength.append(s)
                if progress is not None:  # (the fraction may leave [0, 1] on a path that turns back)
                    progress(number + 1, (stepper.lam(q.y) - control.lam_start) / (target - control.lam_start))
                p, t = q, q.tangent
                h *= 1.3
                continue
            s, what, e, where = disrupted
            out.accepted += 1
            trail.clear()
            kept = where.index + 1  # a crossing found in an earlier step: the points past it are dropped
            del out.points[kept:], out.stages[kept:], out.arclength[kept:]
            on_branch = e.branch = sense_switch if what == "switch" else on_branch  # (the point left is on it)
            out.points.append(e), out.stages.append(number), out.arclength.append(s)
            if what == "<end>":
                previous = e
                break
            if what.startswith("stop:"):
                out.status = f"stopped:{what[5:]}"
                out.message = stopped_message(what[5:], number + 1)
                return out
            if what == "switch":
                switched = True
                e.tangent = _switch_direction(stepper, e, sense_switch)
                e.indicators = {**_quiet(e.indicators, ("det", "det_SS", "bordered", "hill", "secant", "divergence")),
                                SWITCHED: True}
            else:  # a secondary contact closes: its spring acts from here on
                pairs, gaps = e.indicators["gap_pairs"], e.indicators["gap_values"]
                run.closed = np.concatenate([run.closed, pairs[gaps <= 1e-9 * max(1.0, np.max(np.abs(e.u)))]])
                e = stepper.point(e.y, p) if len(run.closed) else e
                e.tangent = stepper.tangent(e, t)
                e.indicators = _quiet({**stepper.indicators(e), "secant": e.indicators.get("secant", 0.0)},
                                      ("det", "det_SS", "bordered", "hill"))
            p, t = e, e.tangent
            h = max(h * 0.5, 1e-6)
    return out
