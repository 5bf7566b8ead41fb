"""A batch of cases of one law on one system: forces, tangents, internal rates.

Every array has a leading case axis of length B; parameters are arrays of
shape (B,).  The engine never loops over cases: it evaluates a ``CaseBatch`` (or
a subset taken with :meth:`CaseBatch.take`) on whole arrays.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ncstab.laws.catalogue import no_tension_branches
from ncstab.paths.evaluation import Evaluation
from ncstab.paths.events import DIAMOND_COLUMNS, IndicatorLayout
from ncstab.laws.registry import Law
from ncstab.operators.tangent import compile_state_kernel, tangent_operator_at_contact_state
from ncstab.symbolic.compile import CompiledLaw, compile_law
from ncstab.systems.protocol import DiscreteSystem

__all__ = ["CaseBatch", "DOMAIN_REASONS", "DiamondBatchTraits", "Evaluation", "NORMAL_OPEN"]

#: Bit of the contact state: the normal contact of a no_tension law is open.
NORMAL_OPEN = 4
#: Why a state of the diamond is outside the admissible domain (checked in this order).
DOMAIN_REASONS = ("non-finite numbers", "l* <= 0", "alpha outside (-pi/2, pi/2)")


#: Rows of the packed array of a fused evaluation (see ``CaseBatch._evaluate_fused``).
_L, _ALPHA, _N, _T, _F, _K, _GAPS, _GRAD = 0, 1, 2, 3, slice(4, 6), slice(6, 10), slice(10, 12), slice(12, 14)
_PACKED = 14
#: Packed row of each output of the kernel (N, T, F, K, then d(internal)/du).
_KERNEL_ROWS = (2, 3, 4, 5, 6, 7, 8, 9, 12, 13)


def _take_parameters(parameters: dict[str, np.ndarray], index: np.ndarray) -> dict[str, np.ndarray]:
    return {k: (v[index] if np.ndim(v) else v) for k, v in parameters.items()}


class DiamondBatchTraits:
    """What the engine reads of a batch of the seed's reduced diamond (fused kernel or
    pure-shear limit): its names, indicator columns, stored fields and domain."""

    dof_names = ("D1", "D2")
    force_names = ("F1", "F2")
    #: Indicator columns: two gaps (top-bottom, left-right), one normal contact.
    columns: IndicatorLayout = DIAMOND_COLUMNS
    #: The recorded work is the work per contact, F . du / 2 (seed Eq. 5).
    work_factor = 0.5
    has_load = False
    load_parameter: str | None = None
    #: Contact-state bits of the secondary contacts.
    gap_bits = 3
    closed_gap_hint = (
        " (secondary-contact springs already act at this state: with "
        "secondary_contacts = 'activate' the grains overlap at rest unless "
        "alpha0 is in [pi/6, pi/3])"
    )
    #: Stored interaction fields: one contact standing for the four.
    interaction_shapes = {"l": (), "alpha": (), "N": (), "T": ()}
    domain_reasons = DOMAIN_REASONS


@dataclass(frozen=True)
class CaseBatch(DiamondBatchTraits):
    """B cases of one law on one system.

    Attributes
    ----------
    system
        A system whose parameters have shape (B,) (or are scalars).
    law
        A law whose parameters have shape (B,) (or are scalars).
    kappa
        Stiffness ratio of the secondary-contact springs, ``(B,)``.
    activate_secondary
        Whether the secondary-contact springs act (``"activate"`` mode).
    """

    system: DiscreteSystem
    law: Law
    kappa: np.ndarray
    activate_secondary: bool

    @property
    def compiled(self) -> CompiledLaw:
        return compile_law(self.law.definition)

    @property
    def n_dof(self) -> int:
        return self.system.n_dof

    @property
    def has_total_form(self) -> bool:
        """Whether forces are functions of the state (Newton projection applies)."""
        return self.law.has_total_form

    @property
    def n_internal(self) -> int:
        """Internal variables per case: T per contact for a rate-form law, else 0."""
        return 0 if self.law.has_total_form else self.system.n_contacts

    @property
    def size(self) -> int:
        shapes = [np.shape(v) for v in self.law.parameters.values()]
        shapes += [np.shape(v) for v in self.system.parameters.values()] + [np.shape(self.kappa)]
        return int(np.prod(np.broadcast_shapes(*shapes)))

    def take(self, index: np.ndarray) -> "CaseBatch":
        """The sub-batch of cases ``index`` (integer array)."""
        law = Law(self.law.definition, _take_parameters(dict(self.law.parameters), index))
        system_parameters = _take_parameters(dict(self.system.parameters), index)
        system = type(self.system)(**system_parameters)
        kappa = self.kappa[index] if np.ndim(self.kappa) else self.kappa
        return CaseBatch(system, law, kappa, self.activate_secondary)

    def contact_state(
        self, u: np.ndarray, internal: np.ndarray, law: Law | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, N, T) at displacements ``u`` (B, n) and internal variables (B, n_internal)."""
        law = self.law if law is None else law
        q = self.system.contact_variables(u)
        compiled = compile_law(law.definition)
        contacts = range(self.system.n_contacts)
        normal = np.stack([compiled.normal_force(law, q[:, c, 0], q[:, c, 1]) for c in contacts], -1)
        if law.has_total_form:
            tangential = np.stack(
                [compiled.tangential_force(law, q[:, c, 0], q[:, c, 1]) for c in contacts], -1
            )
        else:
            tangential = internal
        return q, normal, tangential

    def _branch_laws(self) -> tuple[Law, Law]:
        """(closed, open) smooth branches of a no_tension law, same parameters."""
        closed, opened = no_tension_branches(self.law.definition)
        return Law(closed, self.law.parameters), Law(opened, self.law.parameters)

    def _normal_open(self, u: np.ndarray, secondary_state: np.ndarray | None) -> np.ndarray:
        if secondary_state is None:
            return self.initial_secondary_state(u) & NORMAL_OPEN > 0
        return (secondary_state & NORMAL_OPEN) > 0

    def _overlap(self, q: np.ndarray) -> np.ndarray:
        if not self.law.definition.no_tension:
            return np.full(q.shape[0], np.nan)
        return self.compiled.normal_overlap(self.law, q[:, 0, 0], q[:, 0, 1])

    @property
    def force_unit(self) -> str:
        return "2R k_n"

    def initial_state(self) -> np.ndarray:
        """State coordinates of the unloaded state: u = 0, ``(B, n)``."""
        return np.zeros((self.size, self.n_dof))

    def initial_secondary_state(self, u: np.ndarray) -> np.ndarray:
        """Contact state bits at ``u``: bit 0 top-bottom and bit 1 left-right springs
        compressed (``activate`` mode), bit 2 (:data:`NORMAL_OPEN`) the normal
        contact of a ``no_tension`` law open (delta < 0)."""
        state = np.zeros(u.shape[0], dtype=int)
        if self.activate_secondary:
            overlap = 1.0 - 2.0 * np.stack(
                [np.cos(self.system.parameters["alpha0"]) - u[:, 0], np.sin(self.system.parameters["alpha0"]) - u[:, 1]],
                -1,
            ) * np.ones((u.shape[0], 1))
            state += (overlap[:, 0] > 0).astype(int) + 2 * (overlap[:, 1] > 0).astype(int)
        if self.law.definition.no_tension:
            state += NORMAL_OPEN * (self._overlap(self.system.contact_variables(u)) < 0)
        return state

    @functools.cached_property
    def _kernels(self) -> tuple | None:
        """Fused state kernels (one per smooth branch) where the system has
        symbolic kinematics and one contact family, else ``None``."""
        if not hasattr(type(self.system), "symbolic_kinematics") or self.system.n_contacts != 1:
            return None
        definitions = (
            no_tension_branches(self.law.definition) if self.law.definition.no_tension else (self.law.definition,)
        )
        return tuple(compile_state_kernel(type(self.system), d) for d in definitions)

    @functools.cached_property
    def _alpha0_trig(self) -> tuple[np.ndarray, np.ndarray]:
        alpha0 = self.system.parameters["alpha0"]
        return np.cos(alpha0), np.sin(alpha0)

    def _evaluate_fused(
        self, u: np.ndarray, internal: np.ndarray, secondary_state: np.ndarray | None, geometry_only: bool = False
    ) -> Evaluation:
        """:meth:`evaluate` through the fused kernel (the same quantities as the
        general assembly, to rounding).

        Everything is computed on contiguous ``(B,)`` rows of one packed
        ``(14, B)`` array; the fields of the :class:`Evaluation` are transposed
        views of it, so every entry ``K[:, i, j]`` the engine reads is contiguous.
        """
        size = u.shape[0]
        cos0, sin0 = self._alpha0_trig
        vertical = cos0 - u[:, 0]
        horizontal = sin0 - u[:, 1]
        packed = np.empty((_PACKED, size))
        length, alpha = packed[_L], packed[_ALPHA]
        np.sqrt(vertical * vertical + horizontal * horizontal, out=length)
        np.arctan2(horizontal, vertical, out=alpha)  # within a rounding of the loop's (docs/paths.md: alpha at stage entry)
        cos_a, sin_a = vertical / length, horizontal / length
        t_in = internal[:, 0] if internal.shape[-1] else 0.0
        parameters = self.law.parameter_values()
        rate_form = not self.law.has_total_form
        rows = _KERNEL_ROWS[: 10 if rate_form else 8]
        kernels = self._kernels
        if geometry_only:
            packed[_N:_GAPS.start] = np.nan
            packed[_GRAD] = np.nan
        elif len(kernels) == 1:
            for row, value in zip(rows, kernels[0](length, alpha, cos_a, sin_a, t_in, *parameters)):
                packed[row] = value
        else:
            is_open = self._normal_open(u, secondary_state)
            branches = [kernel(length, alpha, cos_a, sin_a, t_in, *parameters) for kernel in kernels]
            for k, row in enumerate(rows):
                np.copyto(packed[row], np.where(is_open, branches[1][k], branches[0][k]))
        np.multiply(vertical, 2, out=packed[_GAPS.start])
        packed[_GAPS.start] -= 1
        np.multiply(horizontal, 2, out=packed[_GAPS.start + 1])
        packed[_GAPS.start + 1] -= 1
        if self.activate_secondary and not geometry_only:
            state = self.initial_secondary_state(u) if secondary_state is None else secondary_state
            kappa = np.asarray(self.kappa)
            for bit, dof, distance in ((1, 0, vertical), (2, 1, horizontal)):
                active = (state & bit) > 0
                packed[_F.start + dof] += kappa * np.where(active, 1.0 - 2.0 * distance, 0.0)
                packed[_K.start + 3 * dof] += 2.0 * kappa * active
        if self.law.definition.no_tension:
            overlap = self.compiled.normal_overlap(self.law, length, alpha)
        else:
            overlap = np.full(size, np.nan)
        stiffness = packed[_K].T.reshape(size, 2, 2)
        return Evaluation(
            packed[_L:_ALPHA + 1].T.reshape(size, 1, 2),
            packed[_N:_N + 1].T,
            packed[_T:_T + 1].T,
            u,
            packed[_F].T,
            stiffness,
            np.broadcast_to(np.eye(2), (size, 2, 2)),
            stiffness,
            packed[_GAPS].T,
            overlap,
            packed[_GRAD].T.reshape(size, 1, 2) if rate_form else None,
        )

    def evaluate(
        self,
        u: np.ndarray,
        internal: np.ndarray,
        secondary_state: np.ndarray | None = None,
        geometry_only: bool = False,
        load: np.ndarray | None = None,
    ) -> Evaluation:
        """Forces (seed Eq. 4) and tangent operator (Eq. 30-34) at a batch of states.

        The state coordinates are the displacements.  ``secondary_state`` says
        which secondary springs act (bits; default: those compressed at ``u``):
        within a step the set is frozen, so the field is smooth; the engine
        switches it where a gap crossing is located.  ``geometry_only``: the
        caller needs q, the gaps and the overlap only; forces, K and the
        internal gradient may then be NaN (they are where the fused kernel
        applies).
        """
        if self._kernels is not None:
            return self._evaluate_fused(u, internal, secondary_state, geometry_only)
        if self.law.definition.no_tension:
            # Event-driven: each case follows its frozen branch (closed / open) within a step.
            is_open = self._normal_open(u, secondary_state)
            branches = []
            for law in self._branch_laws():
                q, normal, tangential = self.contact_state(u, internal, law)
                stiffness = tangent_operator_at_contact_state(self.system, law, q, normal, tangential)
                branches.append((normal, tangential, stiffness))
            normal, tangential, stiffness = (
                np.where(is_open.reshape((-1,) + (1,) * (closed.ndim - 1)), opened, closed)
                for closed, opened in zip(*branches)
            )
        else:
            q, normal, tangential = self.contact_state(u, internal)
            stiffness = tangent_operator_at_contact_state(self.system, self.law, q, normal, tangential)
        forces = self.system.generalized_forces(q, normal, tangential)
        if self.activate_secondary:
            state = self.initial_secondary_state(u) if secondary_state is None else secondary_state
            active = np.stack([(state & 1) > 0, (state & 2) > 0], -1)
            forces = forces + self.system.secondary_forces(u, self.kappa, active)
            stiffness = stiffness + self.system.secondary_stiffness(u, self.kappa, active)
        identity = np.broadcast_to(np.eye(self.n_dof), stiffness.shape)
        gaps = self.system.secondary_gaps(q)
        return Evaluation(
            q, normal, tangential, u, forces, stiffness, identity, stiffness, gaps, self._overlap(q)
        )
