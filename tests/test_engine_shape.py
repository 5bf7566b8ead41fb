"""The engine's shape, which the readers of src/ncstab/paths rely on.

Two limits a newcomer can read the engine by: no module of ``ncstab.paths`` over
400 lines, and no function there with more than 12 parameters (a case's arrays
travel in the named records of :mod:`ncstab.paths.loop_records`).  The only
exceptions are the template parts of the compiled loop, whose parameters are the
names they take from the parts pasted before them (they are never called); they
go when the loop is no longer pasted together.
"""

from __future__ import annotations

import ast
from pathlib import Path

import ncstab.paths

PATHS = Path(ncstab.paths.__file__).parent
MAX_LINES = 400
MAX_PARAMETERS = 12
#: The template parts of the compiled loop (:mod:`ncstab.paths.compiled_source` pastes
#: their bodies): their parameters are names, not arguments.
TEMPLATE_PARTS = {
    ("loop_cases.py", "cases_part"), ("loop_general_output.py", "general_output_part"),
    ("loop_steps.py", "steps_part"),
}


def _functions(path: Path):
    tree = ast.parse(path.read_text(encoding="utf-8"))
    for node in ast.walk(tree):
        if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
            arguments = node.args
            count = len(arguments.posonlyargs) + len(arguments.args) + len(arguments.kwonlyargs)
            count -= bool(arguments.args) and arguments.args[0].arg in ("self", "cls")
            yield node.name, count


def test_no_module_of_the_engine_is_over_400_lines():
    long = {path.name: n for path in PATHS.glob("*.py") if (n := len(path.read_text().splitlines())) > MAX_LINES}
    assert long == {}


def test_no_function_of_the_engine_takes_more_than_12_parameters():
    over = {
        (path.name, name): count
        for path in sorted(PATHS.glob("*.py"))
        for name, count in _functions(path)
        if count > MAX_PARAMETERS and (path.name, name) not in TEMPLATE_PARTS
    }
    assert over == {}


def test_the_exceptions_are_still_over_the_limit():
    # an exception that is gone from the code, or back within the limit, must leave the list
    counts = {(path.name, name): count for path in PATHS.glob("*.py") for name, count in _functions(path)}
    assert {part: counts.get(part, 0) > MAX_PARAMETERS for part in TEMPLATE_PARTS} == dict.fromkeys(TEMPLATE_PARTS, True)
