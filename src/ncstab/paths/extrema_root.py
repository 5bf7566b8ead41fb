"""The path between two stored states, re-solved, and the root of a variable's rate on it.

The numerical part of :mod:`ncstab.paths.extrema` (see there): the rows of states
worked on together (one per case), the tangent of the constrained rate system
by the bordered solve (seed Eq. 35: ``M du = g'_eff dlambda``, M = P + Q K), the
rate of a state variable along it, the path between stored states a and b by
sigma = t_a . (x - x_a) (Newton's method for a law with a total form, RK4 for a
rate-form law) and the Illinois iteration on sigma.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from ncstab.paths.tangent_field import control_matrix
from ncstab.paths.variables import family_fields

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.extrema import Extremum
    from ncstab.systems import SystemDefinition

__all__ = ["NEWTON_TOL", "RATE_STEP", "RK4_STEPS", "SIGMA_TOL", "Rows", "SecantPath", "StateVariable", "path_motion", "rate_along", "rate_root"]

#: Step (in arclength) of the central difference of an interaction variable along
#: the tangent: truncation h^2 v'''/6 ~ 1e-11, rounding eps |v| / h ~ 2e-11.
RATE_STEP = 1e-5
#: Newton's method on the hyperplane stops below this correction (max norm).
NEWTON_TOL = 1e-14
#: Regula falsi stops once the bracket in sigma is this narrow (sigma ~ the stored
#: step, 0.01 to 0.1): the located state is then good to rounding.
SIGMA_TOL = 1e-14
#: RK4 pieces over [0, sigma] for a rate-form law (error ~ (sigma/64)^4 ~ 1e-13).
RK4_STEPS = 64


@dataclass
class Rows:
    """The states being worked on, one per row, with their case's model and stage control."""

    batch: Any
    force_controlled: np.ndarray  # (R, n) bool
    slope: np.ndarray  # (R, n): d(prescribed quantity)/dlambda
    load_slope: np.ndarray  # (R,)
    offset: np.ndarray  # (R, n): prescribed quantities at lambda_a
    load_offset: np.ndarray  # (R,): load parameter at lambda_a
    lam_a: np.ndarray  # (R,)

    def load(self, lam: np.ndarray) -> np.ndarray:
        return self.load_offset + self.load_slope * (lam - self.lam_a)

    def evaluate(self, u: np.ndarray, lam: np.ndarray, internal: np.ndarray):
        if self.batch.has_load:
            return self.batch.evaluate(u, internal, None, load=self.load(lam))
        return self.batch.evaluate(u, internal, None)

    def bordered(self, evaluation, reference: np.ndarray) -> np.ndarray:
        """``[[M, -g'_eff], [reference^T]]``, ``(R, n + 1, n + 1)``."""
        n = self.slope.shape[1]
        rate = self.slope
        if evaluation.dF_dload is not None:
            rate = rate - np.where(self.force_controlled, evaluation.dF_dload, 0.0) * self.load_slope[:, None]
        matrix = np.zeros((len(rate), n + 1, n + 1))
        matrix[:, :n, :n] = control_matrix(evaluation.du_dv, evaluation.dF_dv, self.force_controlled)
        matrix[:, :n, n] = -rate
        matrix[:, n, :] = reference
        return matrix


