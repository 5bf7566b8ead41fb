"""Whitelisted arithmetic syntax: text is parsed, checked node by node, then folded.

One parser for every formula or number a user types: the constant expressions
of study files (``alpha0 = "pi/4"``, :mod:`ncstab.studies.expressions`) and the
formulas of user laws (``tangential = "gamma*sin(alpha - alpha0)"``,
:mod:`ncstab.laws.formula`).  Text goes through :func:`ast.parse` (which builds
a tree and runs nothing), then :func:`check_tree` walks the whole tree against
a :class:`Whitelist` *before anything is computed*: numbers, the whitelisted
names, unary ``+``/``-``, the binary operators ``+ - * / **`` and calls of
whitelisted functions with positional arguments.  Anything else (attributes,
subscripts, keyword arguments, strings, lambdas, comprehensions, comparisons,
...) raises :class:`ForbiddenConstruct` naming the offending construct.  Only a
checked tree is folded (:func:`fold`), bottom-up, by a builder that gives the
nodes their meaning (floats for study numbers, sympy for law formulas).  No
text is ever compiled, ``eval``-ed or handed to ``sympify``.
"""

from __future__ import annotations

import ast
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any, Protocol

__all__ = [
    "BINARY_OPERATORS",
    "UNARY_OPERATORS",
    "ForbiddenConstruct",
    "Whitelist",
    "Builder",
    "check_tree",
    "fold",
    "parse_tree",
    "source",
]

#: Binary operators of the whitelist, by their AST node type.
BINARY_OPERATORS: dict[type, str] = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**"}
#: Unary operators of the whitelist.
UNARY_OPERATORS: dict[type, str] = {ast.UAdd: "+", ast.USub: "-"}

