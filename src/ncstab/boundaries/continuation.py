"""Pseudo-arclength continuation of a curve G(X) = 0 with a bordered Newton corrector.

The curve is the solution set of ``N - 1`` equations in ``N`` unknowns
(:class:`~ncstab.boundaries.conditions.BoundaryProblem`).  From a point X_k
with unit tangent T_k, the predictor is ``X_k + ds T_k`` and the corrector
solves the bordered system (Keller 1977; AUTO-07p manual, ch. 3;
BifurcationKit.jl, "Pseudo arclength continuation")::

    [ G_X(X)  ] dX = - [ G(X)                    ]
    [ T_k^T   ]        [ T_k . (X - X_k) - ds    ]

The Jacobian G_X is by central differences, all columns in one batched
evaluation.  The new tangent solves ``[G_X; T_k^T] T = [0; 1]``, normalised:
a sign change of its p component is a fold of the curve.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

__all__ = ["ContinuationOptions", "CurvePoint", "correct", "jacobian", "tangent", "trace_curve"]


@dataclass(frozen=True)
class ContinuationOptions:
    """Options of the continuation (change with :func:`dataclasses.replace`).

    Attributes
    ----------
    min_points
        The largest step in arclength is ``abs(stop - start) / min_points``, so
        that the curve has at least that many points over its range.
    max_points
        The most points of one curve.
    tolerance
        Newton converges when ``max |G| <= tolerance`` and ``max |dX| <= tolerance``.
    max_iterations
        Newton iterations per step before the step is halved.
    min_step
        The smallest step; below it the curve ends (``failed``).
    difference_step
        Relative step of the central differences of G_X.
    """

    min_points: int = 50
    max_points: int = 2000
    tolerance: float = 1e-11
    max_iterations: int = 12
    min_step: float = 1e-9
    difference_step: float = 1e-6


@dataclass
class CurvePoint:
    """One point of a curve and what was noted there (``""``, ``"start"``, ``"fold"``, ``"end"``, ``"failed: ..."``)."""

    X: np.ndarray
    note: str = ""
    tangent: np.ndarray = field(default_factory=lambda: np.zeros(0))


def jacobian(residual: Callable[[np.ndarray], np.ndarray], X: np.ndarray, relative_step: float) -> np.ndarray:
    """G_X ``(N - 1, N)`` by central differences, the 2N points in one batch."""
    size = X.size
    steps = relative_step * (1.0 + np.abs(X))
    points = np.repeat(X[None, :], 2 * size, axis=0)
    index = np.arange(size)
    points[index, index] += steps
    points[size + index, index] -= steps
    values = residual(points)
    return ((values[:size] - values[size:]) / (2.0 * steps[:, None])).T


def correct(
    residual: Callable[[np.ndarray], np.ndarray],
    X: np.ndarray,
    border: np.ndarray,
    target: float,
    options: ContinuationOptions,
) -> np.ndarray | None:
    """Newton on ``[G(X); border . X - target] = 0`` (a bordered system); ``None`` if it does not converge."""
    for _ in range(options.max_iterations):
        value = np.append(residual(X[None, :])[0], border @ X - target)
        if not np.all(np.isfinite(value)):
            return None
        matrix = np.vstack([jacobian(residual, X, options.difference_step), border])
        try:
            step = np.linalg.solve(matrix, -value)
        except np.linalg.LinAlgError:
            return None
        X = X + step
        if np.max(np.abs(step)) <= options.tolerance * (1.0 + np.max(np.abs(X))):
            final = residual(X[None, :])[0]
            return X if np.all(np.isfinite(final)) and np.max(np.abs(final)) <= 1e3 * options.tolerance else None
    return None


def tangent(residual: Callable[[np.ndarray], np.ndarray], X: np.ndarray, previous: np.ndarray, options: ContinuationOptions) -> np.ndarray:
    """The unit tangent at X, oriented along ``previous``: ``[G_X; previous^T] T = [0; 1]``."""
    matrix = np.vstack([jacobian(residual, X, options.difference_step), previous])
    rhs = np.zeros(X.size)
    rhs[-1] = 1.0
    direction = np.linalg.solve(matrix, rhs)
    return direction / np.linalg.norm(direction)


def trace_curve(
    residual: Callable[[np.ndarray], np.ndarray],
    start: np.ndarray,
    stop: float,
    options: ContinuationOptions,
    on_accept: Callable[[np.ndarray], None] | None = None,
    origin: float | None = None,
) -> list[CurvePoint]:
    """Continue G(X) = 0 from ``start`` (``start[0]`` the parameter p) to ``p = stop``.

    The first point is corrected at fixed p; the last one is solved at
    ``p = stop`` exactly (note ``"end"``).  ``on_accept(X)`` runs after each
    accepted point (to update the borders of a minimally augmented system).
    The curve ends where it folds back past ``origin`` (the start of its range;
    default ``start[0]``).

    Returns
    -------
    list of CurvePoint
        In order along the curve; the last point's note says how it ended.
    """
    size = start.size
    unit = np.zeros(size)
    unit[0] = 1.0
    p0 = float(start[0])
    origin = p0 if origin is None else float(origin)
    first = correct(residual, start.astype(float), unit, p0, options)
    if first is None:
        return [CurvePoint(start, "failed: no boundary point at the start value")]
    if on_accept is not None:
        on_accept(first)
    direction = np.sign(stop - p0)
    T = tangent(residual, first, unit * direction, options)
    points = [CurvePoint(first, "start", T)]
    max_step = abs(stop - p0) / options.min_points
    ds = max_step / 4
    X = first
    while len(points) < options.max_points:
        predicted = X + ds * T
        if direction * (predicted[0] - stop) >= 0 and abs(T[0]) > 1e-3:  # the end: solve at p = stop
            guess = X + (stop - X[0]) / T[0] * T
            end = correct(residual, guess, unit, stop, options)
            if end is not None:
                points.append(CurvePoint(end, "end", T))
                return points
        new = correct(residual, predicted, T, T @ predicted, options)
        if new is None or np.linalg.norm(new - predicted) > 0.5 * ds + 1e-12:
            ds /= 2
            if ds < options.min_step:
                points[-1].note = points[-1].note or "failed: the continuation step fell below its minimum"
                if points[-1].note == "start":
                    points[-1].note = "start; failed: the continuation step fell below its minimum"
                return points
            continue
        if on_accept is not None:
            on_accept(new)
        T_new = tangent(residual, new, T, options)
        note = "fold" if np.sign(T_new[0]) != np.sign(T[0]) and T[0] != 0 else ""
        points.append(CurvePoint(new, note, T_new))
        if direction * (new[0] - origin) < 0:  # folded back past the start of the range
            points[-1].note = "end: the curve leaves the range at its start"
            return points
        X, T = new, T_new
        ds = min(1.5 * ds, max_step)
    points[-1].note = "max_points: the curve has more points than allowed"
    return points
