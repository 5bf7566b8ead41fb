"""The equations of motion of one case as a first-order system, with its energy balance.

With the free dofs f (their forces held) and the held dofs d (u_d fixed), the
motion of Eq. (1) of :mod:`ncstab.dynamics.stage` is, by Lagrange's equations
with the kinetic energy T = u'^T M(u) u' / 2,

    M_ff(u) u_f'' = F_f - R_f(u, lambda, z) - (C u')_f - Gamma_f(u, u'),      (2)
    Gamma_i = sum_jk (dM_ij/du_k - 1/2 dM_jk/du_i) u_j' u_k'                   (3)

(Gamma, the Christoffel terms, vanish for a constant M such as the grains' and
on linearisation: the linearised dynamics stay M s^2 + C s + K), with the
internal variables z of rate-form laws integrated along the motion,

    z' = (dz/du) u'                                                            (4)

(the law's rates, the same rows the path engine integrates along a path), and
three works integrated as further states (w the system's ``work_factor``):

    W_ext'  = w (F + lambda Q_ext(u)) . u'     controls and loads, followers included
    W_int'  = w R_int(u, z) . u'               interactions, R_int = R + lambda Q_ext
    W_diss' = w u'^T C u'                      dashpots                             (5)

Since u'^T Gamma = u'^T M' u' / 2 (Eq. 3), d(w T)/dt = W_ext' - W_int' - W_diss'
holds exactly along Eq. (2): the kinetic energy w T equals W_ext - W_int - W_diss
at every time, to the integrator's tolerance.  R, K, M(u), C, Q_ext and dz/du
come from the model's compiled kernel (:mod:`ncstab.operators.model_kernel`),
dM/du from the system's symbolic mass matrix, derived once per system.
"""

from __future__ import annotations

import functools
from typing import Any

import numpy as np
import sympy as sp

from ncstab.paths.model_batch import ModelBatch
from ncstab.systems.definition import SystemDefinition

__all__ = ["MotionEquations", "mass_derivative"]


@functools.cache
def mass_derivative(definition: SystemDefinition) -> Any:
    """``(u, parameters) -> dM/du`` ``(n, n, n)`` (entry [i, j, k] = dM_ij/du_k), derived once
    per system; ``None`` where M does not depend on u (the grains' M = I)."""
    if definition.mass is None:
        return None
    dofs = definition.dof_symbols
    entries = [sp.diff(e, u) for row in definition.mass for e in row for u in dofs]
    if all(e == 0 for e in entries):
        return None
    arguments = list(dofs) + [p.symbol for p in definition.parameters]
    function = sp.lambdify(arguments, entries, modules="math", cse=True)
    n = definition.n_dof

    def evaluate(u: np.ndarray, parameters: tuple[float, ...]) -> np.ndarray:
        return np.asarray(function(*u, *parameters), dtype=float).reshape(n, n, n)

    return evaluate


