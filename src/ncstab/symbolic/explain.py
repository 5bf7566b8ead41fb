"""The derivation of a law's class, as text (``ncstab laws --explain NAME``).

Shows the forms the law is given in, its rate matrix C and conjugate tangent
D (seed Eq. 13, 16-17), every condition :func:`~ncstab.symbolic.classify`
evaluates with its residual, the condition that decided the class, and the
energy of a hyperelastic law.
"""

from __future__ import annotations

import sympy as sp

from ncstab.laws.definition import LawDefinition
from ncstab.symbolic.classification import classify
from ncstab.symbolic.derivation import derive_law

__all__ = ["explain_law"]


def _matrix(matrix: sp.Matrix) -> str:
    rows = ["[" + ", ".join(sp.sstr(sp.simplify(entry)) for entry in matrix.row(i)) + "]" for i in range(matrix.rows)]
    return "[" + ", ".join(rows) + "]"


def explain_law(definition: LawDefinition) -> str:
    """Why a law has its class: forms, tangents, each condition and its residual.

    Parameters
    ----------
    definition
        Any law definition (catalogue, modified or user law).

    Returns
    -------
    str
        Several lines, the last ones giving the class and the deciding condition.
    """
    derivation = derive_law(definition)
    result = classify(definition)
    lines = [f"{definition.name}: {definition.title}", f"  equations: {definition.equations}"]
    if definition.parameters:
        lines.append("  parameters: " + ", ".join(f"{p.name} ({p.allowed})" for p in definition.parameters))
    lines.append(f"  N(l, alpha) = {sp.sstr(derivation.normal)}")
    if derivation.tangential is not None:
        lines.append(f"  T(l, alpha) = {sp.sstr(derivation.tangential)}")
    else:
        c_l, c_alpha = derivation.rate_matrix.row(1)
        lines.append(
            f"  dT = ({sp.sstr(c_l)}) dl + ({sp.sstr(c_alpha)}) dalpha   (T is an internal variable, 0 at the start)"
        )
    lines.append(f"  rate matrix C, [dN, dT] = C [dl, dalpha]: {_matrix(derivation.rate_matrix)}")
    lines.append(f"  conjugate tangent D = d(-N, l T)/d(l, alpha): {_matrix(derivation.conjugate_tangent)}")
    lines.append("conditions (seed Eq. 8, 17, 25):")
    for check in result.checks:
        verdict = ("holds" + (" (numeric probe)" if check.method == "numeric probe" else "")) if check.holds else "FAILS"
        lines.append(f"  {check.name}: {check.equation} -- {verdict}")
        if not check.holds:
            lines.append(f"      residual: {sp.sstr(check.residual)}")
    deciding = result.deciding_condition
    verdict = "holds" if deciding.holds else f"fails, residual {sp.sstr(deciding.residual)}"
    lines.append(f"class: {result.kind} -- decided by {deciding.name} ({verdict})")
    if result.energy is not None:
        lines.append(f"energy W(l, alpha) = {sp.sstr(result.energy)}")
    elif result.kind != "hyperelastic":
        lines.append("no energy: the law derives from no potential")
    return "\n".join(lines)
