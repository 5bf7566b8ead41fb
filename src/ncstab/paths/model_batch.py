"""A batch of cases of any system definition: forces, tangent, internal rates, gaps.

:class:`ModelBatch` is what the path engine follows for a
:class:`~ncstab.systems.SystemDefinition` (the unreduced diamond, rings,
columns, Ziegler's pendulum, a user's system).  Its forces, tangent
operator, internal rates, gaps and loads come from the model's compiled
kernel (:mod:`ncstab.operators.model_kernel`: printed once from the system's and
the laws' symbolic definitions, compiled with numba and cached on disk),
which assembles member by member (:mod:`ncstab.operators.model_assembly`):

    F = sum_f w_f sum_m J_m^T Q_m  -  P Q_ext(u) + gap springs,
    K = dF/du = sum_f w_f sum_m [J_m^T D_m J_m + sum_a Q_ma H_ma] - P dQ_ext/du + ...

(seed Eq. 5, 9, 16, 30-34 for a contact family; D = dQ/dq along the law).
The seed's reduced diamond has its own fused kernel
(:class:`ncstab.paths.model.CaseBatch`), the same quantities to rounding.
The kernel's row also holds M(u), C(u) and the domain code.
"""

from __future__ import annotations

import functools
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ncstab.operators.model_kernel import ModelKernel, model_kernel
from ncstab.paths.evaluation import Evaluation
from ncstab.paths.events import IndicatorLayout
from ncstab.paths.variables import family_fields
from ncstab.systems.definition import SystemDefinition

__all__ = ["ModelBatch", "family_fields"]


