"""xarray's test for dask arrays, answered without importing ``dask.array`` first.

Each time xarray builds a variable from data (``as_compatible_data``: every
variable of an archive it decodes, every variable of a Dataset ncstab
assembles) it asks ``isinstance(data, array_type("dask"))``; the first time,
:class:`xarray.namedarray.pycompat.DuckArrayModule` imports ``dask.array`` to
find that class, where dask is installed (the ``test`` and ``distributed``
extras).  That import costs 0.8-0.9 s on a 2-core machine, a sixth of
``ncstab plot``, and the commands never make a dask array.

:func:`defer_dask_array_import` gives xarray's cache of that probe a class
whose instance check asks the real ``dask.array.Array`` once ``dask.array``
has been imported, and answers False before (no object can be an instance of a
class not yet defined).  So the answer is always the one xarray would give, and
a process that later makes dask arrays (a cluster run) still has them
recognised.  xarray only uses the probe's ``type`` and ``version``
(``array_type``, ``mod_version``; checked in the tests).  The commands that
read or build Datasets (``ncstab run``, ``ncstab plot``) call it; as a
library, ncstab leaves xarray as it is.  Where xarray's private cache is not
as expected (another xarray version), nothing is changed.
"""

from __future__ import annotations

import importlib.metadata
import importlib.util
import sys
from typing import Any

__all__ = ["defer_dask_array_import"]


class _DeferredDaskArrayType(type):
    """Metaclass of :class:`DeferredDaskArray`: its instances are dask arrays, once dask.array exists."""

    def __instancecheck__(cls, instance: Any) -> bool:
        module = sys.modules.get("dask.array")
        return module is not None and isinstance(instance, module.Array)

    def __subclasscheck__(cls, subclass: type) -> bool:
        module = sys.modules.get("dask.array")
        return module is not None and issubclass(subclass, module.Array)


class DeferredDaskArray(metaclass=_DeferredDaskArrayType):
    """Stands for ``dask.array.Array`` in xarray's probe until dask.array is imported."""


def defer_dask_array_import() -> bool:
    """Give xarray's dask probe :class:`DeferredDaskArray`; whether it was given.

    Nothing is changed where dask is absent (xarray's probe is then cheap),
    where ``dask.array`` is already imported (nothing to save), where xarray
    already probed, or where its private cache is not the one this was
    written for.
    """
    if "dask.array" in sys.modules or importlib.util.find_spec("dask") is None:
        return False
    try:
        from xarray.namedarray import pycompat
    except ImportError:  # pragma: no cover - xarray is a dependency
        return False
    cache = getattr(pycompat, "_cached_duck_array_modules", None)
    module_type = getattr(pycompat, "DuckArrayModule", None)
    version_type = getattr(pycompat, "Version", None)
    if not isinstance(cache, dict) or module_type is None or version_type is None or "dask" in cache:
        return False
    try:
        version = version_type(importlib.metadata.version("dask"))
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return False
    probe = object.__new__(module_type)
    probe.module = None  # xarray reads only .type and .version of the dask probe
    probe.version = version
    probe.type = (DeferredDaskArray,)
    probe.available = True
    cache["dask"] = probe
    return True
