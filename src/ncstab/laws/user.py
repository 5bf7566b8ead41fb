"""User laws: contact laws typed as formulas, built into :class:`LawDefinition` values.

Three forms, in the dimensionless variables of seed Eq. (37):

* **total**: ``normal`` = N(l, alpha) and ``tangential`` = T(l, alpha) (T may
  also use N, the normal force itself);
* **rate**: ``normal_rate`` = dN and ``tangential_rate`` = dT, each linear in
  the rates ``dl`` and ``dalpha`` with coefficients of l, alpha, N, T (a form
  that is not linear in the rates is refused).  The path engine carries T
  only as an internal variable, so the normal rate is integrated here,
  symbolically, into a total normal force with N = 0 in the unloaded
  reference state (l = 1, alpha = alpha0); one that does not integrate is
  refused (give ``normal``);
* **energy**: ``energy`` = W(l, alpha), the forces by seed Eq. (16):
  dW/dl = -N and dW/dalpha = l T.

A total and a rate form of the same force may be mixed (``normal`` with
``tangential_rate``: Cundall--Strack), but not both forms of one force.  Each
formula may use ``l``, ``alpha``, ``alpha0``, ``gamma`` and the law's own
parameters, declared with their range; rates also ``N``, ``T``, ``dl``,
``dalpha``.  The normal force becomes the law's normal overlap (N = delta), so
the ``no_tension`` modifier (seed Eq. 59) acts on it as on the catalogue's.

Nothing is classified here: :func:`ncstab.symbolic.classify` does it, as for
every law.
"""

from __future__ import annotations

import keyword
import math
import re
from collections.abc import Mapping

import sympy as sp

from ncstab.laws.definition import (
    ALPHA,
    ALPHA0,
    ALPHA0_SPEC,
    DELTA,
    GAMMA,
    GAMMA_SPEC,
    L,
    N,
    T,
    LawDefinition,
    ParameterSpec,
)
from ncstab.laws.formula import FUNCTIONS, CONSTANTS, UserLawError, parse_formula

__all__ = [
    "DALPHA",
    "DL",
    "FORCE_KEYS",
    "LAW_KEYS",
    "PARAMETER_KEYS",
    "RESERVED_NAMES",
    "user_law",
    "user_parameter",
]

#: The rate of the branch length, in rate forms.
DL = sp.Symbol("dl", real=True)
#: The rate of the branch orientation, in rate forms.
DALPHA = sp.Symbol("dalpha", real=True)

#: Keys that give forces, in the order they are documented.
FORCE_KEYS = ("normal", "tangential", "normal_rate", "tangential_rate", "energy")
#: Every key of a user law.
LAW_KEYS = FORCE_KEYS + ("parameters", "description")
#: Keys of one parameter declaration.
PARAMETER_KEYS = ("min", "max", "min_inclusive", "max_inclusive", "default", "description")
#: Names a user law or parameter may not take (variables, functions, constants,
#: what generated code uses).
RESERVED_NAMES = frozenset(
    {"l", "alpha", "alpha0", "gamma", "N", "T", "dl", "dalpha", "delta", "kappa", "e", "numpy", "np", "math",
     "numba", "builtins", "sympy"}
    | set(FUNCTIONS) | set(CONSTANTS)
)
_NAME = re.compile(r"[A-Za-z][A-Za-z0-9]*(?:_[A-Za-z0-9]+)*")
_GENERATED = re.compile(r"x\d+")  # names of common subexpressions in generated code

_CONTACT_NAMES = {"l": L, "alpha": ALPHA, "alpha0": ALPHA0, "gamma": GAMMA}


def _check_name(name: object, what: str, law: str, key: str) -> str:
    if not isinstance(name, str) or not _NAME.fullmatch(name) or keyword.iskeyword(name):
        raise UserLawError(
            law, key, str(name),
            f"{what} name {name!r} is not allowed: use letters and digits, words joined by single '_' "
            "(a letter first, no '_' at either end)",
        )
    if name in RESERVED_NAMES or _GENERATED.fullmatch(name):
        raise UserLawError(law, key, name, f"{what} name {name!r} is reserved; choose another name")
    return name


