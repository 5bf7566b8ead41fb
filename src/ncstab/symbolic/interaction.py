"""Any interaction law, k variables -> conjugate forces: tangents and integrability.

A law of the protocol of :mod:`ncstab.laws` (a contact law, q = (l, alpha),
forces (N, T); a rotational spring, q = (theta,), force M; any user law)
declares its variables q, its stored forces f, their work-conjugates Q(q, f)
(dW_int = Q . dq, seed Eq. 5, 9, 16), the forces' total forms f(q) where they
exist and the rate rows df_i = C_i(q, f) dq of the others.  This module
derives, once per law (cached):

* the rate matrix C (m x k), df = C dq, with the total forms differentiated;
* the conjugate tangent D = dQ/dq along the law, D = dQ/dq|_f + dQ/df C,
  with the total forms substituted for the forces that have one;
* the seed's integrability conditions generalised to k variables: the
  Frobenius condition of the rate form (a total form exists; seed Eq. 8 is
  its failure for Cundall-Strack) and the symmetry of D (a potential
  exists: seed Eq. 17 for a contact);
* the energy W(q) of a hyperelastic law.

For a contact law the results are those of :func:`ncstab.symbolic.derive_law`
(the same expressions, plus the seed's Eq. 25), which this module calls.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from typing import Any

import sympy as sp

from ncstab.laws.definition import LawDefinition
from ncstab.symbolic.derivation import (
    ConditionCheck,
    _check,
    derive_law,
    frobenius_residuals,
    is_identically_zero,
)

__all__ = ["InteractionDerivation", "derive_interaction"]


@dataclass(frozen=True)
class InteractionDerivation:
    """Symbolic tangents and integrability checks of one interaction law.

    Attributes
    ----------
    law
        The law derived (any object of the law protocol).
    totals
        Per stored force, its total form f_i(q), or ``None`` (internal variable).
    rate_matrix
        C (m x k): df = C dq; entries may contain the forces without a total form.
    conjugate_tangent
        D (k x k): dQ = D dq along the law, total forms substituted.
    checks
        The conditions evaluated, in order: rate integrability, then the
        potential condition (symmetry of D), then the law's own (Eq. 25 for a
        contact).
    rate_integrability, hyperelasticity
        The two conditions that decide the class.
    energy
        W(q) of a hyperelastic law (declared and verified, or integrated), else ``None``.
    """

    law: Any
    totals: tuple[sp.Expr | None, ...]
    rate_matrix: sp.Matrix
    conjugate_tangent: sp.Matrix
    checks: tuple[ConditionCheck, ...]
    rate_integrability: ConditionCheck
    hyperelasticity: ConditionCheck
    energy: sp.Expr | None


@functools.lru_cache(maxsize=None)
def derive_interaction(law: Any) -> InteractionDerivation:
    """Derive tangents and test the integrability conditions of any interaction law.

    Raises
    ------
    ValueError
        If a declared energy does not generate the law's conjugate forces
        (dW/dq = Q).
    """
    if isinstance(law, LawDefinition):
        contact = derive_law(law)
        return InteractionDerivation(
            law=law,
            totals=(contact.normal, contact.tangential),
            rate_matrix=contact.rate_matrix,
            conjugate_tangent=contact.conjugate_tangent,
            checks=contact.checks,
            rate_integrability=contact.rate_integrability,
            hyperelasticity=contact.hyperelasticity,
            energy=contact.energy,
        )
    variables, forces = tuple(law.variables), tuple(law.force_symbols)
    totals = tuple(None if e is None else sp.sympify(e) for e in law.force_totals)
    rows = []
    for total, rate_row in zip(totals, law.force_rates):
        if total is not None:
            rows.append([sp.diff(total, q) for q in variables])
        else:
            assert rate_row is not None
            rows.append([sp.sympify(c) for c in rate_row])
    rate = sp.Matrix(rows)
    substitutions = {f: t for f, t in zip(forces, totals) if t is not None}
    conjugates = sp.Matrix([sp.sympify(e) for e in law.conjugate_expressions])
    along = conjugates.jacobian(sp.Matrix(variables)) + conjugates.jacobian(sp.Matrix(forces)) * rate
    tangent = along.applyfunc(lambda e: sp.sympify(e).subs(substitutions))
    frobenius = frobenius_residuals(rate, variables, forces)
    rate_check = next(
        (c for c in (_check("Frobenius integrability of the rate form", "D_b C_ia = D_a C_ib", r) for r in frobenius)
         if not c.holds),
        ConditionCheck("Frobenius integrability of the rate form", "D_b C_ia = D_a C_ib", sp.Integer(0), True),
    )
    names = [q.name for q in variables]
    asymmetry = [(a, b) for a in range(len(variables)) for b in range(a + 1, len(variables))]
    symmetric = [
        _check("potential (D symmetric)", f"dQ_{names[a]}/d{names[b]} = dQ_{names[b]}/d{names[a]}",
               tangent[a, b] - tangent[b, a])
        for a, b in asymmetry
    ]
    hyper_check = next(
        (c for c in symmetric if not c.holds),
        symmetric[0] if symmetric else ConditionCheck(
            "potential (D symmetric)", "one variable: Q dq is always exact", sp.Integer(0), True),
    )
    energy = None if law.energy is None else sp.sympify(law.energy)
    conjugate_totals = [sp.sympify(e).subs(substitutions) for e in law.conjugate_expressions]
    if energy is not None:
        for q, conjugate in zip(variables, conjugate_totals):
            ok, _ = is_identically_zero(sp.diff(energy, q) - conjugate)
            if not ok:
                raise ValueError(
                    f"law {law.name!r}: the declared energy does not generate its forces "
                    f"(dW/d{q.name} = Q_{q.name} fails)"
                )
    elif rate_check.holds and hyper_check.holds and len(variables) == 1 and totals[0] is not None:
        (q,) = variables
        energy = sp.integrate(conjugate_totals[0], (q, 0, q))
    return InteractionDerivation(
        law=law,
        totals=totals,
        rate_matrix=rate,
        conjugate_tangent=tangent,
        checks=(rate_check, hyper_check),
        rate_integrability=rate_check,
        hyperelasticity=hyper_check,
        energy=energy,
    )
