"""The decorators of the compiled stage loop's functions.

The loop's modules (:mod:`ncstab.paths.loop_cases` and the modules it calls) are
compiled into the machine code of the loop's three entry points (:func:`entry`),
which numba caches in ncstab's cache folder (:mod:`ncstab.engine_cache`): no other
function is cached, and none is called from Python, so no CPython or C wrapper
is built for them (:data:`njit`, :data:`hot`).  Under the plain-Python route
(:mod:`ncstab.plain_python`) the decorators leave a function as it is.
"""

from __future__ import annotations

import warnings

import numba
from numba.core.errors import NumbaIRAssumptionWarning

from ncstab.engine_cache import register_engine_cache

__all__ = ["entry", "hot", "njit"]

#: A function of the loop, compiled into its callers' machine code.  Without a Python
#: wrapper (16 s of the general models' 75 s of compilation): called from Python it would
#: crash; read and run the loop's modules as plain Python instead
#: (:func:`ncstab.plain_python.plain_import`, ``backend = "python"``).
njit = numba.njit(cache=False, error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)

#: One of every DOP853 stage (the model's evaluation and tangent, the stage sums),
#: inlined in numba's IR where it is called: a third off the stepping for 6 s of the first
#: compilation (docs/paths.md).
hot = numba.njit(cache=False, error_model="numpy", inline="always")

register_engine_cache()  # before the entry points are decorated

#: An entry point of the loop (``run_cases``, ``start``, ``settle``), called from Python:
#: cached in ncstab's cache folder with everything it calls (:mod:`ncstab.engine_cache`),
#: releasing the GIL (the cases of a stage run on threads side by side).
entry = numba.njit(cache=True, error_model="numpy", nogil=True)

# numba's IR inliner runs a pedantic check of its own that warns ("variable ... is not in
# scope") where an inlined function inlines others (dy/ds in the DOP853 stages); the
# machine code is right (tests/test_plain_python.py compares it with plain Python, bit for
# bit), and a user would read the warning as ncstab's.
warnings.filterwarnings("ignore", category=NumbaIRAssumptionWarning)
