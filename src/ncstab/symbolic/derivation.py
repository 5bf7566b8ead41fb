"""Symbolic tangents and integrability conditions of contact laws.

Everything here runs once per law definition (results are cached) and never
inside a numeric loop.

Notation (per contact, dimensionless, seed Eq. 37): contact variables
q = (l, alpha), forces (N, T).  The work-conjugate of q is Q = (-N, l T)
(seed Eq. 9 and 16: dW_int = -N dl + T l dalpha).

* The *rate matrix* C gives [dN, dT] = C [dl, dalpha] (seed Eq. 13, 21-22, 26).
* The *conjugate tangent* D gives dQ = D dq:
  D = [[-C_Nl, -C_Na], [T + l C_Tl, l C_Ta]].
  A law derives from a potential exactly when D is symmetric (seed Eq. 17).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ncstab.laws.definition import ALPHA, ALPHA0, GAMMA, L, N, T, LawDefinition

__all__ = [
    "ConditionCheck",
    "frobenius_residuals",
    "LawDerivation",
    "derive_law",
    "kinematic_integrability",
    "is_identically_zero",
]

_CONTACT = (L, ALPHA)
_FORCES = (N, T)


@dataclass(frozen=True)
class ConditionCheck:
    """The outcome of one integrability condition.

    Attributes
    ----------
    name
        Short name (``"Eq. (17) hyperelasticity"``).
    equation
        The condition in words/symbols.
    residual
        The simplified sympy expression that must vanish identically.
    holds
        Whether it vanishes identically.
    method
        ``"symbolic"`` (simplified to 0, or to a non-zero expression) or
        ``"numeric probe"`` (simplify was inconclusive; decided on random points).
    """

    name: str
    equation: str
    residual: sp.Expr
    holds: bool
    method: str = "symbolic"

    def __str__(self) -> str:
        verdict = "holds" if self.holds else f"fails (residual {sp.sstr(self.residual)})"
        return f"{self.name}: {self.equation} {verdict}"


def _free_numeric_symbols(expr: sp.Expr) -> list[sp.Symbol]:
    return sorted(expr.free_symbols, key=lambda s: s.name)


def is_identically_zero(expr: sp.Expr, *, probes: int = 64, seed: int = 20220712) -> tuple[bool, str]:
    """Decide whether ``expr`` vanishes identically.

    First ``sympy.simplify``; when that is inconclusive (non-smooth Macaulay
    brackets), evaluate at ``probes`` random admissible points (l in [0.3, 1.7],
    angles in [0.05, 1.5], forces in [-1, 1], gamma in [0, 3]) and call it zero if
    every value is below 1e-12 in absolute value.

    Returns
    -------
    (bool, str)
        The verdict and the method that decided it.
    """
    expr = sp.sympify(expr)
    expr = expr.replace(sp.DiracDelta, lambda *args: sp.Integer(0))
    simplified = sp.simplify(expr)
    if simplified == 0:
        return True, "symbolic"
    symbols = _free_numeric_symbols(simplified)
    if not symbols:
        return bool(abs(complex(simplified)) == 0), "symbolic"
    rng = np.random.default_rng(seed)
    ranges = {
        "l": (0.3, 1.7),
        "alpha": (0.05, 1.5),
        "alpha0": (0.05, 1.5),
        "gamma": (0.0, 3.0),
        "N": (-1.0, 1.0),
        "T": (-1.0, 1.0),
    }
    func = sp.lambdify(symbols, simplified, "numpy")
    samples = [rng.uniform(*ranges.get(s.name, (-1.0, 1.0)), size=probes) for s in symbols]
    with np.errstate(all="ignore"):
        values = np.asarray(func(*samples), dtype=complex) * np.ones(probes)
    return bool(np.all(np.abs(values) < 1e-12)), "numeric probe"


def _check(name: str, equation: str, residual: sp.Expr) -> ConditionCheck:
    holds, method = is_identically_zero(residual)
    shown = sp.Integer(0) if holds else sp.simplify(residual)
    return ConditionCheck(name, equation, shown, holds, method)


def kinematic_integrability() -> ConditionCheck:
    """Seed Eq. (7)-(8): is du_t = l dalpha a total differential of (l, alpha)?

    With du_t = A dl + B dalpha, A = 0 and B = l, exactness needs
    dA/dalpha = dB/dl, i.e. 0 = 1: it fails, so (u_n, u_t) are not state
    variables of the contact.
    """
    a_coefficient = sp.Integer(0)
    b_coefficient = L
    residual = sp.diff(a_coefficient, ALPHA) - sp.diff(b_coefficient, L)
    return _check("Eq. (8) kinematics", "d(0)/dalpha = d(l)/dl for du_t = l dalpha", residual)


@dataclass(frozen=True)
class LawDerivation:
    """Symbolic tangents and integrability checks of one law definition.

    Attributes
    ----------
    definition
        The law definition derived.
    normal, tangential
        Total forms N(l, alpha), T(l, alpha); ``tangential`` is ``None`` for a
        law given only in rate form.
    rate_matrix
        C, 2x2, with [dN, dT] = C [dl, dalpha] (may contain N, T for rate laws).
    conjugate_tangent
        D, 2x2, with d(-N, l T) = D d(l, alpha).
    rate_integrability
        Frobenius condition of the rate system (total form exists iff it holds).
    hyperelasticity
        Seed Eq. (17): -dN/dalpha = d(l T)/dl, i.e. D symmetric.
    normal_independent_of_alpha
        Seed Eq. (25), first half: dN/dalpha = 0.
    energy
        W(l, alpha) per contact (units k_n (2R)^2), declared and verified, or
        ``None``.
    """

    definition: LawDefinition
    normal: sp.Expr
    tangential: sp.Expr | None
    rate_matrix: sp.Matrix
    conjugate_tangent: sp.Matrix
    rate_integrability: ConditionCheck
    hyperelasticity: ConditionCheck
    normal_independent_of_alpha: ConditionCheck
    energy: sp.Expr | None

    @property
    def checks(self) -> tuple[ConditionCheck, ...]:
        return (
            self.rate_integrability,
            self.hyperelasticity,
            self.normal_independent_of_alpha,
        )


def _rate_matrix(definition: LawDefinition) -> sp.Matrix:
    normal = definition.normal_total
    rows = [[sp.diff(normal, L), sp.diff(normal, ALPHA)]]
    tangential = definition.tangential_total
    if tangential is not None:
        rows.append([sp.diff(tangential, L), sp.diff(tangential, ALPHA)])
    else:
        assert definition.tangential_rate is not None
        rows.append([sp.sympify(c) for c in definition.tangential_rate])
    return sp.Matrix(rows)


def frobenius_residuals(
    rate: sp.Matrix, variables: tuple[sp.Symbol, ...], forces: tuple[sp.Symbol, ...]
) -> list[sp.Expr]:
    """Residuals of the Frobenius condition of the rate system df = C(q, f) dq.

    For k variables q and m forces f (C is m x k), the rate form is
    integrable -- a total form f(q) exists -- iff for every force i and every
    pair of variables a < b, D_b C_ia = D_a C_ib with the total derivatives
    D_a = d/dq_a + sum_j C_ja d/df_j.  For a contact (q = (l, alpha),
    f = (N, T)) this is one condition per force, D_alpha C_il = D_l C_ialpha
    (the seed's Eq. 8 in rate form: l dalpha is not exact).  Returns the
    residuals ordered by force, then by pair; none for k = 1 (a one-variable
    rate law always integrates).
    """
    k, m = len(variables), len(forces)

    def total_derivative(expr: sp.Expr, a: int) -> sp.Expr:
        return sp.diff(expr, variables[a]) + sum(rate[j, a] * sp.diff(expr, forces[j]) for j in range(m))

    return [
        total_derivative(rate[i, a], b) - total_derivative(rate[i, b], a)
        for i in range(m)
        for a in range(k)
        for b in range(a + 1, k)
    ]


def _substitute_total_forms(expr: sp.Expr, normal: sp.Expr, tangential: sp.Expr | None) -> sp.Expr:
    subs = {N: normal}
    if tangential is not None:
        subs[T] = tangential
    return sp.sympify(expr).subs(subs)


@functools.lru_cache(maxsize=None)
def derive_law(definition: LawDefinition) -> LawDerivation:
    """Derive tangents and test the seed's integrability conditions for a law.

    Parameters
    ----------
    definition
        Any law definition (catalogue or user-defined).

    Returns
    -------
    LawDerivation

    Raises
    ------
    ValueError
        If a declared energy does not generate the law's forces
        (dW/dl = -N and dW/dalpha = l T, seed Eq. 16).
    """
    normal = definition.normal_total
    tangential = definition.tangential_total
    rate = _rate_matrix(definition)
    conjugate = sp.Matrix(
        [
            [-rate[0, 0], -rate[0, 1]],
            [T + L * rate[1, 0], L * rate[1, 1]],
        ]
    )
    conjugate = conjugate.applyfunc(lambda e: _substitute_total_forms(e, normal, tangential))

    frobenius = frobenius_residuals(rate, _CONTACT, _FORCES)
    normal_rate, tangential_rate = (
        _check(
            "Frobenius integrability of the rate form",
            f"D_alpha(d{force}/dl) = D_l(d{force}/dalpha)",
            residual,
        )
        for force, residual in zip("NT", frobenius)
    )
    rate_check = normal_rate if not normal_rate.holds else tangential_rate
    hyper_check = _check(
        "Eq. (17) hyperelasticity",
        "-dN/dalpha = d(l T)/dl",
        conjugate[0, 1] - conjugate[1, 0],
    )
    normal_check = _check("Eq. (25) N independent of alpha", "dN/dalpha = 0", rate[0, 1])

    energy = definition.energy_total
    if energy is not None:
        residual_l = sp.diff(energy, L) + normal
        residual_alpha = sp.diff(energy, ALPHA) - (L * tangential if tangential is not None else sp.nan)
        for label, residual in (("dW/dl = -N", residual_l), ("dW/dalpha = l T", residual_alpha)):
            ok, _ = is_identically_zero(residual)
            if not ok:
                raise ValueError(
                    f"law {definition.name!r}: the declared energy does not generate its "
                    f"forces ({label} fails, seed Eq. 16)"
                )
    elif rate_check.holds and hyper_check.holds and tangential is not None:
        energy = _integrate_potential(normal, tangential)

    return LawDerivation(
        definition=definition,
        normal=normal,
        tangential=tangential,
        rate_matrix=rate,
        conjugate_tangent=conjugate,
        rate_integrability=rate_check,
        hyperelasticity=hyper_check,
        normal_independent_of_alpha=normal_check,
        energy=energy,
    )


def _integrate_potential(normal: sp.Expr, tangential: sp.Expr) -> sp.Expr | None:
    """W(l, alpha) = int_{alpha0}^{alpha} l T(1, a) da + int_1^l -N(s, alpha) ds.

    Returns ``None`` if sympy cannot do the quadratures in closed form.
    """
    s, a = sp.symbols("s a", real=True)
    try:
        along_alpha = sp.integrate((L * tangential).subs({L: 1, ALPHA: a}), (a, ALPHA0, ALPHA))
        along_l = sp.integrate(-normal.subs(L, s), (s, 1, L))
    except (NotImplementedError, ValueError):  # pragma: no cover - sympy limits
        return None
    if along_alpha.has(sp.Integral) or along_l.has(sp.Integral):
        return None
    return sp.simplify(along_alpha + along_l)


# Symbols that compiled functions take as arguments, in order.
CONTACT_SYMBOLS = _CONTACT
FORCE_SYMBOLS = _FORCES
PARAMETER_SYMBOLS = (GAMMA, ALPHA0)
