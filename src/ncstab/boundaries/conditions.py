"""The extended system of a stability boundary: equilibrium, controls and the event.

A point of a boundary is ``X = (p, u, lam, e)``: the boundary parameter p, the
state u (n dofs), the stage's progress ``lam`` (the load parameter of a
load-parameter stage, else the first driven quantity of the stage) and the
event's extra unknowns e.  :class:`BoundaryProblem` gives the residual
``G(X)``, ``N - 1`` equations for ``N`` unknowns, whose solutions form the
boundary curve:

* the stage's controls, one equation per dof (seed Eq. 4 with the stage's
  mixed control): ``F_i(u, P; p) - F_i*(lam) = 0`` for a dof whose force is
  prescribed (0 for the free dofs of a load-parameter stage), else
  ``u_i - u_i*(lam) = 0``;
* the event condition (BifurcationKit's minimally augmented systems, Govaerts
  2000, ch. 4):

  - ``limit_point``, ``divergence``: ``sigma(K) = 0``, with ``sigma`` from the
    bordered system ``[[K, b], [c^T, 0]] [v; sigma] = [0; 1]`` (sigma = 0 iff
    det K = 0, seed Eq. 36; for ``divergence`` a real root s = 0 of
    ``det(M s^2 + C s + K)``);
  - ``bifurcation``: ``sigma(A) = 0`` with ``A = dG_controls/du`` the Jacobian of
    the stage's equations (a singular point of the stage's path);
  - ``hill_loss``: ``lambda_min(K_sym) = 0`` (Hill's condition);
  - ``flutter_onset``: a pair ``s = +- i omega`` of ``M s^2 + C s + K``, with the
    unknowns ``e = (omega, Re v, Im v)`` and the equations
    ``(K - omega^2 M + i omega C) v = 0`` (2n real) and ``c^H v = 1`` (2 real).
    Without damping (C = 0 at both ends of the range) this condition is
    degenerate: flutter is then a coalescence of two pairs ``s = +- i omega``, a
    double root ``mu = omega^2`` of ``det(K - mu M)`` with a Jordan chain, and
    the unknowns ``e = (omega, v, w)`` (v, w real) solve the defining system of
    a double eigenvalue (Govaerts 2000, ch. 4; Seyranian & Mailybaev 2003)
    ``(K - omega^2 M) v = 0``, ``(K - omega^2 M) w = M v`` (2n) and
    ``c^T v = 1``, ``c^T w = 0`` (2).

R, K, M and C come from the system's compiled evaluators
(:func:`ncstab.paths.api.case_batch`), for a batch of points at once.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ncstab.paths.api import Model, case_batch
from ncstab.paths.programme import CycleStage, LoadingProgramme, Stage

__all__ = ["BOUNDARY_EVENTS", "BoundaryError", "BoundaryProblem", "StageControls", "stage_controls"]

#: The events a boundary can follow.
BOUNDARY_EVENTS = ("limit_point", "hill_loss", "bifurcation", "flutter_onset", "divergence")

#: Events that need the inertia (M, C) of the system.
DYNAMIC_EVENTS = ("flutter_onset", "divergence")


class BoundaryError(ValueError):
    """A boundary that cannot be traced as asked; ``field`` names the offending input."""

    def __init__(self, field_name: str, message: str) -> None:
        self.field = field_name
        super().__init__(f"{field_name}: {message}")


@dataclass(frozen=True)
class StageControls:
    """The controls of the boundary's stage, per dof, as functions of (lam, parameters).

    Attributes
    ----------
    force_controlled
        ``(n,)`` booleans: the dof's force is prescribed (else its displacement).
    load_stage
        The stage drives the load parameter (then ``lam`` is P).
    held_load
        The load parameter's value in a stage that does not drive it.
    prescribed
        Per dof, ``(start, target)`` of a driven quantity or ``(value, None)`` of a
        held one; each entry a number or a parameter name.
    first
        Index of the dof whose quantity is ``lam`` (``None`` in a load stage).
    first_range
        ``(start, target)`` of that quantity.
    """

    force_controlled: tuple[bool, ...]
    load_stage: bool
    held_load: Any
    prescribed: tuple[tuple[Any, Any], ...]
    first: int | None
    first_range: tuple[Any, Any]


def _value(value: Any, parameters: Mapping[str, np.ndarray]) -> np.ndarray | float:
    return parameters[value] if isinstance(value, str) else float(value)


def _value_at_end(stages: tuple, index: int, quantity: str, load: str | None, forces: tuple[str, ...]) -> Any:
    """The value of ``quantity`` where stage ``index`` ends (-1: the unloaded initial state)."""
    if index < 0:
        return 0.0
    stage = stages[index]
    if isinstance(stage, CycleStage):
        raise BoundaryError("loading", f"stage {index + 1} is a cycle: the boundary's stage must start from prescribed values")
    controls = stage.controls()
    if quantity in controls:
        value = controls[quantity]
        return _value_at_end(stages, index - 1, quantity, load, forces) if value == "current" else value
    if load is not None and load in stage.drive and quantity in forces:
        return 0.0  # the free dofs of a load-parameter stage
    if quantity == load:
        return _value_at_end(stages, index - 1, quantity, load, forces)
    raise BoundaryError(
        "loading",
        f"{quantity} at the start of stage {index + 2} depends on the path (no earlier stage prescribes it); "
        "a boundary needs the stage's prescribed values",
    )


def stage_controls(programme: LoadingProgramme, dofs: tuple[str, ...], forces: tuple[str, ...], load: str | None) -> StageControls:
    """The controls of the programme's last stage, with their values resolved (``"current"`` followed back).

    Raises
    ------
    BoundaryError
        The last stage is a cycle, or a value depends on the path.
    """
    stages = tuple(programme.stages)
    last = len(stages) - 1
    stage = stages[last]
    if not isinstance(stage, Stage):
        raise BoundaryError("loading", "the last stage is a cycle: a boundary follows an event of a linear stage")
    controls = stage.controls()
    load_stage = load is not None and load in stage.drive
    held_load = None
    if load is not None and not load_stage:
        held_load = _value_at_end(stages, last, load, load, forces)
    prescribed, flags, first, first_range = [], [], None, (0.0, 1.0)
    driven = [name for name, _ in stage.drives if name != load]
    for i, (dof, force) in enumerate(zip(dofs, forces)):
        name = dof if dof in controls else force
        flags.append(name == force)
        if name not in controls:  # free dof of a load-parameter stage
            prescribed.append((0.0, None))
            continue
        if name in stage.drive:
            # a start value matters only for a proportional drive of several quantities
            start = _value_at_end(stages, last - 1, name, load, forces) if len(driven) > 1 else 0.0
            prescribed.append((start, stage.drive[name]))
            if name == (driven[0] if driven else None) and not load_stage:
                first, first_range = i, (start, stage.drive[name])
        else:
            value = controls[name]
            prescribed.append((_value_at_end(stages, last - 1, name, load, forces) if value == "current" else value, None))
    return StageControls(tuple(flags), load_stage, held_load, tuple(prescribed), first, first_range)


@dataclass
class BoundaryProblem:
    """The residual G(X) of a boundary (see the module docstring) for one case.

    Attributes
    ----------
    model
        The study's model.
    law
        The law of this case.
    parameter
        The boundary parameter p.
    values
        The case's other parameter values (floats).
    controls
        The stage's controls.
    event
        One of :data:`BOUNDARY_EVENTS`.
    borders
        ``(b, c)``, the bordering vectors of ``sigma`` (updated between points).
    normal
        ``c`` of the flutter normalisation ``c^H v = 1`` (complex, ``(n,)``).
    stop
        The other end of the parameter's range (where C is checked to vanish too).
    coalescence
        Flutter without damping: the double-eigenvalue system (module docstring).
    """

    model: Model
    law: Any
    parameter: str
    values: Mapping[str, float]
    controls: StageControls
    event: str
    borders: tuple[np.ndarray, np.ndarray] | None = None
    normal: np.ndarray | None = None
    coalescence: bool = False
    stop: float | None = None
    n: int = field(init=False)

    def __post_init__(self) -> None:
        self.n = len(self.model.definition.dofs)

    @property
    def n_extra(self) -> int:
        """Extra unknowns of the event: ``2n + 1`` for flutter, else 0."""
        return 2 * self.n + 1 if self.event == "flutter_onset" else 0

    @property
    def size(self) -> int:
        """N, the number of unknowns."""
        return 2 + self.n + self.n_extra

    def evaluate(self, X: np.ndarray):
        """The evaluation of the system at the points ``X`` ``(B, N)`` and their controls' targets."""
        size = X.shape[0]
        p, u, lam = X[:, 0], X[:, 1 : 1 + self.n], X[:, 1 + self.n]
        values = {k: np.full(size, float(v)) for k, v in self.values.items()}
        values[self.parameter] = p
        batch = case_batch(self.law, self.model, values, size)
        c = self.controls
        if c.load_stage:
            load = lam
        elif c.held_load is not None:
            load = np.broadcast_to(_value(c.held_load, values), (size,)).astype(float)
        else:
            load = None
        internal = np.zeros((size, batch.n_internal))
        evaluation = batch.evaluate(u, internal, None, load=load)
        fraction = None
        if c.first is not None and sum(t is not None for _, t in c.prescribed) > 1:
            s1, t1 = (_value(v, values) for v in c.first_range)
            fraction = (lam - s1) / (t1 - s1)
        targets = np.empty((size, self.n))
        for i, (start, target) in enumerate(c.prescribed):
            start_value = np.broadcast_to(_value(start, values), (size,))
            if target is None:
                targets[:, i] = start_value
            elif i == c.first:
                targets[:, i] = lam
            else:
                targets[:, i] = start_value + fraction * (_value(target, values) - start_value)
        return evaluation, targets

    def control_jacobian(self, evaluation) -> np.ndarray:
        """A = d(controls)/du ``(B, n, n)``: rows of K for force-controlled dofs, of I otherwise."""
        flags = np.asarray(self.controls.force_controlled)
        identity = np.broadcast_to(np.eye(self.n), evaluation.stiffness.shape)
        return np.where(flags[None, :, None], evaluation.stiffness, identity)

    def residual(self, X: np.ndarray) -> np.ndarray:
        """G(X) ``(B, N - 1)`` at the points ``X`` ``(B, N)``."""
        X = np.atleast_2d(X)
        evaluation, targets = self.evaluate(X)
        u = X[:, 1 : 1 + self.n]
        actual = np.where(np.asarray(self.controls.force_controlled)[None, :], evaluation.forces, u)
        parts = [actual - targets]
        K = evaluation.stiffness
        if self.event in ("limit_point", "divergence"):
            parts.append(self._sigma(K)[:, None])
        elif self.event == "bifurcation":
            parts.append(self._sigma(self.control_jacobian(evaluation))[:, None])
        elif self.event == "hill_loss":
            parts.append(np.linalg.eigvalsh(0.5 * (K + np.swapaxes(K, -1, -2)))[:, :1])
        else:
            parts.append(self._flutter(X, K, evaluation.mass, evaluation.damping))
        return np.concatenate(parts, axis=1)

    def _sigma(self, A: np.ndarray) -> np.ndarray:
        """sigma of the bordered system ``[[A, b], [c^T, 0]] [v; sigma] = [0; 1]`` ``(B,)``."""
        b, c = self.borders
        size, n = A.shape[0], self.n
        bordered = np.zeros((size, n + 1, n + 1))
        bordered[:, :n, :n] = A
        bordered[:, :n, n] = b
        bordered[:, n, :n] = c
        rhs = np.zeros((size, n + 1))
        rhs[:, n] = 1.0
        return np.linalg.solve(bordered, rhs[..., None])[:, n, 0]

    def _flutter(self, X: np.ndarray, K: np.ndarray, M: np.ndarray, C: np.ndarray | None) -> np.ndarray:
        """Re, Im of ``(K - omega^2 M + i omega C) v`` and of ``c^H v - 1`` ``(B, 2n + 2)``.

        With :attr:`coalescence`, ``(K - omega^2 M) v``, ``(K - omega^2 M) w - M v``,
        ``c^T v - 1`` and ``c^T w`` (v, w real: the slots of Re v and Im v).
        """
        n = self.n
        omega = X[:, 2 + n]
        if self.coalescence:
            v, w = X[:, 3 + n : 3 + 2 * n], X[:, 3 + 2 * n : 3 + 3 * n]
            pencil = K - omega[:, None, None] ** 2 * M
            c = self.normal.real
            return np.concatenate([
                np.einsum("bij,bj->bi", pencil, v),
                np.einsum("bij,bj->bi", pencil, w) - np.einsum("bij,bj->bi", M, v),
                (v @ c - 1.0)[:, None], (w @ c)[:, None],
            ], axis=1)
        v = X[:, 3 + n : 3 + 2 * n] + 1j * X[:, 3 + 2 * n : 3 + 3 * n]
        C = np.zeros_like(K) if C is None else C
        pencil = K - omega[:, None, None] ** 2 * M + 1j * omega[:, None, None] * C
        product = np.einsum("bij,bj->bi", pencil, v)
        normal = np.einsum("i,bi->b", np.conj(self.normal), v) - 1.0
        return np.concatenate([product.real, product.imag, normal.real[:, None], normal.imag[:, None]], axis=1)

    def update(self, X: np.ndarray) -> None:
        """New borders (the null vectors of the singular matrix) or flutter normal at an accepted point."""
        if self.event == "flutter_onset":
            n = self.n
            if self.coalescence:  # v alone: w is the Jordan vector
                v = X[3 + n : 3 + 2 * n].astype(complex)
            else:
                v = X[3 + n : 3 + 2 * n] + 1j * X[3 + 2 * n : 3 + 3 * n]
            self.normal = v / np.vdot(v, v).real
            return
        if self.event in ("limit_point", "divergence", "bifurcation"):
            evaluation, _ = self.evaluate(X[None, :])
            A = self.control_jacobian(evaluation)[0] if self.event == "bifurcation" else evaluation.stiffness[0]
            left, _, right = np.linalg.svd(A)
            self.borders = (left[:, -1], right[-1])