def user_parameter(law: str, name: str, declaration: Mapping[str, object] | None) -> ParameterSpec:
    """The specification of a parameter a user law declares.

    Parameters
    ----------
    law
        The law declaring it (for messages).
    name
        The parameter's name (an identifier, not a reserved name).
    declaration
        ``{"min": 0.0, "max": 1.0, "min_inclusive": True, "max_inclusive":
        True, "default": 0.5, "description": "..."}``, every key optional;
        bounds are inclusive unless said otherwise; no ``default`` means the
        parameter must be given.

    Raises
    ------
    UserLawError
        A bad name, an unknown key, a bound or default that is not a finite
        number, an empty range or a default outside it.
    """
    key = f"parameters.{name}"
    _check_name(name, "parameter", law, "parameters")
    declaration = dict(declaration or {})
    unknown = [k for k in declaration if k not in PARAMETER_KEYS]
    if unknown:
        raise UserLawError(law, f"{key}.{unknown[0]}", unknown[0],
                           f"unknown key {unknown[0]!r}; a parameter takes: {', '.join(PARAMETER_KEYS)}")
    numbers: dict[str, float] = {}
    for bound in ("min", "max", "default"):
        if bound in declaration:
            value = declaration[bound]
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise UserLawError(law, f"{key}.{bound}", str(value), f"{bound} must be a finite number, got {value!r}")
            numbers[bound] = float(value)
    flags: dict[str, bool] = {}
    for flag in ("min_inclusive", "max_inclusive"):
        value = declaration.get(flag, True)
        if not isinstance(value, bool):
            raise UserLawError(law, f"{key}.{flag}", str(value), f"{flag} must be true or false, got {value!r}")
        flags[flag] = value
    description = declaration.get("description", f"parameter {name} of user law {law}")
    if not isinstance(description, str):
        raise UserLawError(law, f"{key}.description", str(description), "description must be a string")
    lower, upper = numbers.get("min", -math.inf), numbers.get("max", math.inf)
    if not (lower < upper or (lower == upper and flags["min_inclusive"] and flags["max_inclusive"])):
        raise UserLawError(law, key, name, f"the range [{lower:g}, {upper:g}] of {name!r} is empty")
    positive = lower > 0 or (lower == 0 and not flags["min_inclusive"])
    symbol = sp.Symbol(name, real=True, positive=True) if positive else (
        sp.Symbol(name, real=True, nonnegative=True) if lower >= 0 else sp.Symbol(name, real=True)
    )
    spec = ParameterSpec(
        name, symbol, description, lower=lower, upper=upper,
        lower_inclusive=flags["min_inclusive"], upper_inclusive=flags["max_inclusive"],
        default=numbers.get("default"),
    )
    if spec.default is not None:
        try:
            spec.validate(spec.default)
        except ValueError:
            raise UserLawError(law, f"{key}.default", f"{spec.default:g}",
                               f"default {spec.default:g} is outside the range of {name!r} ({spec.allowed})") from None
    return spec


def _rate_coefficients(expression: sp.Expr, law: str, key: str) -> tuple[sp.Expr, sp.Expr]:
    """(c_l, c_alpha) of a rate c_l dl + c_alpha dalpha; refuses one not linear in the rates."""
    at_rest = {DL: 0, DALPHA: 0}
    coefficients = (sp.diff(expression, DL).subs(at_rest), sp.diff(expression, DALPHA).subs(at_rest))
    residual = sp.expand(expression - coefficients[0] * DL - coefficients[1] * DALPHA)
    bad = any(c.has(sp.zoo, sp.oo, -sp.oo, sp.nan) for c in coefficients)
    if bad or (residual != 0 and sp.simplify(residual) != 0):
        shown = sp.sstr(expression) if bad else sp.sstr(sp.simplify(residual))
        raise UserLawError(
            law, key, shown,
            f"{sp.sstr(expression)} is not linear in the rates dl and dalpha (the part that is not: {shown}); "
            "write it as c_l*dl + c_alpha*dalpha with c_l and c_alpha free of dl and dalpha",
        )
    return coefficients


