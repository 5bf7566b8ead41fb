"""The engine's shape, which the readers of src/ncstab/paths rely on.

Three limits a newcomer can read the engine by: no module of ``ncstab.paths`` over
400 lines, no function there with more than 12 parameters (a case's arrays
travel in the named records of :mod:`ncstab.paths.loop_records`), and no source
pasted together from template parts: the compiled loop is plain modules whose
functions call each other (the only generated text is the small entry module of
:func:`ncstab.paths.compiled_source.loop_source` and the law kernels printed from
sympy).
"""

from __future__ import annotations

import ast
from pathlib import Path

import ncstab.paths

PATHS = Path(ncstab.paths.__file__).parent
MAX_LINES = 400
MAX_PARAMETERS = 12


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
        if count > MAX_PARAMETERS
    }
    assert over == {}


def test_nothing_in_the_engine_is_a_template():
    # grep -ri template src/ncstab/paths: no part pasted into another module's text
    named = [path.name for path in PATHS.glob("*.py") if "template" in path.read_text(encoding="utf-8").lower()]
    assert named == []


def test_the_loop_s_modules_are_what_the_plain_route_runs_and_the_cache_folder_hashes():
    # every module of the loop's compiled functions runs as plain Python on the plain route
    # (ncstab.plain_python) and its text is part of the name of the loop's cache folder
    from ncstab.engine_cache import ENGINE_MODULES
    from ncstab.plain_python import PLAIN_IMPORTS

    loop_modules = {f"ncstab.paths.{path.stem}" for path in PATHS.glob("loop_*.py")} - {
        "ncstab.paths.loop_records", "ncstab.paths.loop_route",
    }
    assert loop_modules <= set(PLAIN_IMPORTS) <= set(ENGINE_MODULES)