def _solve(matrix: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """Row-wise solves; NaN for a singular row (a bifurcation point)."""
    try:
        return np.linalg.solve(matrix, rhs[..., None])[..., 0]
    except np.linalg.LinAlgError:
        out = np.full(rhs.shape, np.nan)
        for r in range(len(rhs)):
            try:
                out[r] = np.linalg.solve(matrix[r], rhs[r])
            except np.linalg.LinAlgError:
                pass
        return out


class StateVariable:
    """The value and the rate of one :class:`Extremum` at the rows' states."""

    def __init__(self, spec: Extremum, definition: SystemDefinition) -> None:
        self.spec = spec
        self.fields = family_fields(definition)

    def named(self, evaluation) -> dict[str, np.ndarray]:
        """The interaction variables of an evaluation, by stored name (member axis last)."""
        if evaluation.interactions is None:  # the reduced diamond: one contact standing for four
            return {"l": evaluation.q[:, 0, 0], "alpha": evaluation.q[:, 0, 1],
                    "N": evaluation.normal[:, 0], "T": evaluation.tangential[:, 0]}
        out = {}
        for (family, names, _), (variables, forces) in zip(self.fields, evaluation.interactions):
            values = np.concatenate([variables, forces], axis=-1)
            for a, name in enumerate(names):
                out[name] = values[:, 0, a] if family.size == 1 else values[:, :, a]
        return out

    def value(self, evaluation) -> np.ndarray:
        values = self.named(evaluation)[self.spec.variable]
        return values if self.spec.index is None else values[:, self.spec.index]


@dataclass
class Motion:
    """dx/dsigma at the rows' states: du, dlambda, dP, d(internal), dF, and ds/dsigma."""

    du: np.ndarray
    dlam: np.ndarray
    dload: np.ndarray
    dinternal: np.ndarray
    dF: np.ndarray

    @property
    def speed(self) -> np.ndarray:
        """ds/dsigma, the engine's arclength norm in (u, F, lambda)."""
        return np.sqrt((self.du**2).sum(1) + (self.dF**2).sum(1) + self.dlam**2)


def path_motion(rows: Rows, evaluation, reference: np.ndarray) -> Motion:
    n = rows.slope.shape[1]
    rhs = np.zeros((len(reference), n + 1))
    rhs[:, n] = 1.0
    z = _solve(rows.bordered(evaluation, reference), rhs)
    du, dlam = z[:, :n], z[:, n]
    dload = rows.load_slope * dlam
    dF = np.einsum("rij,rj->ri", evaluation.dF_dv, du)
    if evaluation.dF_dload is not None:
        dF = dF + evaluation.dF_dload * dload[:, None]
    gradient = evaluation.internal_gradient
    dinternal = np.einsum("rij,rj->ri", gradient, du) if gradient is not None else np.zeros((len(du), 0))
    return Motion(du, dlam, dload, dinternal, dF)


def rate_along(rows: Rows, variable: StateVariable, state: tuple, evaluation, motion: Motion) -> np.ndarray:
    """dv/ds at the rows' states (NaN where the tangent is undefined)."""
    spec = variable.spec
    if spec.variable == "u":
        rate = motion.du[:, spec.index]
    elif spec.variable == "F":
        rate = motion.dF[:, spec.index]
    elif spec.variable == "load":
        rate = motion.dload
    else:  # an interaction variable: central difference along the tangent, step RATE_STEP in s
        u, lam, internal = state
        h = RATE_STEP / motion.speed
        ahead = variable.value(rows.evaluate(u + h[:, None] * motion.du, lam + h * motion.dlam,
                                             internal + h[:, None] * motion.dinternal))
        behind = variable.value(rows.evaluate(u - h[:, None] * motion.du, lam - h * motion.dlam,
                                              internal - h[:, None] * motion.dinternal))
        rate = (ahead - behind) / (2 * h)
    return rate / motion.speed


class SecantPath:
    """Points of the path between stored states a and b of each row, by sigma = t_a . (x - x_a)."""

    def __init__(self, rows: Rows, u_a: np.ndarray, lam_a: np.ndarray, internal_a: np.ndarray,
                 t_a: np.ndarray, total_form: bool) -> None:
        self.rows, self.u_a, self.lam_a, self.internal_a, self.t_a = rows, u_a, lam_a, internal_a, t_a
        self.total_form = total_form

    def state(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(u, lambda, internal) at ``sigma`` (``(R,)``)."""
        if self.total_form:
            return self._projected(sigma)
        return self._integrated(sigma)

    def _projected(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        rows, n = self.rows, self.u_a.shape[1]
        x = np.concatenate([self.u_a, self.lam_a[:, None]], 1)
        x = x + (sigma / (self.t_a**2).sum(1))[:, None] * self.t_a  # the predictor along t_a
        internal = self.internal_a
        for _ in range(30):
            u, lam = x[:, :n], x[:, n]
            evaluation = rows.evaluate(u, lam, internal)
            measured = np.where(rows.force_controlled, evaluation.forces, u)
            residual = np.empty_like(x)
            residual[:, :n] = measured - rows.offset - rows.slope * (lam - rows.lam_a)[:, None]
            residual[:, n] = ((x - np.concatenate([self.u_a, self.lam_a[:, None]], 1)) * self.t_a).sum(1) - sigma
            step = _solve(rows.bordered(evaluation, self.t_a), residual)
            x = x - step
            if not np.nanmax(np.abs(step), initial=0.0) > NEWTON_TOL * (1 + np.nanmax(np.abs(x), initial=0.0)):
                break
        return x[:, :n], x[:, n], internal

    def _integrated(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        n = self.u_a.shape[1]
        y = np.concatenate([self.u_a, self.lam_a[:, None], self.internal_a], 1)
        h = (sigma / RK4_STEPS)[:, None]

        def field(y: np.ndarray) -> np.ndarray:
            u, lam, internal = y[:, :n], y[:, n], y[:, n + 1:]
            motion = path_motion(self.rows, self.rows.evaluate(u, lam, internal), self.t_a)
            return np.concatenate([motion.du, motion.dlam[:, None], motion.dinternal], 1)

        for _ in range(RK4_STEPS):
            k1 = field(y)
            k2 = field(y + h / 2 * k1)
            k3 = field(y + h / 2 * k2)
            k4 = field(y + h * k3)
            y = y + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        return y[:, :n], y[:, n], y[:, n + 1:]

    def rate(self, variable: StateVariable, sigma: np.ndarray) -> tuple[np.ndarray, tuple, Any, Motion]:
        state = self.state(sigma)
        evaluation = self.rows.evaluate(*state)
        motion = path_motion(self.rows, evaluation, self.t_a)
        return rate_along(self.rows, variable, state, evaluation, motion), state, evaluation, motion


def rate_root(path: SecantPath, variable: StateVariable, sigma_b: np.ndarray) -> np.ndarray:
    """The root in sigma of the rate on (0, sigma_b) per row (Illinois), NaN where the
    re-solved path does not confirm the stored states' sign change."""
    lo, hi = np.zeros_like(sigma_b), sigma_b.copy()
    f_lo, f_hi = path.rate(variable, lo)[0], path.rate(variable, hi)[0]
    ok = (np.sign(f_lo) * np.sign(f_hi) < 0) & (sigma_b > 0)
    best = np.where(ok, np.nan, np.nan)
    side = np.zeros_like(sigma_b)
    previous = np.full_like(sigma_b, np.inf)
    for _ in range(200):
        active = ok & (np.abs(hi - lo) > SIGMA_TOL * (1 + np.abs(sigma_b)))
        if not active.any():
            break
        sigma = np.where(active, (lo * f_hi - hi * f_lo) / np.where(active, f_hi - f_lo, 1.0), lo)
        f = path.rate(variable, sigma)[0]
        best = np.where(active, sigma, best)
        zero = active & (f == 0)
        upper = active & ~zero & (np.sign(f) == np.sign(f_hi))
        lower = active & ~zero & ~upper
        f_lo = np.where(upper & (side == -1), f_lo / 2, f_lo)
        f_hi = np.where(lower & (side == 1), f_hi / 2, f_hi)
        hi, f_hi = np.where(upper, sigma, hi), np.where(upper, f, f_hi)
        lo, f_lo = np.where(lower, sigma, lo), np.where(lower, f, f_lo)
        side = np.where(upper, -1, np.where(lower, 1, side))
        lo, hi = np.where(zero, sigma, lo), np.where(zero, sigma, hi)
        stalled = active & (np.abs(sigma - previous) <= SIGMA_TOL * (1 + np.abs(sigma_b)))
        lo, hi = np.where(stalled, sigma, lo), np.where(stalled, sigma, hi)
        previous = np.where(active, sigma, previous)
    return np.where(ok, np.where(np.isfinite(best), best, (lo + hi) / 2), np.nan)