def _integrated_normal(coefficients: tuple[sp.Expr, sp.Expr], law: str) -> sp.Expr:
    """N(l, alpha) with dN = c_l dl + c_alpha dalpha and N = 0 at l = 1, alpha = alpha0."""
    key = "normal_rate"
    c_l, c_alpha = coefficients
    for force in (N, T):
        if c_l.has(force) or c_alpha.has(force):
            raise UserLawError(
                law, key, force.name,
                f"the normal rate depends on {force.name}: ncstab needs a total normal force N(l, alpha) "
                "(only T is carried as an internal variable); give the normal force with `normal`",
            )
    exactness = sp.simplify(sp.diff(c_l, ALPHA) - sp.diff(c_alpha, L))
    if exactness != 0:
        raise UserLawError(
            law, key, sp.sstr(exactness),
            "the normal rate is not the rate of a total normal force (d(c_l)/dalpha - d(c_alpha)/dl = "
            f"{sp.sstr(exactness)}, not 0): ncstab carries only T as an internal variable; "
            "give the normal force in total form with `normal`",
        )
    s = sp.Dummy("s", positive=True)
    a = sp.Dummy("a", real=True)
    try:
        total = sp.integrate(c_l.subs({L: s, ALPHA: ALPHA0}), (s, 1, L)) + sp.integrate(
            c_alpha.subs(ALPHA, a), (a, ALPHA0, ALPHA)
        )
    except (NotImplementedError, ValueError, TypeError) as error:  # pragma: no cover - sympy limits
        raise UserLawError(law, key, "", f"sympy cannot integrate the normal rate ({error}); give `normal`") from None
    if total.has(sp.Integral) or total.has(sp.Piecewise):
        raise UserLawError(law, key, "", "sympy cannot integrate the normal rate in closed form; give `normal`")
    total = sp.simplify(total)
    if sp.simplify(sp.diff(total, L) - c_l) != 0 or sp.simplify(sp.diff(total, ALPHA) - c_alpha) != 0:
        raise UserLawError(  # pragma: no cover - an exact rate integrates to its own antiderivative
            law, key, sp.sstr(total), "the integrated normal force does not reproduce the rate; give `normal`"
        )
    return total


def _names_for(key: str, parameters: Mapping[str, sp.Symbol]) -> dict[str, sp.Symbol]:
    names: dict[str, sp.Symbol] = dict(_CONTACT_NAMES) | dict(parameters)
    if key == "tangential":
        names["N"] = N
    if key.endswith("_rate"):
        names |= {"N": N, "T": T, "dl": DL, "dalpha": DALPHA}
    return names


def _forms(name: str, formulas: Mapping[str, object]) -> str:
    """``"energy"``, or ``"<normal key>+<tangential key>"``; refuses missing or doubled forms."""
    given = [k for k in FORCE_KEYS if formulas.get(k) is not None]
    if "energy" in given:
        others = [k for k in given if k != "energy"]
        if others:
            raise UserLawError(name, others[0], others[0],
                               f"an energy form gives both forces: remove {', '.join(others)} (or remove energy)")
        return "energy"
    chosen = []
    for total, rate in (("normal", "normal_rate"), ("tangential", "tangential_rate")):
        if total in given and rate in given:
            raise UserLawError(name, rate, rate,
                               f"give the {total} force once: either `{total}` (total form) or `{rate}`, not both")
        if total not in given and rate not in given:
            raise UserLawError(name, total, total,
                               f"missing: give `{total}` (total form) or `{rate}` (rate form), or an `energy`")
        chosen.append(total if total in given else rate)
    return "+".join(chosen)


