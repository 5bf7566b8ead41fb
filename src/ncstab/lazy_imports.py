"""Public names of a package imported on first use (PEP 562 module ``__getattr__``).

``ncstab --version`` must not import sympy, and ``ncstab info`` must not import
the path engine (scipy, numba): so ``ncstab``, ``ncstab.paths`` and
``ncstab.studies`` import the modules behind their public names only when a
name is first used.  Every name stays importable as before
(``from ncstab import follow``, ``ncstab.open_study``), and so does every
submodule as an attribute of its package (``ncstab.studies.chunked``).
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Mapping
from typing import Any

__all__ = ["lazy_attributes", "lazy_function"]


def lazy_attributes(
    package: str, names: Mapping[str, str], namespace: dict[str, Any]
) -> tuple[Callable[[str], Any], Callable[[], list[str]]]:
    """The module ``__getattr__`` and ``__dir__`` of a package whose names are imported on use.

    Parameters
    ----------
    package
        The package's ``__name__``.
    names
        Public name -> the module that defines it (absolute, ``"ncstab.paths.api"``).
    namespace
        The package's ``globals()``: a name, once imported, is kept there, so the
        next lookup does not go through ``__getattr__``.

    Returns
    -------
    (__getattr__, __dir__)
        ``__getattr__(name)`` imports ``names[name]`` and returns its attribute, or
        imports the submodule ``package.name``; ``AttributeError`` otherwise.
    """

    def __getattr__(name: str) -> Any:
        module = names.get(name)
        if module is None:
            try:
                return importlib.import_module(f"{package}.{name}")
            except ModuleNotFoundError as error:
                if error.name != f"{package}.{name}":
                    raise
                raise AttributeError(f"module {package!r} has no attribute {name!r}") from None
        value = getattr(importlib.import_module(module), name)
        namespace[name] = value
        return value

    def __dir__() -> list[str]:
        return sorted(set(namespace) | set(names))

    return __getattr__, __dir__


def lazy_function(module: str, name: str) -> Callable[..., Any]:
    """``module.name``, a function imported at its first call: a registry names the builders of
    every system without importing them (the packing reader, scipy) until one is built."""

    def call(*args: Any, **kwargs: Any) -> Any:
        return getattr(importlib.import_module(module), name)(*args, **kwargs)

    call.__name__ = call.__qualname__ = name
    call.__doc__ = f"``{module}.{name}``, imported at its first call."
    return call
