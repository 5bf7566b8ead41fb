"""The tangent operator K (dF = K du) of a system with a contact law.

For a system whose contacts have variables q_c(u) = (l_c, alpha_c) and forces
(N_c, T_c), the virtual-work equilibrium F = sum_c w_c J_c^T Q_c with
Q_c = (-N_c, l_c T_c) differentiates to

    K = sum_c w_c [ J_c^T D_c J_c + sum_k Q_ck H_ck ]

where D_c = dQ_c/dq_c is the law's conjugate tangent (from its rate form) and
H_ck = d2 q_ck/du2 carries the geometric terms in the current forces (seed
Eq. 30-34: the -F2 dalpha and +F1 dalpha terms).  For the diamond this gives
the seed's Eq. (38) for Cundall--Strack and Eq. (51) for McNamara et al.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np
import sympy as sp

from ncstab.laws.definition import ALPHA, L, N, T, LawDefinition

from ncstab.laws.registry import Law
from ncstab.symbolic.compile import compile_law
from ncstab.systems.protocol import DiscreteSystem, conjugate_forces

__all__ = [
    "STATE_KERNEL_OUTPUTS",
    "check_shared_parameters",
    "compile_state_kernel",
    "conjugate_tangent",
    "contact_forces",
    "generalized_forces",
    "tangent_operator",
    "tangent_operator_at_contact_state",
    "tangent_operator_at_forces",
]


def check_shared_parameters(system: DiscreteSystem, law: Law) -> None:
    """Raise if a parameter both the system and the law carry (alpha0) differs.

    The law's reference orientation and the system's initial orientation are
    the same quantity in the seed; two different values would silently give a
    prestressed reference state.
    """
    for name in set(system.parameters) & set(law.parameters):
        a, b = np.asarray(system.parameters[name]), np.asarray(law.parameters[name])
        if a.shape == b.shape and np.array_equal(a, b):
            continue
        try:
            same = np.allclose(a, b, rtol=0, atol=1e-15)
        except ValueError:
            same = False
        if not same:
            raise ValueError(
                f"parameter {name!r} differs between the system ({a!r}) and the law ({b!r}); "
                "give both the same value (they are the same quantity, seed Eq. 1 and 18)"
            )


def conjugate_tangent(
    law: Law, length: np.ndarray, alpha: np.ndarray, normal: np.ndarray, tangential: np.ndarray
) -> np.ndarray:
    """D = d(-N, l T)/d(l, alpha) of a law at a contact state, ``(..., 2, 2)``.

    From the rate matrix C ([dN, dT] = C [dl, dalpha], seed Eq. 13/22/26):
    ``D = [[-C_Nl, -C_Na], [T + l C_Tl, l C_Ta]]``.  D is symmetric for a
    hyperelastic law (seed Eq. 17).
    """
    rate = compile_law(law.definition).rate_matrix(law, length, alpha, normal, tangential)
    top = -rate[..., 0, :]
    bottom = np.stack(
        [tangential + length * rate[..., 1, 0], length * rate[..., 1, 1]], axis=-1
    )
    return np.stack([top, bottom], axis=-2)


def contact_forces(system: DiscreteSystem, law: Law, u: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N, T) per contact from the law's total form at displacements ``u``.

    Returns two arrays of shape ``(..., n_contacts)``.

    Raises
    ------
    ValueError
        For a law without a total tangential force (T is then an internal
        variable that only a path can carry).
    """
    check_shared_parameters(system, law)
    compiled = compile_law(law.definition)
    q = system.contact_variables(u)
    normal = np.stack(
        [compiled.normal_force(law, q[..., c, 0], q[..., c, 1]) for c in range(system.n_contacts)], -1
    )
    tangential = np.stack(
        [compiled.tangential_force(law, q[..., c, 0], q[..., c, 1]) for c in range(system.n_contacts)],
        -1,
    )
    return normal, tangential