_OTHER_OPERATORS = {
    ast.FloorDiv: "//", ast.Mod: "%", ast.MatMult: "@", ast.LShift: "<<", ast.RShift: ">>",
    ast.BitOr: "|", ast.BitAnd: "&", ast.BitXor: "^", ast.Not: "not", ast.Invert: "~",
}
_KINDS = {
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


class ForbiddenConstruct(ValueError):
    """A construct outside the whitelist, or text that is not an expression.

    Attributes
    ----------
    construct
        The offending part of the text (``"os.system"``, ``"**"``, ``"x"``), or
        ``""`` when the whole text is at fault (syntax, length, nesting).
    """

    def __init__(self, construct: str, message: str) -> None:
        self.construct = construct
        super().__init__(message)


@dataclass(frozen=True)
class Whitelist:
    """What a text may contain besides numbers, ``+ - * / **`` and parentheses.

    Attributes
    ----------
    names
        Names allowed as values (``pi``; a law's ``l``, ``alpha``, ...).
    functions
        Function name -> allowed numbers of positional arguments.
    allowed
        One line saying what is allowed, for messages.
    unknown_name
        Message for a name that is not allowed (receives the name).
    max_length, max_depth, max_nodes
        Limits on the text (characters), the nesting of the tree and its size.
    """

    names: frozenset[str]
    functions: Mapping[str, tuple[int, ...]]
    allowed: str
    unknown_name: Callable[[str], str] = field(default=lambda name: f"name {name!r} is not allowed")
    max_length: int = 200
    max_depth: int = 64
    max_nodes: int = 1000


def source(node: ast.AST, limit: int = 60) -> str:
    """The text of a node (``ast.unparse`` builds text from the tree; it evaluates nothing)."""
    text = ast.unparse(node)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def parse_tree(text: str, whitelist: Whitelist) -> ast.expr:
    """The syntax tree of ``text`` (one expression), its length checked.

    Raises
    ------
    ForbiddenConstruct
        Empty or too long text, or text that is not an expression
        (``construct`` is ``""``).
    """
    stripped = text.strip()
    if not stripped:
        raise ForbiddenConstruct("", "empty expression")
    if len(stripped) > whitelist.max_length:
        raise ForbiddenConstruct("", f"expression longer than {whitelist.max_length} characters")
    try:
        tree = ast.parse(stripped, mode="eval")
    except SyntaxError as error:
        raise ForbiddenConstruct(
            "", f"{text!r} is not a valid expression ({error.msg}); allowed: {whitelist.allowed}"
        ) from None
    except (ValueError, RecursionError, MemoryError):
        raise ForbiddenConstruct("", f"{text!r} is not a valid expression; allowed: {whitelist.allowed}") from None
    return tree.body


def check_tree(node: ast.expr, whitelist: Whitelist) -> None:
    """Walk the whole tree; raise at the first construct outside the whitelist.

    Nothing is computed here: the check is on the tree's node types, names
    and call forms only.  The walk is iterative (a deep tree cannot exhaust the
    interpreter's stack) and bounded by ``whitelist.max_depth`` and
    ``max_nodes``.

    Raises
    ------
    ForbiddenConstruct
        Naming the construct and what is allowed.
    """
    pending: list[tuple[ast.AST, int]] = [(node, 1)]
    seen = 0
    while pending:
        current, depth = pending.pop()
        seen += 1
        if depth > whitelist.max_depth:
            raise ForbiddenConstruct("", f"expression nested more than {whitelist.max_depth} levels deep")
        if seen > whitelist.max_nodes:
            raise ForbiddenConstruct("", f"expression with more than {whitelist.max_nodes} terms")
        pending.extend((child, depth + 1) for child in _checked_children(current, whitelist))


def _checked_children(node: ast.AST, whitelist: Whitelist) -> list[ast.AST]:
    """The children of a whitelisted node (raises for any other node)."""
    if isinstance(node, ast.Constant):
        value = node.value
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ForbiddenConstruct(
                source(node), f"{type(value).__name__} constant {source(node)} is not allowed; allowed: {whitelist.allowed}"
            )
        if isinstance(value, float) and not math.isfinite(value):
            raise ForbiddenConstruct(source(node), f"{source(node)} is not finite (too large for a floating-point number)")
        return []
    if isinstance(node, ast.Name):
        if node.id in whitelist.names:
            return []
        if node.id in whitelist.functions:
            raise ForbiddenConstruct(node.id, f"function {node.id!r} must be called, e.g. {node.id}(2)")
        raise ForbiddenConstruct(node.id, whitelist.unknown_name(node.id))
    if isinstance(node, ast.UnaryOp):
        if type(node.op) not in UNARY_OPERATORS:
            symbol = _OTHER_OPERATORS.get(type(node.op), type(node.op).__name__)
            raise ForbiddenConstruct(symbol, f"operator {symbol!r} is not allowed; allowed: {whitelist.allowed}")
        return [node.operand]
    if isinstance(node, ast.BinOp):
        if type(node.op) not in BINARY_OPERATORS:
            symbol = _OTHER_OPERATORS.get(type(node.op), type(node.op).__name__)
            raise ForbiddenConstruct(symbol, f"operator {symbol!r} is not allowed; allowed: {whitelist.allowed}")
        return [node.right, node.left]
    if isinstance(node, ast.Call):
        if not isinstance(node.func, ast.Name) or node.func.id not in whitelist.functions:
            name = source(node.func)
            functions = ", ".join(whitelist.functions) or "none"
            raise ForbiddenConstruct(name, f"call of {name!r} is not allowed; the functions are: {functions}")
        name = node.func.id
        if node.keywords:
            keyword = node.keywords[0]
            shown = f"{keyword.arg}=" if keyword.arg else "**"
            raise ForbiddenConstruct(shown, f"keyword argument {shown!r} in a call of {name} is not allowed")
        if any(isinstance(argument, ast.Starred) for argument in node.args):
            raise ForbiddenConstruct("*", f"starred argument in a call of {name} is not allowed")
        arities = whitelist.functions[name]
        if len(node.args) not in arities:
            expected = " or ".join(map(str, arities))
            raise ForbiddenConstruct(source(node), f"{name} takes {expected} argument(s), got {len(node.args)}")
        return list(reversed(node.args))
    kind = _KINDS.get(type(node), type(node).__name__)
    raise ForbiddenConstruct(source(node), f"{kind} {source(node)!r} is not allowed; allowed: {whitelist.allowed}")


class Builder(Protocol):
    """Gives the nodes of a checked tree their meaning (see :func:`fold`)."""

    def number(self, value: int | float, node: ast.Constant) -> Any: ...

    def name(self, name: str, node: ast.Name) -> Any: ...

    def unary(self, operator: str, operand: Any, node: ast.UnaryOp) -> Any: ...

    def binary(self, operator: str, left: Any, right: Any, node: ast.BinOp) -> Any: ...

    def call(self, function: str, arguments: list[Any], node: ast.Call) -> Any: ...


def fold(node: ast.expr, builder: Builder) -> Any:
    """Fold a tree that :func:`check_tree` accepted, bottom-up, with ``builder``.

    Iterative (post-order on an explicit stack): the depth of the tree was
    bounded by the check, and no Python recursion limit is involved.
    """
    values: list[Any] = []
    pending: list[tuple[ast.AST, bool]] = [(node, False)]
    while pending:
        current, children_done = pending.pop()
        children = _children(current)
        if children and not children_done:
            pending.append((current, True))
            pending.extend((child, False) for child in reversed(children))
            continue
        arguments = values[len(values) - len(children):] if children else []
        if children:
            del values[len(values) - len(children):]
        values.append(_apply(current, arguments, builder))
    return values[0]


def _children(node: ast.AST) -> list[ast.AST]:
    if isinstance(node, ast.UnaryOp):
        return [node.operand]
    if isinstance(node, ast.BinOp):
        return [node.left, node.right]
    if isinstance(node, ast.Call):
        return list(node.args)
    return []


def _apply(node: ast.AST, arguments: list[Any], builder: Builder) -> Any:
    if isinstance(node, ast.Constant):
        return builder.number(node.value, node)
    if isinstance(node, ast.Name):
        return builder.name(node.id, node)
    if isinstance(node, ast.UnaryOp):
        return builder.unary(UNARY_OPERATORS[type(node.op)], arguments[0], node)
    if isinstance(node, ast.BinOp):
        return builder.binary(BINARY_OPERATORS[type(node.op)], arguments[0], arguments[1], node)
    if isinstance(node, ast.Call):
        assert isinstance(node.func, ast.Name)
        return builder.call(node.func.id, arguments, node)
    raise AssertionError(f"unchecked node {type(node).__name__}")  # pragma: no cover - check_tree first
