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
of it), and no infinite or undefined constants (``1/0``, ``log(0)``).

Every error is a :class:`FormulaError` that names the law, the key, the
offending token and what is allowed.
"""

from __future__ import annotations

import ast
from collections.abc import Mapping

import sympy as sp

from ncstab.laws.safe_syntax import ForbiddenConstruct, Whitelist, check_tree, fold, parse_tree, source

__all__ = [
    "CONSTANTS",
    "FUNCTIONS",
    "MAX_DEPTH",
    "MAX_EXPONENT",
    "MAX_LENGTH",
    "MAX_TERMS",
    "FormulaError",
    "UserLawError",
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
        deep or too large, an exponent beyond :data:`MAX_EXPONENT`, or an
        infinite or undefined constant.
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
        expression: sp.Expr = fold(tree, _SympyBuilder(names))
    except ForbiddenConstruct as error:
        raise FormulaError(law, key, text, error.construct, str(error)) from None
    except (ArithmeticError, ValueError, TypeError, RecursionError) as error:
        raise FormulaError(law, key, text, "", f"{text!r} cannot be built: {error}") from None
    if expression.has(sp.zoo, sp.oo, -sp.oo, sp.nan):
        raise FormulaError(law, key, text, "", f"{text!r} is infinite or undefined (a division by zero, log(0), ...)")
    return expression
