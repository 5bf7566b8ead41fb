"""User-law formulas: text to sympy through a whitelist, never ``sympify``/``eval``.

A formula such as ``"gamma*sin(alpha - alpha0)/l"`` is parsed and checked by
:mod:`ncstab.laws.safe_syntax` (the parser study-file numbers share), then
folded into a sympy expression node by node: numbers become exact integers or
rationals (``0.1`` is 1/10, as written), the declared names become their
symbols, ``+ - * / **`` become sympy's operators and the calls of
:data:`FUNCTIONS` sympy's functions.  Nothing of the text reaches Python's or
sympy's own parsers.  Limits: :data:`MAX_LENGTH` characters, a tree
:data:`MAX_DEPTH` deep and :data:`MAX_TERMS` large, numeric exponents of at most
:data:`MAX_EXPONENT` in absolute value (in the formula and in what sympy makes
of it), at most :data:`MAX_EXPANDED_TERMS` terms once expanded (counted on the
syntax tree before sympy builds anything: :func:`expanded_terms`), no integer
or decimal constant beyond :data:`MAX_CONSTANT` in absolute value, and no
infinite or undefined constants (``1/0``, ``log(0)``).

Every error is a :class:`FormulaError` that names the law, the key, the
offending token and what is allowed.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Mapping

import sympy as sp

from ncstab.laws.safe_syntax import ForbiddenConstruct, Whitelist, check_tree, fold, parse_tree, source

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_CONSTANT",
    "MAX_DEPTH",
    "MAX_EXPANDED_TERMS",
    "MAX_EXPONENT",
    "MAX_LENGTH",
    "MAX_TERMS",
    "FormulaError",
    "UserLawError",
    "expanded_terms",
    "parse_formula",
]

#: Functions a formula may call: name -> (sympy function, allowed numbers of arguments).
FUNCTIONS: dict[str, tuple[object, tuple[int, ...]]] = {
    "sin": (sp.sin, (1,)),
    "cos": (sp.cos, (1,)),
    "tan": (sp.tan, (1,)),
    "exp": (sp.exp, (1,)),
    "log": (sp.log, (1, 2)),
    "sqrt": (sp.sqrt, (1,)),
    "atan2": (sp.atan2, (2,)),
    "abs": (sp.Abs, (1,)),
}
#: Constants a formula may use besides its declared names.
CONSTANTS: dict[str, sp.Expr] = {"pi": sp.pi}
#: Longest formula (characters).
MAX_LENGTH = 1000
#: Deepest nesting of the syntax tree.
MAX_DEPTH = 40
#: Largest syntax tree (nodes).
MAX_TERMS = 400
#: Largest absolute value of a numeric exponent.
MAX_EXPONENT = 100
#: Most terms a formula may have once expanded (:func:`expanded_terms`): the symbolic
#: work on a law grows with it -- (l + alpha + gamma + alpha0 + 1)**k*(l - 1)**2 as an
#: energy took 1.8 s to build and classify at k = 6 (630 terms), 4.9 s at k = 8 (1,485)
#: and 9.7 s at k = 10 (3,003), measured; at k = 100 it did not end.
MAX_EXPANDED_TERMS = 1000
#: Largest absolute value of a number written in a formula: the compiled stepper
#: computes in 64-bit floats (a 900-digit integer is no number there).
MAX_CONSTANT = 1e15
#: Largest numerator or denominator of an exact number in a formula once built
#: (``999999999999999**5`` is one number to sympy): 2**53, what a 64-bit float holds exactly.
MAX_EXACT = 2**53
#: Largest denominator of an exact number in a formula once built (``1e-30`` is 1/10**30).
MAX_DENOMINATOR = 10**30


class UserLawError(ValueError):
    """A user law that is not allowed, naming the law, the key and the offending token.

    Attributes
    ----------
    law, key
        The law and its key at fault (``"my_law"``, ``"tangential_rate"``;
        ``""`` for the law as a whole).
    token
        The offending token, construct or sub-expression (``"x"``,
        ``"os.system"``, ``"dl**2"``), or ``""``.
    detail
        The message without the ``law ..., key ...:`` prefix.
    """

    def __init__(self, law: str, key: str, token: str, message: str) -> None:
        self.law = law
        self.key = key
        self.token = token
        self.detail = message
        where = f"law {law!r}, key {key!r}" if key else f"law {law!r}"
        super().__init__(f"{where}: {message}")

    def __reduce__(self):  # picklable despite the custom signature
        return (type(self), (self.law, self.key, self.token, self.detail))


class FormulaError(UserLawError):
    """A formula that is not allowed (a :class:`UserLawError` that also keeps the text).

    Attributes
    ----------
    formula
        The text of the formula.
    """

    def __init__(self, law: str, key: str, formula: str, token: str, message: str) -> None:
        self.formula = formula
        super().__init__(law, key, token, message)

    def __reduce__(self):  # picklable despite the custom signature
        return (type(self), (self.law, self.key, self.formula, self.token, self.detail))


def _allowed(names: Mapping[str, sp.Symbol]) -> str:
    return (
        "numbers, the names " + ", ".join(list(names) + list(CONSTANTS))
        + ", + - * / ** and parentheses, and the functions " + ", ".join(FUNCTIONS)
    )


class _SympyBuilder:
    """Folds a checked tree into a sympy expression."""

    def __init__(self, names: Mapping[str, sp.Symbol]) -> None:
        self.names = names

    def number(self, value: int | float, node: ast.Constant) -> sp.Expr:
        if isinstance(value, int):
            return sp.Integer(value)
        return sp.Rational(repr(value))  # the decimal as written: 0.1 -> 1/10

    def name(self, name: str, node: ast.Name) -> sp.Expr:
        return CONSTANTS[name] if name in CONSTANTS else self.names[name]

    def unary(self, operator: str, operand: sp.Expr, node: ast.UnaryOp) -> sp.Expr:
        return -operand if operator == "-" else operand

    def binary(self, operator: str, left: sp.Expr, right: sp.Expr, node: ast.BinOp) -> sp.Expr:
        if operator == "+":
            return left + right
        if operator == "-":
            return left - right
        if operator == "*":
            return left * right
        if operator == "/":
            if right == 0:
                raise ForbiddenConstruct(source(node), f"division by zero in {source(node)!r}")
            return left / right
        _check_exponent(right, node)
        result = left**right
        for power in sp.preorder_traversal(result):
            if isinstance(power, sp.Pow):
                _check_exponent(power.exp, node)
        return result

    def call(self, function: str, arguments: list[sp.Expr], node: ast.Call) -> sp.Expr:
        return FUNCTIONS[function][0](*arguments)  # type: ignore[operator]


def _check_exponent(exponent: sp.Expr, node: ast.BinOp) -> None:
    if exponent.is_number and exponent.is_finite is not False:
        magnitude = abs(complex(sp.N(exponent, 15)))
        if magnitude > MAX_EXPONENT:
            raise ForbiddenConstruct(
                source(node),
                f"exponent {sp.sstr(exponent)[:20]} in {source(node)!r} is too large (at most {MAX_EXPONENT})",
            )


class _TermCounter:
    """Folds a checked tree into (terms once expanded, numeric value or None), sympy-free.

    Terms: 1 for a number or a name; added by ``+ -``; multiplied by ``* /``
    (a quotient is brought to one denominator); a power of a numeric exponent n
    of an expression of t terms has C(t + m - 1, m) terms with m = ceil(|n|)
    (the monomials of degree m in t terms); a power of a symbolic exponent, and
    a function's arguments, add up.  Counts are capped just above
    :data:`MAX_EXPANDED_TERMS`: each node reports the first one over it.
    """

    cap = MAX_EXPANDED_TERMS + 1

    def __init__(self) -> None:
        self.over: ast.AST | None = None

    def _counted(self, terms: int, node: ast.AST) -> int:
        if terms > MAX_EXPANDED_TERMS and self.over is None:
            self.over = node
        return min(terms, self.cap)

    def number(self, value: int | float, node: ast.Constant) -> tuple[int, float | None]:
        try:
            return 1, float(value)
        except OverflowError:
            return 1, None

    def name(self, name: str, node: ast.Name) -> tuple[int, float | None]:
        return 1, (math.pi if name == "pi" else None)

    def unary(self, operator: str, operand: tuple, node: ast.UnaryOp) -> tuple[int, float | None]:
        terms, value = operand
        return terms, (None if value is None else (-value if operator == "-" else value))

    def binary(self, operator: str, left: tuple, right: tuple, node: ast.BinOp) -> tuple[int, float | None]:
        (t_left, v_left), (t_right, v_right) = left, right
        value = _numeric(operator, v_left, v_right)
        if operator in "+-":
            return self._counted(t_left + t_right, node), value
        if operator in "*/":
            return self._counted(t_left * t_right, node), value
        if v_right is None:  # a symbolic exponent: not expanded
            return self._counted(t_left + t_right, node), value
        degree = math.ceil(min(abs(v_right), MAX_EXPONENT + 1))
        return self._counted(math.comb(t_left + degree - 1, degree) if degree else 1, node), value

    def call(self, function: str, arguments: list[tuple], node: ast.Call) -> tuple[int, float | None]:
        return self._counted(sum(terms for terms, _ in arguments), node), None


def _numeric(operator: str, left: float | None, right: float | None) -> float | None:
    """``left <operator> right`` in floats, or None where unknown, undefined or not finite."""
    if left is None or right is None:
        return None
    try:
        value = {"+": lambda: left + right, "-": lambda: left - right, "*": lambda: left * right,
                 "/": lambda: left / right, "**": lambda: left**right}[operator]()
    except (ArithmeticError, ValueError):
        return None
    return value if isinstance(value, float) and math.isfinite(value) else None


def expanded_terms(tree: ast.expr) -> tuple[int, ast.AST | None]:
    """Terms of a checked formula once expanded, at most ``MAX_EXPANDED_TERMS + 1``, and the
    first node whose expansion has more than :data:`MAX_EXPANDED_TERMS` (None if none):
    counted on the syntax tree, before sympy builds anything (see :class:`_TermCounter`)."""
    counter = _TermCounter()
    terms, _ = fold(tree, counter)
    return terms, counter.over


def _check_constants(tree: ast.expr) -> None:
    """Refuse a number beyond :data:`MAX_CONSTANT` (``10**900`` written out, ``1e20``)."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)):
            too_large = node.value > MAX_CONSTANT or node.value < -MAX_CONSTANT
            if too_large:
                shown = source(node, 24)
                raise ForbiddenConstruct(
                    shown, f"the number {shown} is too large: numbers in a formula are at most {MAX_CONSTANT:g} "
                    "in absolute value (the path engine computes in 64-bit floats); rescale the law"
                )