def user_law(
    name: str,
    *,
    normal: str | None = None,
    tangential: str | None = None,
    normal_rate: str | None = None,
    tangential_rate: str | None = None,
    energy: str | None = None,
    parameters: Mapping[str, Mapping[str, object] | None] | None = None,
    description: str = "",
) -> LawDefinition:
    """A law from formulas: ``user_law("my_law", normal="-(l - 1)", tangential="gamma*sin(alpha - alpha0)")``.

    Parameters
    ----------
    name
        The law's name (letters, digits, single ``_``); not a catalogue name
        (the caller checks that: :func:`ncstab.laws.registry.law_definition`
        looks user laws up first).
    normal, tangential
        Total forms N(l, alpha), T(l, alpha) (T may use N).
    normal_rate, tangential_rate
        Rate forms, linear in ``dl`` and ``dalpha``; coefficients may use N, T.
    energy
        W(l, alpha), per contact in units of k_n (2R)^2 (seed Eq. 16, 19, 29).
    parameters
        The law's own parameters: name -> declaration (see
        :func:`user_parameter`), in order; each is swept like gamma.
    description
        One line for the law's title.

    Returns
    -------
    LawDefinition
        Parameters: gamma (if a formula uses it), alpha0, then the declared ones.

    Raises
    ------
    UserLawError
        (a ``ValueError``) naming the law, the key and the offending token: a
        formula outside the whitelist (:class:`~ncstab.laws.formula.FormulaError`),
        a missing or doubled form, a rate not linear in the rates, a normal
        rate that does not integrate, a declared parameter no formula uses.
    """
    _check_name(name, "law", name if isinstance(name, str) else "?", "")
    formulas = {"normal": normal, "tangential": tangential, "normal_rate": normal_rate,
                "tangential_rate": tangential_rate, "energy": energy}
    forms = _forms(name, formulas)
    if not isinstance(description, str):
        raise UserLawError(name, "description", str(description), "description must be a string")
    if parameters is not None and not isinstance(parameters, Mapping):
        raise UserLawError(name, "parameters", str(parameters),
                           "expected a table of parameters, e.g. { mu = { min = 0 } }")
    specs = [user_parameter(name, pname, declaration) for pname, declaration in (parameters or {}).items()]
    symbols = {spec.name: spec.symbol for spec in specs}
    parsed = {key: parse_formula(text, _names_for(key, symbols), law=name, key=key)
              for key, text in formulas.items() if text is not None}

    used = set().union(*(expression.free_symbols for expression in parsed.values()))
    for spec in specs:
        if spec.symbol not in used:
            raise UserLawError(name, f"parameters.{spec.name}", spec.name,
                               f"parameter {spec.name!r} is declared but no formula of the law uses it")
    tangential_rate_coefficients = None
    tangential_force = None
    energy_expression = None
    if forms == "energy":
        energy_expression = parsed["energy"]
        normal_force = sp.simplify(-sp.diff(energy_expression, L))
        tangential_force = sp.simplify(sp.diff(energy_expression, ALPHA) / L)
    else:
        if "normal" in parsed:
            normal_force = parsed["normal"]
        else:
            normal_force = _integrated_normal(_rate_coefficients(parsed["normal_rate"], name, "normal_rate"), name)
        if "tangential" in parsed:
            tangential_force = parsed["tangential"].subs(N, DELTA)  # N itself: the bracketed force with no_tension
        else:
            tangential_rate_coefficients = _rate_coefficients(parsed["tangential_rate"], name, "tangential_rate")
    law_parameters = ((GAMMA_SPEC,) if GAMMA in used else ()) + (ALPHA0_SPEC,) + tuple(specs)
    shown = forms.replace("+", " + ").replace("_", " ")
    return LawDefinition(
        name=name,
        title=f"user law {name} ({shown} form){': ' + description if description else ''}",
        equations=f"user formulas ({shown})",
        normal_overlap=normal_force,
        normal_force=DELTA,
        tangential_force=tangential_force,
        tangential_rate=tangential_rate_coefficients,
        energy=energy_expression,
        parameters=law_parameters,
        internal_variables=("T",) if tangential_rate_coefficients is not None else (),
    )
