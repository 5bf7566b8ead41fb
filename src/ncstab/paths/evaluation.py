"""What the engine knows at a batch of states: :class:`Evaluation`.

Every model batch (the diamond's :class:`~ncstab.paths.model.CaseBatch`, the
pure-shear limit's :class:`~ncstab.paths.rigid_model.RigidCaseBatch`, general
models' :class:`~ncstab.paths.model_batch.ModelBatch`) evaluates its cases into
one, with a leading case axis of length B.
"""

from __future__ import annotations

from dataclasses import dataclass, fields

import numpy as np

__all__ = ["Evaluation"]


@dataclass(frozen=True)
class Evaluation:
    """Everything the engine needs at a batch of states.

    The engine integrates *state coordinates* v (B, n): the displacements
    themselves for a deformable system (v = u, du/dv = I, dF/dv = K), or other
    coordinates where constraints hold exactly (the pure-shear limit:
    v = (alpha, Nhat), see :mod:`ncstab.paths.rigid_model`).

    Attributes
    ----------
    q
        Contact variables (l, alpha), ``(B, n_c, 2)``.
    normal, tangential
        Contact forces N, T, ``(B, n_c)``.
    displacements
        Generalized displacements u(v), ``(B, n)``.
    forces
        Generalized forces F(v), ``(B, n)``.
    stiffness
        Tangent operator K (dF = K du), ``(B, n, n)``; NaN where undefined.
    du_dv, dF_dv
        Jacobians of u and F with respect to the state coordinates, ``(B, n, n)``.
    gaps
        Secondary-contact gaps (units of 2R), ``(B, 2)``.
    normal_overlap
        Normal overlap delta of a ``no_tension`` law's contact, ``(B,)``
        (NaN for other laws): its sign change is where the contact opens or
        closes.
    internal_gradient
        d(internal)/du, ``(B, n_internal, n)``, where the fused kernel gave it
        (rate-form laws), else ``None``.
    dF_dload
        dF/dP ``(B, n)`` (= -Q_ext, the load per unit of the load parameter P
        with its sign in F = R(u, P)) for a system with a load parameter, else
        ``None``.
    mass, damping
        M(u) and C ``(B, n, n)`` of a system with inertia, else ``None``.
    interactions
        Per interaction family (in the system's order), its variables
        ``(B, m, k)`` and stored forces ``(B, m, k_f)``, where the batch gives
        them (general models), else ``None`` (the diamond: ``q``, ``normal``,
        ``tangential`` say it all).
    """

    q: np.ndarray
    normal: np.ndarray
    tangential: np.ndarray
    displacements: np.ndarray
    forces: np.ndarray
    stiffness: np.ndarray
    du_dv: np.ndarray
    dF_dv: np.ndarray
    gaps: np.ndarray
    normal_overlap: np.ndarray
    internal_gradient: np.ndarray | None = None
    dF_dload: np.ndarray | None = None
    interactions: tuple[tuple[np.ndarray, np.ndarray], ...] | None = None
    mass: np.ndarray | None = None
    damping: np.ndarray | None = None

    def take(self, index: np.ndarray) -> "Evaluation":
        return Evaluation(*(_take_or_none(getattr(self, f.name), index) for f in fields(self)))

    def put(self, index: np.ndarray, other: "Evaluation") -> None:
        for f in fields(self):
            mine = getattr(self, f.name)
            if f.name == "interactions" and mine is not None:
                for (variables, forces), (other_variables, other_forces) in zip(mine, other.interactions):
                    variables[index], forces[index] = other_variables, other_forces
            elif mine is not None:
                mine[index] = getattr(other, f.name)


def _take_or_none(value, index: np.ndarray):
    if value is None:
        return None
    if isinstance(value, tuple):  # interactions: (variables, forces) per family
        return tuple((variables[index], forces[index]) for variables, forces in value)
    return value[index]