def parse_formula(text: object, names: Mapping[str, sp.Symbol], *, law: str, key: str) -> sp.Expr:
    """The sympy expression of a formula, built through the whitelist.

    Parameters
    ----------
    text
        The formula, e.g. ``"gamma*(alpha - alpha0)/l"``.
    names
        The names the formula may use and their symbols (in the order they are
        listed in messages).
    law, key
        Where the formula comes from, for messages.

    Returns
    -------
    sympy.Expr
        Finite: no ``zoo``, ``oo`` or ``nan`` in it.

    Raises
    ------
    FormulaError
        For anything outside the whitelist (checked on the whole syntax tree
        before any of it is built), a syntax error, a formula too long, too
        deep or too large, an exponent beyond :data:`MAX_EXPONENT`, more than
        :data:`MAX_EXPANDED_TERMS` terms once expanded, a number beyond
        :data:`MAX_CONSTANT`, or an infinite or undefined constant.
    """
    if not isinstance(text, str):
        raise FormulaError(law, key, str(text), "", f"expected a formula (a string), got {text!r}")
    allowed = _allowed(names)
    listed = ", ".join(list(names) + list(CONSTANTS))
    whitelist = Whitelist(
        names=frozenset(names) | frozenset(CONSTANTS),
        functions={name: arities for name, (_, arities) in FUNCTIONS.items()},
        allowed=allowed,
        unknown_name=lambda name: f"unknown name {name!r}; {key} may use the names {listed}",
        max_length=MAX_LENGTH,
        max_depth=MAX_DEPTH,
        max_nodes=MAX_TERMS,
    )
    try:
        tree = parse_tree(text, whitelist)
        check_tree(tree, whitelist)
        _check_constants(tree)
        terms, over = expanded_terms(tree)
        if over is not None:
            shown = source(over)
            raise ForbiddenConstruct(
                shown, f"{shown!r} has more than {MAX_EXPANDED_TERMS:,} terms once expanded: the symbolic "
                "work on the law (its forces, its class) would not end in reasonable time; write the formula "
                "with fewer terms or lower powers"
            )
        expression: sp.Expr = fold(tree, _SympyBuilder(names))
    except ForbiddenConstruct as error:
        raise FormulaError(law, key, text, error.construct, str(error)) from None
    except (ArithmeticError, ValueError, TypeError, RecursionError) as error:
        raise FormulaError(law, key, text, "", f"{text!r} cannot be built: {error}") from None
    if expression.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise FormulaError(law, key, text, "", f"{text!r} is infinite or undefined (a division by zero, log(0), ...)")
    for number in expression.atoms(sp.Rational):
        if abs(number.p) > MAX_EXACT or number.q > MAX_DENOMINATOR:
            shown = sp.sstr(number)
            shown = shown if len(shown) <= 24 else shown[:21] + "..."
            raise FormulaError(
                law, key, text, shown, f"{text!r} makes the number {shown}, whose numerator is beyond 2**53 (the "
                f"integers a 64-bit float holds exactly) or denominator beyond 1e30; numbers are at most "
                f"{MAX_CONSTANT:g} and at least 1e-30 in absolute value: rescale the law"
            )
    return expression
