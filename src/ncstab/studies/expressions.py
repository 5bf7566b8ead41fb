"""Safe arithmetic expressions of pi in study files (``alpha0 = "pi/4"``).

An expression is parsed and checked by the whitelist of
:mod:`ncstab.laws.safe_syntax` (the parser user-law formulas share), never
compiled or evaluated by Python: only numbers, the constants ``pi`` and ``e``,
unary ``+``/``-``, the binary operators ``+ - * / **`` and calls of a short list
of functions (:data:`FUNCTIONS`) with positional arguments are allowed.  Anything
else (names, attributes, subscripts, keyword arguments, strings, lambdas,
comprehensions, ...) is rejected before any part of the expression is computed,
with a message that names the offending construct.

Arithmetic is done in floating point (``"1/3"`` is ``1.0 / 3.0``), so results are
the values Python itself gives: ``evaluate_expression("pi/4") == math.pi / 4``.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable

from ncstab.laws.safe_syntax import ForbiddenConstruct, Whitelist, check_tree, fold, parse_tree, source

__all__ = ["CONSTANTS", "FUNCTIONS", "ExpressionError", "evaluate_expression", "is_expression"]

#: Names an expression may use as values.
CONSTANTS: dict[str, float] = {"pi": math.pi, "e": math.e}

#: Functions an expression may call: name -> (function, allowed numbers of arguments).
FUNCTIONS: dict[str, tuple[Callable[..., float], tuple[int, ...]]] = {
    "sqrt": (math.sqrt, (1,)),
    "sin": (math.sin, (1,)),
    "cos": (math.cos, (1,)),
    "tan": (math.tan, (1,)),
    "exp": (math.exp, (1,)),
    "log": (math.log, (1, 2)),
    "radians": (math.radians, (1,)),
    "degrees": (math.degrees, (1,)),
}

#: Longest expression accepted (characters); study-file numbers are short.
MAX_LENGTH = 200
#: Largest absolute exponent of ``**``.
MAX_EXPONENT = 100.0

_BINARY: dict[str, Callable[[float, float], float]] = {
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    "/": lambda a, b: a / b,
    "**": math.pow,  # real results only: math.pow(-8, 1/3) raises, ** would give a complex
}
ALLOWED = (
    "numbers, pi, e, + - * / ** and parentheses, and the functions "
    + ", ".join(FUNCTIONS)
)
WHITELIST = Whitelist(
    names=frozenset(CONSTANTS),
    functions={name: arities for name, (_, arities) in FUNCTIONS.items()},
    allowed=ALLOWED,
    unknown_name=lambda name: (
        f"name {name!r} is not allowed in an expression (only pi and e); "
        "a parameter is referred to by its name alone, not inside an expression"
    ),
    max_length=MAX_LENGTH,
)


class ExpressionError(ValueError):
    """An expression that is not allowed or cannot be evaluated.

    Attributes
    ----------
    expression
        The text of the expression.
    construct
        The offending part of it (source text), or ``""`` when the whole
        expression is at fault (syntax, overflow, a non-finite result).
    """

    def __init__(self, expression: str, construct: str, message: str) -> None:
        self.expression = expression
        self.construct = construct
        super().__init__(message)


class _FloatBuilder:
    """Folds a checked tree into a float, as Python's floating point does."""

    def __init__(self, text: str) -> None:
        self.text = text

    def number(self, value: int | float, node: ast.Constant) -> float:
        return float(value)

    def name(self, name: str, node: ast.Name) -> float:
        return CONSTANTS[name]

    def unary(self, operator: str, operand: float, node: ast.UnaryOp) -> float:
        return -operand if operator == "-" else +operand

    def binary(self, operator: str, left: float, right: float, node: ast.BinOp) -> float:
        if operator == "**" and abs(right) > MAX_EXPONENT:
            raise ExpressionError(
                self.text, source(node),
                f"exponent {right:g} in {source(node)!r} is too large (at most {MAX_EXPONENT:g})",
            )
        return _BINARY[operator](left, right)

    def call(self, function: str, arguments: list[float], node: ast.Call) -> float:
        return FUNCTIONS[function][0](*arguments)


def evaluate_expression(text: str) -> float:
    """The value of a safe arithmetic expression of pi.

    Parameters
    ----------
    text
        ``"pi/4"``, ``"2*pi/5"``, ``"-0.5*pi"``, ``"sqrt(2)/2"``, ``"1e-3"``,
        ``"radians(30)"``...

    Returns
    -------
    float
        The finite value.

    Raises
    ------
    ExpressionError
        For any construct outside :data:`ALLOWED` (checked on the syntax tree,
        before anything is computed), a syntax error, a math error (division
        by zero, ``sqrt(-1)``, overflow) or a non-finite result.
    """
    if not isinstance(text, str):
        raise ExpressionError(str(text), "", f"expected a number or an expression string, got {text!r}")
    try:
        tree = parse_tree(text, WHITELIST)
        check_tree(tree, WHITELIST)
        value = fold(tree, _FloatBuilder(text))
    except ForbiddenConstruct as error:
        raise ExpressionError(text, error.construct, str(error)) from None
    except ExpressionError:
        raise
    except (ArithmeticError, ValueError) as error:
        raise ExpressionError(text, "", f"{text!r} cannot be evaluated: {error}") from None
    if not math.isfinite(value):
        raise ExpressionError(text, "", f"{text!r} = {value} is not finite")
    return value


def is_expression(text: str) -> bool:
    """Whether a string in a loading stage is an expression, not a name.

    A string that is a Python identifier (``"F2_lateral"``, ``"current"``) is a
    parameter name or ``"current"``, except the constants ``pi`` and ``e``;
    anything else (``"pi/4"``, ``"0.5"``, ``"2*pi"``) is an expression.
    """
    stripped = text.strip()
    return not stripped.isidentifier() or stripped in CONSTANTS