def generalized_forces(
    system: DiscreteSystem,
    law: Law,
    u: np.ndarray,
    tangential: np.ndarray | None = None,
) -> np.ndarray:
    """Equilibrium forces F(u) (seed Eq. 4), shape ``(..., n_dof)``.

    ``tangential`` (shape ``(..., n_contacts)``) supplies T for a law without a
    total tangential form (its internal variable); otherwise T comes from the law.
    """
    compiled = compile_law(law.definition)
    q = system.contact_variables(u)
    normal = np.stack(
        [compiled.normal_force(law, q[..., c, 0], q[..., c, 1]) for c in range(system.n_contacts)], -1
    )
    if tangential is None:
        _, tangential = contact_forces(system, law, u)
    return system.generalized_forces(q, normal, np.asarray(tangential, dtype=float))


def tangent_operator_at_contact_state(
    system: DiscreteSystem, law: Law, q: np.ndarray, normal: np.ndarray, tangential: np.ndarray
) -> np.ndarray:
    """K from contact variables ``q`` (..., n_c, 2) and forces (N, T) (..., n_c).

    The assembly K = sum_c w_c [J_c^T D_c J_c + sum_k Q_ck H_ck] itself; the
    other entry points compute (q, N, T) and call this.
    """
    jacobian = system.contact_jacobian(q)
    hessian = system.contact_hessian(q)
    weights = system.contact_weights
    stiffness = 0.0
    for c in range(system.n_contacts):  # contact families: a handful, not cases
        length, alpha = q[..., c, 0], q[..., c, 1]
        d_matrix = conjugate_tangent(law, length, alpha, normal[..., c], tangential[..., c])
        conjugate = conjugate_forces(length, normal[..., c], tangential[..., c])
        jac = jacobian[..., c, :, :]
        material = np.swapaxes(jac, -1, -2) @ d_matrix @ jac
        geometric = (conjugate[..., :, None, None] * hessian[..., c, :, :, :]).sum(axis=-3)
        stiffness = stiffness + weights[c] * (material + geometric)
    return np.asarray(stiffness)


def tangent_operator(
    system: DiscreteSystem,
    law: Law,
    u: np.ndarray,
    tangential: np.ndarray | None = None,
) -> np.ndarray:
    """K = dF/du at displacements ``u``, shape ``(..., n_dof, n_dof)``.

    Parameters
    ----------
    system, law
        The system and its contact law (parameters broadcast with ``u[..., 0]``).
    u
        Generalized displacements, ``(..., n_dof)``.
    tangential
        Current T per contact, ``(..., n_contacts)``; required for a law without
        a total tangential form (Cundall--Strack), ignored otherwise.
    """
    check_shared_parameters(system, law)
    u = np.asarray(u, dtype=float)
    q = system.contact_variables(u)
    compiled = compile_law(law.definition)
    normal = np.stack(
        [compiled.normal_force(law, q[..., c, 0], q[..., c, 1]) for c in range(system.n_contacts)], -1
    )
    if law.has_total_form:
        _, tangential = contact_forces(system, law, u)
    elif tangential is None:
        raise ValueError(
            f"law {law.name!r} has T as an internal variable: pass its current value "
            "as `tangential` (shape (..., n_contacts))"
        )
    return tangent_operator_at_contact_state(system, law, q, normal, np.asarray(tangential, dtype=float))


def tangent_operator_at_forces(
    system: DiscreteSystem, law: Law, u: np.ndarray, forces: np.ndarray
) -> np.ndarray:
    """K at displacements ``u`` carrying generalized forces ``F`` (any law).

    The contact forces are recovered from F by inverting the equilibrium (for
    the diamond, seed Eq. 4), so this is the operator of seed Eq. (34)/(38)
    written with the current (F1, F2), whatever the law's history.
    """
    check_shared_parameters(system, law)
    u = np.asarray(u, dtype=float)
    q = system.contact_variables(u)
    normal, tangential = system.contact_forces(q, np.asarray(forces, dtype=float))
    return tangent_operator_at_contact_state(system, law, q, normal, tangential)


#: Outputs of a state kernel (:func:`compile_state_kernel`), in order; the
#: last two only for a law whose T is an internal variable.
STATE_KERNEL_OUTPUTS = ("N", "T", "F1", "F2", "K11", "K12", "K21", "K22", "dT_dD1", "dT_dD2")


