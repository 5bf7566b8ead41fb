"""The engine's generated modules run by CPython: the same text, no machine code.

ncstab's stage loops and kernels are Python modules that numba compiles
(:mod:`ncstab.generated_modules`).  Compiling them takes about a minute per
loop the first time on a machine; a study of a few cases needs a few seconds of
stepping.  :func:`plain_module` executes the *same text* as ordinary Python, so
that a small study gives its first results at once (:mod:`ncstab.paths.loop_route`
decides which one runs).  Nothing is re-implemented: the text is executed with

* ``numba`` standing for a stand-in whose ``njit``, ``cfunc`` and ``vectorize``
  leave each function as it is, and whose ``carray`` reads a pointer (``a.ctypes``,
  as the loop passes arrays to a kernel's C callback) back as a numpy view;
* ``math`` standing for the math module whose functions give numpy's value where
  CPython's raise (``sqrt(-1)`` is NaN, ``log(0)`` is -inf), as numba's compiled code
  does (``error_model="numpy"``);
* the engine's modules of compiled functions that a generated module imports
  (:data:`PLAIN_IMPORTS`) standing for their own text run the same way.

The two give the same numbers (the arithmetic is the same IEEE operations in
the same order, and the elementary functions are the C library's in both:
tests/test_plain_python.py compares whole archives bit for bit).  One
difference stays: a division by zero between two Python floats raises
``ZeroDivisionError`` where compiled code gives an infinity;
:func:`ncstab.paths.stepper.follow_cases` then runs the batch again compiled.
"""

from __future__ import annotations

import builtins
import ctypes
import functools
import importlib.util
import math
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["PLAIN_ERRORS", "PLAIN_IMPORTS", "plain_file", "plain_import", "plain_module"]

#: What the plain text may raise where compiled code returns inf or NaN: the caller
#: runs the work again compiled (``ZeroDivisionError`` of two Python floats, above all).
PLAIN_ERRORS = (ArithmeticError, ValueError)


def _keep(*args: Any, **kwargs: Any) -> Any:
    """``numba.njit`` / ``numba.cfunc`` as a decorator or a decorator factory: the function itself."""
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return args[0]
    return lambda function: function


def _carray(pointer: Any, shape: Any, dtype: Any = float) -> np.ndarray:
    """``numba.carray``: the array behind ``pointer`` (a numpy array's ``.ctypes``), viewed."""
    if isinstance(pointer, np.ndarray):
        return pointer
    item = np.ctypeslib.as_ctypes_type(np.dtype(dtype))
    return np.ctypeslib.as_array(pointer.data_as(ctypes.POINTER(item)), shape=tuple(np.atleast_1d(shape)))


_NUMBA = types.SimpleNamespace(
    njit=_keep, jit=_keep, cfunc=_keep, carray=_carray, vectorize=lambda *a, **k: np.vectorize, types=None,
    extending=types.SimpleNamespace(overload=lambda *a, **k: lambda function: function),
)


#: math functions whose numpy ufunc has another name.
_NUMPY_NAMES = {
    "acos": "arccos", "asin": "arcsin", "atan": "arctan", "atan2": "arctan2", "acosh": "arccosh",
    "asinh": "arcsinh", "atanh": "arctanh", "pow": "power",
}


def _numpy_like(name: str, function: Callable[..., float]) -> Callable[..., float]:
    """``function`` of the math module, but where it raises (an argument outside its
    domain, a result that overflows) numpy's value instead, as numba's compiled code
    gives it (``error_model="numpy"``): ``sqrt(-1)`` is NaN, ``log(0)`` is -inf."""
    ufunc = getattr(np, _NUMPY_NAMES.get(name, name), None)

    @functools.wraps(function)
    def guarded(*args: Any) -> float:
        try:
            return function(*args)
        except (ValueError, OverflowError):
            if ufunc is None:
                return math.nan
            with np.errstate(all="ignore"):
                return float(ufunc(*args))

    return guarded


_MATH = types.ModuleType("math")
_MATH.__dict__.update(
    {name: (_numpy_like(name, value) if callable(value) and not isinstance(value, type) else value)
     for name, value in vars(math).items() if not name.startswith("__")}
)
_STAND_INS = {"numba": _NUMBA, "math": _MATH}


#: The engine's modules of compiled functions that the generated modules import
#: (``from ... import ...``, directly or through each other): run as plain Python too,
#: from their own files.  The stage loop is these modules (:mod:`ncstab.paths.loop_cases`
#: and what it calls), whose decorators come from :mod:`ncstab.jit`.
PLAIN_IMPORTS = (
    "ncstab.jit", "ncstab.paths.loop_numerics", "ncstab.paths.loop_signs", "ncstab.paths.bracket",
    "ncstab.paths.cofactor",
    "ncstab.operators.one_state", "ncstab.operators.onset_cases", "ncstab.paths.loop_diamond_model", "ncstab.paths.loop_diamond",
    "ncstab.paths.loop_general", "ncstab.paths.loop_general_output", "ncstab.paths.loop_dispatch",
    "ncstab.paths.loop_steps", "ncstab.paths.loop_step_limits", "ncstab.paths.loop_start", "ncstab.paths.loop_cases",
)


def _import(name: str, globals: Any = None, locals: Any = None, fromlist: Any = (), level: int = 0) -> Any:
    if level == 0 and name in _STAND_INS:
        return _STAND_INS[name]
    if level == 0 and name in PLAIN_IMPORTS and fromlist:
        return plain_import(name)
    package = builtins.__import__(name, globals, locals, fromlist, level)
    if level == 0 and fromlist and any(f"{name}.{item}" in PLAIN_IMPORTS for item in fromlist):
        # ``from ncstab.paths import loop_diamond``: the plain module for each engine module named
        return types.SimpleNamespace(**{
            item: plain_import(f"{name}.{item}") if f"{name}.{item}" in PLAIN_IMPORTS else getattr(package, item)
            for item in fromlist
        })
    return package


def plain_import(name: str) -> types.ModuleType:
    """The engine's module ``name`` (one of :data:`PLAIN_IMPORTS`) run as plain Python."""
    return plain_file(name, importlib.util.find_spec(name).origin)


_BUILTINS = {**vars(builtins), "__import__": _import}


@functools.cache
def plain_file(name: str, path: str) -> types.ModuleType:
    """The generated module ``name`` at ``path`` executed as plain Python (once per process)."""
    module = types.ModuleType(f"{name}_plain", f"{name}, run by CPython (ncstab.plain_python)")
    module.__dict__.update(__builtins__=_BUILTINS, __file__=path)
    code = compile(Path(path).read_text(encoding="utf-8"), path, "exec")
    exec(code, module.__dict__)  # noqa: S102 - ncstab's own generated module, never a user's text
    return module


def plain_module(module: types.ModuleType) -> types.ModuleType:
    """The generated module ``module`` (:func:`ncstab.generated_modules.load_named_module`)
    executed again from its file as plain Python: its functions are Python functions, none
    compiled (once per module and process)."""
    return plain_file(module.__name__, str(module.__file__))
