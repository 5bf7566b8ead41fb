"""Generated state kernels kept on disk: sympy derives a law's kernel once per machine, not per process.

:func:`ncstab.operators.tangent.compile_state_kernel` assembles, in sympy, the
forces, K and the internal-variable rate of a law on a system's symbolic
kinematics and lambdifies them with common-subexpression elimination: about
half a second per law, in every process that follows a path (``ncstab run``,
each dask worker).  The lambdified function is plain numpy source; it is kept
as text in the cache directory (:mod:`ncstab.cache`, folder
:data:`CACHE_KIND`) and a later process builds the function from that text,
without sympy's derivation.

An entry is named by the SHA-256 of everything the text depends on
(:func:`kernel_key`): the law's whole symbolic definition with the ncstab and
sympy versions (:func:`ncstab.symbolic.class_cache.definition_fingerprint`),
the system's class, and the source of the modules that generate the kernel
(this one's caller, the law derivation, the system's kinematics), so that an
edited generator never reads a stale kernel.  A fresh derivation and a cached
one build the function the same way, from the same text
(:func:`function_from_source`), so the two cannot differ.
"""

from __future__ import annotations

import builtins
import hashlib
import inspect
import json
import linecache
import re
import sys
import types
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np

from ncstab.cache import read_entry, write_entry

__all__ = ["CACHE_KIND", "cached_kernel", "function_from_source", "kernel_key", "numpy_namespace", "used_names"]

#: The cache's folder in the cache directory.
CACHE_KIND = "state_kernels"

#: The modules whose source the generated text depends on, besides the system's.
GENERATING_MODULES = ("ncstab.operators.tangent", "ncstab.symbolic.derivation", "ncstab.laws.definition")


def _source_digest(module_names: tuple[str, ...]) -> str:
    """SHA-256 of the source files of the named (imported) modules, in order."""
    digest = hashlib.sha256()
    for name in module_names:
        try:
            path = inspect.getsourcefile(sys.modules[name])
            digest.update(Path(path).read_bytes() if path else name.encode())
        except (KeyError, OSError, TypeError):
            digest.update(name.encode())
    return digest.hexdigest()


def kernel_key(system_type: type, definition: Any) -> str:
    """The name of a law's kernel entry on a system: 64 hexadecimal digits.

    Parameters
    ----------
    system_type
        The system's class (its ``symbolic_kinematics`` is part of the kernel).
    definition
        The law's definition.
    """
    from ncstab.symbolic.class_cache import definition_fingerprint

    description = {
        "what": "state_kernel",
        "system": f"{system_type.__module__}.{system_type.__qualname__}",
        "definition": definition_fingerprint(definition),
        "code": _source_digest((*GENERATING_MODULES, system_type.__module__)),
    }
    return hashlib.sha256(json.dumps(description, sort_keys=True).encode()).hexdigest()


def used_names(code: types.CodeType) -> set[str]:
    """The global names a compiled text reads, its nested functions' included."""
    names: set[str] = set()
    stack = [code]
    while stack:
        current = stack.pop()
        names.update(current.co_names)
        stack.extend(constant for constant in current.co_consts if isinstance(constant, types.CodeType))
    return names


def numpy_namespace(names: set[str]) -> dict[str, Any]:
    """The globals of a text lambdified with ``modules="numpy"``, for the ``names`` it reads.

    As sympy builds them (``import numpy; from numpy import *; from numpy.linalg
    import *``, then its imaginary unit ``I``, its numpy translation
    ``Heaviside``, ``Abs``, ``builtins`` and ``range``): ``numpy`` itself, the
    names of ``numpy.__all__``, those of ``numpy.linalg.__all__`` over them,
    sympy's over both; any other name is left to Python's builtins or a
    NameError.  Checked against sympy's own
    namespace for every name the kernels of the catalogue laws read
    (tests/test_engine_kernel.py).  Taking only the names read, instead of the
    star imports, saves importing numpy's submodules (0.3 s).
    """
    namespace: dict[str, Any] = {"numpy": np}
    numpy_names, linalg_names = set(np.__all__), set(np.linalg.__all__)
    for name in names - {"numpy"}:
        if name in _SYMPY_NUMPY_NAMES:
            namespace[name] = _SYMPY_NUMPY_NAMES[name]
        elif name in linalg_names:
            namespace[name] = getattr(np.linalg, name)
        elif name in numpy_names:
            namespace[name] = getattr(np, name)
    return namespace


#: sympy's additions to numpy's names in a lambdified function's namespace
#: (``sympy.utilities.lambdify``: NUMPY_DEFAULT, NUMPY_TRANSLATIONS, and what
#: ``lambdify`` adds to every namespace).
_SYMPY_NUMPY_NAMES: dict[str, Any] = {
    "I": 1j, "Heaviside": np.heaviside, "Abs": abs, "builtins": builtins, "range": range,
}


def function_from_source(source: str, key: str) -> Callable[..., Any]:
    """The function a lambdified source text defines, with sympy's numpy namespace.

    The text is registered with :mod:`linecache` under a name made from ``key``, so that
    :func:`inspect.getsource` reads it (the compiled stepper prints the kernel's source
    into a module of its own, :func:`ncstab.paths.compiled_source.kernel_source`).

    Raises
    ------
    ValueError
        When the text defines no function.
    """
    match = re.search(r"^def (\w+)\(", source, re.MULTILINE)
    if match is None:
        raise ValueError("a state kernel's source must define a function")
    filename = f"<ncstab-state-kernel-{key[:16]}>"
    linecache.cache[filename] = (len(source), None, source.splitlines(True), filename)
    code = compile(source, filename, "exec")
    namespace = numpy_namespace(used_names(code))
    exec(code, namespace)  # noqa: S102 (text that sympy generated here, or its copy in the cache)
    return namespace[match.group(1)]


def cached_kernel(system_type: type, definition: Any, derive: Callable[[], Callable[..., Any]]) -> Callable[..., Any]:
    """The kernel of ``definition`` on ``system_type``: built from its cached source if
    the cache holds it, else from the source of ``derive()`` (kept for next time).

    Parameters
    ----------
    system_type, definition
        What the kernel is of (:func:`kernel_key`).
    derive
        Derives the kernel with sympy (a lambdified function) when the cache has none.
    """
    key = kernel_key(system_type, definition)
    entry = read_entry(CACHE_KIND, key)
    source = entry.get("source") if entry is not None else None
    if isinstance(source, str):
        try:
            return function_from_source(source, key)
        except (SyntaxError, ValueError):  # a damaged entry: derived again and rewritten
            pass
    source = inspect.getsource(derive())
    write_entry(CACHE_KIND, key, {"source": source})
    return function_from_source(source, key)