@functools.lru_cache(maxsize=None)
def compile_state_kernel(system_type: type, definition: LawDefinition) -> Callable[..., list]:
    """One fused numpy function for forces, K and the T rate of a one-contact system.

    Derived by :func:`_derive_state_kernel` once per machine: its source is kept
    in the cache directory (:mod:`ncstab.operators.kernel_cache`), and a later
    process builds the function from it without sympy's derivation (half a
    second per law).
    """
    from ncstab.operators.kernel_cache import cached_kernel

    return cached_kernel(system_type, definition, lambda: _derive_state_kernel(system_type, definition))


def _derive_state_kernel(system_type: type, definition: LawDefinition) -> Callable[..., list]:
    """The state kernel of :func:`compile_state_kernel`, derived with sympy.

    The assembly of :func:`tangent_operator_at_contact_state` (K = w [J^T D J
    + Q_l H_l + Q_alpha H_alpha], F = w J^T Q) and of the internal-variable
    rate dT = C_Tl dl + C_Ta dalpha, done once in sympy on the system's
    symbolic kinematics (``system_type.symbolic_kinematics``) and the law's
    derived rate matrix, then lambdified with common-subexpression
    elimination.  The constant zeros and ones of a law's rate matrix vanish
    from the generated code, and no (B, 2, 2) temporaries are built: this is
    the engine's inner loop.  sympy runs here only (cached per system type and
    law definition, in the process and on disk), never per evaluation.

    Returns
    -------
    callable
        ``f(l, alpha, cos_alpha, sin_alpha, T_internal, *law_parameters)`` ->
        list of the :data:`STATE_KERNEL_OUTPUTS` (arrays or Python scalars;
        ``T_internal`` is ignored by a law with a total form).
    """
    from ncstab.symbolic.derivation import derive_law

    derivation = derive_law(definition)
    length, alpha, c, s, t_in = sp.symbols("l_ alpha_ c_ s_ T_internal_", real=True)
    jacobian, hessians = system_type.symbolic_kinematics(length, c, s)
    weight = sp.Integer(2)
    normal = derivation.normal
    tangential = derivation.tangential if derivation.tangential is not None else T
    contact = {L: length, ALPHA: alpha}
    normal = sp.sympify(normal).subs(contact)
    tangential = sp.sympify(tangential).subs(contact).subs(T, t_in)
    rate = [
        sp.sympify(e).subs(contact).subs({N: normal, T: tangential}) for e in derivation.rate_matrix
    ]
    conjugate_tangent_matrix = sp.Matrix(
        [[-rate[0], -rate[1]], [tangential + length * rate[2], length * rate[3]]]
    )
    conjugate = [-normal, length * tangential]
    stiffness = weight * (
        jacobian.T * conjugate_tangent_matrix * jacobian + conjugate[0] * hessians[0] + conjugate[1] * hessians[1]
    )
    forces = weight * jacobian.T * sp.Matrix(conjugate)
    outputs = [normal, tangential, forces[0], forces[1], *list(stiffness)]
    if derivation.tangential is None:
        gradient = sp.Matrix([[rate[2], rate[3]]]) * jacobian
        outputs += list(gradient)
    outputs = [sp.sympify(e).replace(sp.DiracDelta, lambda *args: sp.Integer(0)) for e in outputs]
    arguments = [length, alpha, c, s, t_in, *definition.parameter_symbols]
    return sp.lambdify(arguments, outputs, modules="numpy", cse=True, printer=_KernelPrinter)


def _kernel_printer_class() -> type:
    from sympy.printing.numpy import NumPyPrinter

    class KernelPrinter(NumPyPrinter):
        """numpy printer writing integer powers as products in numba's order
        (:func:`ncstab.symbolic.powers.power_product`): the same bits compiled, in plain
        Python and on numpy arrays, and cheaper than numpy's power."""

        def _print_Pow(self, expr, rational=False):  # noqa: N802 (sympy's name)
            from ncstab.symbolic.powers import LARGEST_UNROLLED, power_product

            base, exponent = expr.as_base_exp()
            if exponent.is_Integer and 0 < abs(int(exponent)) <= LARGEST_UNROLLED:
                text = self._print(base)
            return power_product(text if base.is_Symbol else f"({text})", int(exponent))
            return super()._print_Pow(expr, rational=rational)

    return KernelPrinter


_KernelPrinter = _kernel_printer_class()