@dataclass(frozen=True)
class ModelBatch:
    """B cases of one model: a system definition, its laws and parameter values.

    Attributes
    ----------
    definition
        The system.
    laws
        One law per family, in the system's order (a family's own law, or the
        model's law for the families of its kind).
    law_values
        Per family, the values of its law's parameters that the geometry does
        not fix (``gamma``), each ``(B,)`` or a scalar.
    parameters
        The system's parameters, each ``(B,)`` or a scalar.
    kappa
        Stiffness ratio of the secondary-contact springs, ``(B,)``.
    activate_secondary
        Whether closed gaps carry springs (``"activate"`` mode).
    size
        B.
    """

    definition: SystemDefinition
    laws: tuple[Any, ...]
    law_values: tuple[Mapping[str, np.ndarray], ...]
    parameters: Mapping[str, np.ndarray]
    kappa: np.ndarray
    activate_secondary: bool
    size: int

    # --- what the engine reads ----------------------------------------------------------------
    @property
    def dof_names(self) -> tuple[str, ...]:
        return self.definition.dofs

    @property
    def force_names(self) -> tuple[str, ...]:
        return self.definition.forces

    @property
    def n_dof(self) -> int:
        return self.definition.n_dof

    @property
    def has_load(self) -> bool:
        return self.definition.load is not None

    @property
    def load_parameter(self) -> str | None:
        return self.definition.load_parameter

    @property
    def work_factor(self) -> float:
        return self.definition.work_factor

    @property
    def has_total_form(self) -> bool:
        return all(all(t is not None for t in law.force_totals) for law in self.laws)

    @functools.cached_property
    def _internal(self) -> list[tuple[int, ...]]:
        """Per family, the indices of its forces that are internal variables."""
        return [tuple(i for i, t in enumerate(law.force_totals) if t is None) for law in self.laws]

    @property
    def n_internal(self) -> int:
        return sum(f.size * len(i) for f, i in zip(self.definition.families, self._internal))

    @functools.cached_property
    def _no_tension_members(self) -> list[tuple[int, int]]:
        """(family, member) of every normal contact that can open, in bit order."""
        return [
            (f, m)
            for f, (family, law) in enumerate(zip(self.definition.families, self.laws))
            if getattr(law, "no_tension", False)
            for m in range(family.size)
        ]

    @property
    def columns(self) -> IndicatorLayout:
        return IndicatorLayout(
            gaps=len(self.definition.gaps), normal_contacts=len(self._no_tension_members), general=True
        )

    @property
    def gap_bits(self) -> int:
        return (1 << len(self.definition.gaps)) - 1

    closed_gap_hint = " (secondary-contact springs already act at this state)"

    @functools.cached_property
    def interaction_shapes(self) -> dict[str, tuple[int, ...]]:
        return {
            name: (() if family.size == 1 else (family.size,))
            for family, names, _ in family_fields(self.definition)
            for name in names
        }

    @functools.cached_property
    def domain_reasons(self) -> tuple[str, ...]:
        reasons = ["non-finite numbers"]
        for family in self.definition.families:
            if family.kind == "contact":
                for member in family.members:
                    reasons += [f"l* <= 0 at contact {member}", f"alpha outside (-pi/2, pi/2) at contact {member}"]
        reasons += [condition.reason for condition in self.definition.domain]
        return tuple(reasons)

    # --- sub-batches --------------------------------------------------------------------------
    def take(self, index: np.ndarray) -> ModelBatch:
        """The sub-batch of cases ``index`` (integer array)."""

        def cut(values: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
            return {k: (v[index] if np.ndim(v) else v) for k, v in values.items()}

        kappa = self.kappa[index] if np.ndim(self.kappa) else self.kappa
        part = ModelBatch(
            self.definition, self.laws, tuple(cut(v) for v in self.law_values), cut(self.parameters),
            kappa, self.activate_secondary, int(np.size(index)) if np.ndim(index) else 1,
        )
        part.__dict__["_kernel"] = self._kernel  # the same model: no lookup (hashing its expressions)
        if "_rows" in self.__dict__:
            part.__dict__["_rows"] = self._rows[np.atleast_1d(index)]
        return part

    # --- the state ------------------------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        """The unloaded state: u = 0, ``(B, n)``."""
        return np.zeros((self.size, self.n_dof))

    def initial_secondary_state(self, u: np.ndarray) -> np.ndarray:
        """Contact-state bits at ``u``: gap g closed (bit 2**g, ``activate`` mode),
        normal contact j of a no_tension law open (bit 2**(gaps + j))."""
        state = np.zeros(u.shape[0], dtype=int)
        layout = self._kernel.layout
        watched = (self.activate_secondary and layout.n_gaps) or layout.n_open
        if not watched:
            return state
        internal = np.zeros((u.shape[0], layout.n_internal))
        out = self._kernel.evaluate(u, internal, 0.0, state, self._rows)
        if self.activate_secondary:
            for k in range(layout.n_gaps):
                state += (1 << k) * (out[:, layout.gaps + k] < 0)
        for j in range(layout.n_open):
            state += (1 << (layout.n_gaps + j)) * (out[:, layout.overlaps + j] < 0)
        return state

    @functools.cached_property
    def _kernel(self) -> ModelKernel:
        # kept on the batch: looking it up hashes the definition's sympy expressions
        return model_kernel(self.definition, self.laws, self.activate_secondary)

    def __getstate__(self) -> dict:
        # the kernel holds a compiled module: a batch pickles without it (dask workers)
        state = dict(self.__dict__)
        state.pop("_kernel", None)
        return state

    @functools.cached_property
    def _rows(self) -> np.ndarray:
        """Each case's parameter row of the compiled kernel (:meth:`ModelKernel.parameter_rows`)."""
        return self._kernel.parameter_rows(self.parameters, self.law_values, self.kappa, self.size)

    def evaluate(
        self,
        u: np.ndarray,
        internal: np.ndarray,
        secondary_state: np.ndarray | None = None,
        geometry_only: bool = False,
        load: np.ndarray | None = None,
    ) -> Evaluation:
        """Forces, tangent operator, gaps and overlaps at a batch of states, from the
        model's compiled kernel (:mod:`ncstab.operators.model_kernel`).

        ``secondary_state`` (bits, default: from ``u``) is frozen within a
        step: closed gaps carry their springs, open normal contacts follow the
        open branch of their law.  ``load``: the load parameter ``(B,)``
        (0 where not given).  ``geometry_only`` is accepted for the engine's
        protocol; everything is computed.
        """
        size, n = u.shape[0], self.n_dof
        state = self.initial_secondary_state(u) if secondary_state is None else secondary_state
        layout = self._kernel.layout
        out = self._kernel.evaluate(u, internal, 0.0 if load is None else load, state, self._rows)

        def block(start: int, *shape: int) -> np.ndarray:
            return out[:, start : start + int(np.prod(shape))].reshape(size, *shape)

        stiffness = block(layout.stiffness, n, n)
        interactions = tuple(
            (block(q_at, m, k), block(f_at, m, kf))
            for (q_at, f_at), (m, k, kf) in zip(layout.interactions, layout.family_shapes)
        )
        contacts = [i for i, family in enumerate(self.definition.families) if family.kind == "contact"]
        if contacts:
            q_contact, contact_forces = interactions[contacts[0]]
            normal, tangential = contact_forces[..., 0], contact_forces[..., 1]
        else:
            q_contact, normal, tangential = np.zeros((size, 0, 2)), None, None
        return Evaluation(
            q=q_contact,
            normal=normal,
            tangential=tangential,
            displacements=u,
            forces=block(layout.forces, n),
            stiffness=stiffness,
            du_dv=np.broadcast_to(np.eye(n), (size, n, n)),
            dF_dv=stiffness,
            gaps=block(layout.gaps, layout.n_gaps),
            normal_overlap=block(layout.overlaps, layout.n_open),
            internal_gradient=block(layout.gradient, layout.n_internal, n) if layout.n_internal else None,
            dF_dload=block(layout.load, n) if self.has_load else None,
            interactions=interactions,
            mass=block(layout.mass, n, n) if layout.inertia[0] else None,
            damping=block(layout.damping, n, n) if layout.inertia[1] else None,
        )
