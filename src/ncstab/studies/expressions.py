"""Safe arithmetic expressions of pi in study files (``alpha0 = "pi/4"``).

An expression is parsed with :func:`ast.parse` and its tree is *walked*, never
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

_BINARY: dict[type, Callable[[float, float], float]] = {
    ast.Add: lambda a, b: a + b,
    ast.Sub: lambda a, b: a - b,
    ast.Mult: lambda a, b: a * b,
    ast.Div: lambda a, b: a / b,
    ast.Pow: math.pow,  # real results only: math.pow(-8, 1/3) raises, ** would give a complex
}
_UNARY: dict[type, Callable[[float], float]] = {
    ast.UAdd: lambda a: +a,
    ast.USub: lambda a: -a,
}
_OPERATOR_SYMBOLS = {
    ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>",
    ast.BitOr: "|", ast.BitAnd: "&", ast.BitXor: "^", ast.Not: "not", ast.Invert: "~",
}
ALLOWED = (
    "numbers, pi, e, + - * / ** and parentheses, and the functions "
    + ", ".join(FUNCTIONS)
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


def _source(node: ast.AST, limit: int = 60) -> str:
    text = ast.unparse(node)  # turns the tree back into text; evaluates nothing
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _describe(node: ast.AST) -> str:
    """A user-facing name for a construct that is not allowed."""
    kinds = {
        ast.Attribute: "attribute access",
        ast.Subscript: "subscript",
        ast.Lambda: "lambda",
        ast.ListComp: "comprehension",
        ast.SetComp: "comprehension",
        ast.DictComp: "comprehension",
        ast.GeneratorExp: "generator expression",
        ast.Compare: "comparison",
        ast.BoolOp: "boolean operator",
        ast.IfExp: "conditional expression",
        ast.NamedExpr: "assignment expression",
        ast.JoinedStr: "f-string",
        ast.List: "list",
        ast.Tuple: "tuple",
        ast.Dict: "dict",
        ast.Set: "set",
        ast.Starred: "starred expression",
        ast.Await: "await",
        ast.Yield: "yield",
        ast.YieldFrom: "yield",
        ast.Slice: "slice",
    }
    return kinds.get(type(node), type(node).__name__)


def _walk(node: ast.AST, text: str) -> float:
    if isinstance(node, ast.Expression):
        return _walk(node.body, text)
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ExpressionError(
                text, _source(node), f"{type(value).__name__} constant {_source(node)} is not allowed; allowed: {ALLOWED}"
            )
        return float(value)
    if isinstance(node, ast.Name):
        if node.id in CONSTANTS:
            return CONSTANTS[node.id]
        if node.id in FUNCTIONS:
            raise ExpressionError(text, node.id, f"function {node.id!r} must be called, e.g. {node.id}(2)")
        raise ExpressionError(
            text, node.id,
            f"name {node.id!r} is not allowed in an expression (only pi and e); "
            "a parameter is referred to by its name alone, not inside an expression",
        )
    if isinstance(node, ast.UnaryOp):
        operation = _UNARY.get(type(node.op))
        if operation is None:
            symbol = _OPERATOR_SYMBOLS.get(type(node.op), type(node.op).__name__)
            raise ExpressionError(text, symbol, f"operator {symbol!r} is not allowed; allowed: {ALLOWED}")
        return operation(_walk(node.operand, text))
    if isinstance(node, ast.BinOp):
        operation = _BINARY.get(type(node.op))
        if operation is None:
            symbol = _OPERATOR_SYMBOLS.get(type(node.op), type(node.op).__name__)
            raise ExpressionError(text, symbol, f"operator {symbol!r} is not allowed; allowed: {ALLOWED}")
        left = _walk(node.left, text)
        right = _walk(node.right, text)
        if isinstance(node.op, ast.Pow) and abs(right) > MAX_EXPONENT:
            raise ExpressionError(
                text, _source(node), f"exponent {right:g} in {_source(node)!r} is too large (at most {MAX_EXPONENT:g})"
            )
        return operation(left, right)
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS:
            name = _source(node.func)
            raise ExpressionError(
                text, name, f"call of {name!r} is not allowed; the functions are: {', '.join(FUNCTIONS)}"
            )
        function, arities = FUNCTIONS[node.func.id]
        if node.keywords:
            keyword = node.keywords[0]
            shown = f"{keyword.arg}=" if keyword.arg else "**"
            raise ExpressionError(
                text, shown, f"keyword argument {shown!r} in a call of {node.func.id} is not allowed"
            )
        if any(isinstance(arg, ast.Starred) for arg in node.args):
            raise ExpressionError(text, "*", f"starred argument in a call of {node.func.id} is not allowed")
        if len(node.args) not in arities:
            expected = " or ".join(map(str, arities))
            raise ExpressionError(
                text, _source(node), f"{node.func.id} takes {expected} argument(s), got {len(node.args)}"
            )
        arguments = [_walk(arg, text) for arg in node.args]
        return function(*arguments)
    raise ExpressionError(
        text, _source(node), f"{_describe(node)} {_source(node)!r} is not allowed; allowed: {ALLOWED}"
    )


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
    stripped = text.strip()
    if not stripped:
        raise ExpressionError(text, "", "empty expression")
    if len(stripped) > MAX_LENGTH:
        raise ExpressionError(text, "", f"expression longer than {MAX_LENGTH} characters")
    try:
        tree = ast.parse(stripped, mode="eval")
    except SyntaxError as error:
        raise ExpressionError(text, "", f"{text!r} is not a valid expression ({error.msg}); allowed: {ALLOWED}") from None
    except (ValueError, RecursionError, MemoryError):
        raise ExpressionError(text, "", f"{text!r} is not a valid expression; allowed: {ALLOWED}") from None
    try:
        value = _walk(tree, text)
    except ExpressionError:
        raise
    except RecursionError:
        raise ExpressionError(text, "", f"{text!r} is nested too deeply") from None
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