class MotionEquations:
    """The right-hand side of Eq. (2), (4), (5) for one case (a one-case :class:`ModelBatch`).

    The state is ``y = [u_f, u_f', z, W_ext, W_int, W_diss]``.

    Parameters
    ----------
    batch
        The case (``size == 1``).
    free
        ``(n,)`` bool: the dofs whose force is held (the others' displacement is).
    forces
        ``(n,)`` the held forces F (read on the free dofs).
    load
        The held load parameter lambda (0 for a system without one).
    start
        ``(n,)`` the displacements at the stage's start, perturbation included
        (the held dofs stay there).
    """

    def __init__(self, batch: ModelBatch, free: np.ndarray, forces: np.ndarray, load: float, start: np.ndarray) -> None:
        self.batch = batch
        self.kernel = batch._kernel
        self.layout = self.kernel.layout
        self.rows = batch._rows
        self.n = batch.n_dof
        self.free = np.asarray(free, dtype=bool)
        self.m = int(self.free.sum())
        self.n_internal = self.layout.n_internal
        self.forces = np.where(self.free, np.asarray(forces, dtype=float), 0.0)
        self.load = float(load)
        self.start = np.asarray(start, dtype=float).copy()
        self.work_factor = batch.work_factor
        definition = batch.definition
        self.parameters = tuple(float(np.asarray(batch.parameters[p.name]).reshape(-1)[0]) for p in definition.parameters)
        self.dmass = mass_derivative(definition)
        self.watch_gaps = bool((batch.activate_secondary and self.layout.n_gaps) or self.layout.n_open)
        self.evaluations = 0
        #: Whether the integrator asked for the right-hand side outside the admissible domain.
        self.left_domain = False

    # --- the state vector -------------------------------------------------------------------------
    def initial_state(self, internal: np.ndarray) -> np.ndarray:
        """y at t = 0: the starting displacements, zero velocity, ``internal`` z, zero works."""
        y = np.zeros(2 * self.m + self.n_internal + 3)
        y[: self.m] = self.start[self.free]
        y[2 * self.m : 2 * self.m + self.n_internal] = np.asarray(internal, dtype=float).reshape(-1)
        return y

    def split(self, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(u, u', z, works) of states ``y`` ``(..., size)``: ``(..., n)``, ``(..., n)``, ``(..., n_internal)``, ``(..., 3)``."""
        y = np.asarray(y, dtype=float)
        u = np.broadcast_to(self.start, y.shape[:-1] + (self.n,)).copy()
        velocity = np.zeros(y.shape[:-1] + (self.n,))
        u[..., self.free] = y[..., : self.m]
        velocity[..., self.free] = y[..., self.m : 2 * self.m]
        internal = y[..., 2 * self.m : 2 * self.m + self.n_internal]
        return u, velocity, internal, y[..., -3:]

    # --- the kernel -------------------------------------------------------------------------------
    def evaluate(self, u: np.ndarray, internal: np.ndarray) -> np.ndarray:
        """The kernel's row at one state (:class:`~ncstab.operators.model_kernel_layout.KernelLayout`)."""
        u2 = u.reshape(1, self.n)
        z2 = internal.reshape(1, self.n_internal)
        state = self.batch.initial_secondary_state(u2) if self.watch_gaps else np.zeros(1, dtype=np.int64)
        self.evaluations += 1
        return self.kernel.evaluate(u2, z2, np.array([self.load]), state, self.rows)[0]

    def _block(self, row: np.ndarray, start: int, *shape: int) -> np.ndarray:
        return row[start : start + int(np.prod(shape))].reshape(shape)

    def mass(self, row: np.ndarray) -> np.ndarray:
        return self._block(row, self.layout.mass, self.n, self.n)

    def damping(self, row: np.ndarray) -> np.ndarray:
        if not self.layout.inertia[1]:
            return np.zeros((self.n, self.n))
        return self._block(row, self.layout.damping, self.n, self.n)

    def inside(self, row: np.ndarray) -> bool:
        """Whether the state is in the model's admissible domain (and its row finite)."""
        return bool(row[self.layout.domain] < 0) and bool(np.isfinite(row).all())

    def christoffel(self, u: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """Gamma(u, u') of Eq. (3), ``(n,)``."""
        if self.dmass is None:
            return np.zeros(self.n)
        d = self.dmass(u, self.parameters)
        return np.einsum("ijk,j,k->i", d, velocity, velocity) - 0.5 * np.einsum("jki,j,k->i", d, velocity, velocity)

    # --- the right-hand side ----------------------------------------------------------------------
    def __call__(self, t: float, y: np.ndarray) -> np.ndarray:
        """y' of Eq. (2), (4), (5); NaN outside the admissible domain (the integrator then stops)."""
        u, velocity, internal, _ = self.split(y)
        row = self.evaluate(u, internal)
        out = np.empty_like(y)
        if not self.inside(row):
            self.left_domain = True
            out[:] = np.nan
            return out
        layout = self.layout
        residual = row[layout.forces : layout.forces + self.n]
        per_load = row[layout.load : layout.load + self.n]  # dR/dlambda = -Q_ext
        mass, damping = self.mass(row), self.damping(row)
        damping_force = damping @ velocity
        rhs = self.forces - residual - damping_force - self.christoffel(u, velocity)
        free = self.free
        acceleration = np.linalg.solve(mass[np.ix_(free, free)], rhs[free])
        m, k = self.m, self.n_internal
        out[:m] = velocity[free]
        out[m : 2 * m] = acceleration
        if k:
            gradient = self._block(row, layout.gradient, k, self.n)
            out[2 * m : 2 * m + k] = gradient @ velocity
        w = self.work_factor
        out[-3] = w * (self.forces - self.load * per_load) @ velocity
        out[-2] = w * (residual - self.load * per_load) @ velocity
        out[-1] = w * velocity @ damping_force
        return out

    def kinetic_energy(self, u: np.ndarray, velocity: np.ndarray, internal: np.ndarray) -> float:
        """w u'^T M(u) u' / 2 at one state."""
        return self.kinetic_energy_of_row(self.evaluate(u, internal), velocity)

    def kinetic_energy_of_row(self, row: np.ndarray, velocity: np.ndarray) -> float:
        """w u'^T M(u) u' / 2 with M(u) from the kernel's row at u."""
        return 0.5 * self.work_factor * float(velocity @ self.mass(row) @ velocity)
