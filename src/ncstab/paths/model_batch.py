"""A batch of cases of any system definition: forces, tangent, internal rates, gaps.

:class:`ModelBatch` is what the path engine follows for a
:class:`~ncstab.systems.SystemDefinition` (the unreduced diamond, rings,
columns, Ziegler's pendulum, a user's system).  Everything symbolic was
derived once (:func:`ncstab.systems.compile.compile_system` for the
kinematics, :func:`ncstab.symbolic.compile.compile_interaction` for the
laws); here the numeric functions are evaluated on whole arrays and the
generalized forces and the tangent operator assembled family by family
(:func:`ncstab.operators.tangent.assemble_interactions`):

    F = sum_f w_f sum_m J_m^T Q_m  -  P Q_ext(u) + gap springs,
    K = dF/du = sum_f w_f sum_m [J_m^T D_m J_m + sum_a Q_ma H_ma] - P dQ_ext/du + ...

(seed Eq. 5, 9, 16, 30-34 for a contact family; D = dQ/dq along the law).
The seed's reduced diamond has its own fused kernel
(:class:`ncstab.paths.model.CaseBatch`), the same quantities to rounding.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from ncstab.laws.catalogue import no_tension_branches
from ncstab.operators.tangent import assemble_interactions
from ncstab.paths.events import IndicatorLayout
from ncstab.paths.variables import family_fields
from ncstab.paths.evaluation import Evaluation
from ncstab.symbolic.compile import CompiledInteraction, compile_interaction
from ncstab.systems.compile import CompiledSystem, compile_system
from ncstab.systems.definition import SystemDefinition

__all__ = ["ModelBatch", "family_fields"]


@dataclass(frozen=True)
class _FamilyLaw:
    """A family's law (both smooth branches of a no_tension law) and its parameters."""

    branches: tuple[CompiledInteraction, ...]
    values: Mapping[str, np.ndarray]  # non-fixed law parameters, (B,) or scalars


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
    def compiled(self) -> CompiledSystem:
        return compile_system(self.definition)

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

    @functools.cached_property
    def _internal_slices(self) -> list[slice]:
        slices, start = [], 0
        for family, internal in zip(self.definition.families, self._internal):
            width = family.size * len(internal)
            slices.append(slice(start, start + width))
            start += width
        return slices

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
    def take(self, index: np.ndarray) -> "ModelBatch":
        """The sub-batch of cases ``index`` (integer array)."""

        def cut(values: Mapping[str, np.ndarray]) -> dict[str, np.ndarray]:
            return {k: (v[index] if np.ndim(v) else v) for k, v in values.items()}

        kappa = self.kappa[index] if np.ndim(self.kappa) else self.kappa
        return ModelBatch(
            self.definition, self.laws, tuple(cut(v) for v in self.law_values), cut(self.parameters),
            kappa, self.activate_secondary, int(np.size(index)) if np.ndim(index) else 1,
        )

    def _parameter_tuple(self) -> tuple:
        return tuple(self.parameters[p.name] for p in self.definition.parameters)

    @functools.cached_property
    def _family_laws(self) -> list[_FamilyLaw]:
        out = []
        for law, values in zip(self.laws, self.law_values):
            branches = no_tension_branches(law) if getattr(law, "no_tension", False) else (law,)
            out.append(_FamilyLaw(tuple(compile_interaction(b) for b in branches), values))
        return out

    def _law_arguments(self, f: int, fixed: dict[str, np.ndarray]) -> list[np.ndarray]:
        """The law parameters of family f in the law's order: member values ``(B, m)`` or
        the case's value ``(B, 1)``."""
        law, values = self.laws[f], self.law_values[f]
        out = []
        for spec in law.parameters:
            if spec.name in fixed:
                out.append(fixed[spec.name])
            else:
                out.append(np.asarray(values[spec.name], dtype=float).reshape(-1, 1))
        return out

    # --- the state ------------------------------------------------------------------------------
    def initial_state(self) -> np.ndarray:
        """The unloaded state: u = 0, ``(B, n)``."""
        return np.zeros((self.size, self.n_dof))

    def initial_secondary_state(self, u: np.ndarray) -> np.ndarray:
        """Contact-state bits at ``u``: gap g closed (bit 2**g, ``activate`` mode),
        normal contact j of a no_tension law open (bit 2**(gaps + j))."""
        state = np.zeros(u.shape[0], dtype=int)
        parameters = self._parameter_tuple()
        if self.activate_secondary and self.definition.gaps:
            (g,) = self.compiled.gaps(u, parameters, derivatives=False)
            for k in range(g.shape[1]):
                state += (1 << k) * (g[:, k] < 0)
        if self._no_tension_members:
            overlap = self._overlaps(u, parameters)
            offset = len(self.definition.gaps)
            for j in range(overlap.shape[1]):
                state += (1 << (offset + j)) * (overlap[:, j] < 0)
        return state

    def _overlaps(self, u: np.ndarray, parameters: tuple) -> np.ndarray:
        """Normal overlaps of the contacts that can open, ``(B, n_open)``."""
        columns = []
        for f, m in self._no_tension_members:
            cf = self.compiled.families[f]
            q, _, _ = cf.kinematics(u, parameters)
            fixed = cf.member_parameters(parameters, u.shape[0])
            law = self._family_laws[f].branches[0]
            args = self._law_arguments(f, fixed)
            overlap = law.overlap_function(*(q[..., a] for a in range(q.shape[-1])), *args)[..., 0]
            columns.append(np.broadcast_to(overlap, q.shape[:2])[:, m])
        return np.stack(columns, axis=-1) if columns else np.zeros((u.shape[0], 0))

    def close_contact(self, y: np.ndarray, secondary_state: np.ndarray, bits: np.ndarray, layout: object) -> None:
        """A gap or a normal contact crossed zero: toggle its bit, in place."""
        secondary_state ^= bits.astype(int)

    def evaluate(
        self,
        u: np.ndarray,
        internal: np.ndarray,
        secondary_state: np.ndarray | None = None,
        geometry_only: bool = False,
        load: np.ndarray | None = None,
    ) -> Evaluation:
        """Forces, tangent operator, gaps and overlaps at a batch of states.

        ``secondary_state`` (bits, default: from ``u``) is frozen within a
        step: closed gaps carry their springs, open normal contacts follow the
        open branch of their law.  ``load``: the load parameter ``(B,)``
        (0 where not given).  ``geometry_only`` is accepted for the engine's
        protocol; everything is computed.
        """
        size, n = u.shape[0], self.n_dof
        state = self.initial_secondary_state(u) if secondary_state is None else secondary_state
        parameters = self._parameter_tuple()
        compiled = self.compiled
        contributions, interactions, gradients, overlaps = [], [], [], []
        first_contact = None
        open_bit = 1 << len(self.definition.gaps)
        for f, (cf, family_law) in enumerate(zip(compiled.families, self._family_laws)):
            family = cf.family
            q, jacobian, hessian = cf.kinematics(u, parameters)
            args = self._law_arguments(f, cf.member_parameters(parameters, size))
            qs = [q[..., a] for a in range(q.shape[-1])]
            internal_values = internal[:, self._internal_slices[f]].reshape(size, family.size, len(self._internal[f]))
            branch_values = [
                self._law_values(law, qs, internal_values, f, args) for law in family_law.branches
            ]
            if len(branch_values) == 2:
                is_open = np.zeros((size, family.size), dtype=bool)
                for j, (ff, m) in enumerate(self._no_tension_members):
                    if ff == f:
                        is_open[:, m] = (state & (open_bit << j)) > 0
                forces, conjugates, tangent, rate = (
                    np.where(is_open.reshape(size, family.size, *([1] * (closed.ndim - 2))), opened, closed)
                    for closed, opened in zip(*branch_values)
                )
                overlap = family_law.branches[0].overlap_function(*qs, *args)[..., 0]
                overlaps.append(np.broadcast_to(overlap, (size, family.size)))
            else:
                forces, conjugates, tangent, rate = branch_values[0]
            contributions.append((jacobian, hessian, cf.incidence, family.weight, conjugates, tangent))
            interactions.append((q, forces))
            if self._internal[f]:
                rows = rate[:, :, list(self._internal[f]), :]  # (B, m, i, k)
                local = np.einsum("bmik,bmkl->bmil", rows, jacobian)
                width = cf.width
                local = local.reshape(size, family.size, -1, width)
                # scatter (B, m, i, L) -> (B, m * i, n)
                incidence = cf.incidence.reshape(family.size, width, n)
                gradients.append(np.einsum("bmil,mln->bmin", local, incidence).reshape(size, -1, n))
            if family.kind == "contact" and first_contact is None:
                first_contact = (q, forces)
        forces_vector, stiffness = assemble_interactions(contributions, size, n)
        dF_dload = None
        if self.definition.load is not None:
            vector, jacobian = compiled.load(u, parameters)
            load = np.zeros(size) if load is None else np.asarray(load, dtype=float)
            forces_vector = forces_vector - load[:, None] * vector
            stiffness = stiffness - load[:, None, None] * jacobian
            dF_dload = -vector
        gaps = np.zeros((size, 0))
        if self.definition.gaps and not self.activate_secondary:
            (gaps,) = compiled.gaps(u, parameters, derivatives=False)
        elif self.definition.gaps:  # closed gaps carry springs: energy w kappa g^2 / 2
            gaps, gradient, hessian = compiled.gaps(u, parameters)
            weights = np.array([g.weight for g in self.definition.gaps])
            closed = np.stack([(state & (1 << k)) > 0 for k in range(gaps.shape[1])], -1)
            scale = np.where(closed, np.asarray(self.kappa).reshape(-1, 1) * weights, 0.0)
            forces_vector = forces_vector + np.einsum("bg,bg,bgn->bn", scale, gaps, gradient)
            stiffness = stiffness + np.einsum(
                "bg,bgij->bij", scale, gradient[:, :, :, None] * gradient[:, :, None, :] + gaps[:, :, None, None] * hessian
            )
        if first_contact is not None:
            q_contact, contact_forces = first_contact
            normal, tangential = contact_forces[..., 0], contact_forces[..., 1]
        else:
            q_contact, normal, tangential = np.zeros((size, 0, 2)), None, None
        identity = np.broadcast_to(np.eye(n), (size, n, n))
        return Evaluation(
            q=q_contact,
            normal=normal,
            tangential=tangential,
            displacements=u,
            forces=forces_vector,
            stiffness=stiffness,
            du_dv=identity,
            dF_dv=stiffness,
            gaps=gaps,
            normal_overlap=np.concatenate(overlaps, axis=-1) if overlaps else np.zeros((size, 0)),
            internal_gradient=np.concatenate(gradients, axis=1) if gradients else None,
            dF_dload=dF_dload,
            interactions=tuple(interactions),
            mass=compiled.mass(u, parameters),
            damping=compiled.damping(u, parameters),
        )

    def _law_values(
        self, law: CompiledInteraction, qs: list[np.ndarray], internal: np.ndarray, f: int, args: list[np.ndarray]
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(forces (B, m, kf), conjugates (B, m, k), D (B, m, k, k), C (B, m, kf, k)) of a law."""
        shape = qs[0].shape
        k = len(qs)
        totals = np.broadcast_to(law.totals_function(*qs, *args), shape + (len(law.law.force_symbols),)).copy()
        for column, index in enumerate(self._internal[f]):
            totals[..., index] = internal[..., column]
        fs = [totals[..., i] for i in range(totals.shape[-1])]
        conjugates = np.broadcast_to(law.conjugate_function(*qs, *fs), shape + (k,))
        tangent = np.broadcast_to(law.tangent_function(*qs, *fs, *args), shape + (k * k,)).reshape(shape + (k, k))
        rate = np.broadcast_to(law.rate_function(*qs, *fs, *args), shape + (len(fs) * k,)).reshape(shape + (len(fs), k))
        return totals, conjugates, tangent, rate

    def internal_rate(self, evaluation: Evaluation, du: np.ndarray, secondary_state: np.ndarray | None = None) -> np.ndarray:
        """d(internal)/ds along du/ds: df = C dq = C J du for the forces without a total form."""
        if evaluation.internal_gradient is None:
            return np.zeros(du.shape[:-1] + (0,))
        return np.einsum("bkn,bn->bk", evaluation.internal_gradient, du)

    # --- what is stored -----------------------------------------------------------------------
    def record_interactions(self, evaluation: Evaluation) -> dict[str, np.ndarray]:
        """Every family's variables and forces: name -> ``(B,)`` or ``(B, m)``."""
        out = {}
        for (family, names, _), (variables, forces) in zip(family_fields(self.definition), evaluation.interactions):
            values = np.concatenate([variables, forces], axis=-1)
            for a, name in enumerate(names):
                column = values[..., a]
                out[name] = column[:, 0] if family.size == 1 else column
        return out

    def domain_codes(self, evaluation: Evaluation) -> np.ndarray:
        """Per state, -1 inside the domain, else the index of the first violated
        condition in :attr:`domain_reasons` (contacts: l* > 0 and |alpha| < pi/2)."""
        size = evaluation.forces.shape[0]
        checks = []
        for family, (variables, _) in zip(self.definition.families, evaluation.interactions):
            if family.kind == "contact":
                for m in range(family.size):
                    checks += [variables[:, m, 0] > 0, np.abs(variables[:, m, 1]) < np.pi / 2]
        if self.definition.domain:
            values = self.compiled.domain(evaluation.displacements, self._parameter_tuple())
            checks += [values[:, k] > 0 for k in range(values.shape[1])]
        if not checks:
            return np.full(size, -1)
        inside = np.stack(checks, axis=-1)
        first = np.argmin(inside, axis=-1)
        return np.where(inside.all(axis=-1), -1, first + 1)
