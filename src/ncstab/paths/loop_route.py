"""Which route runs the stage loop: its machine code (numba) or its text as plain Python.

The compiled stage loop (:mod:`ncstab.paths.compiled`) takes about a minute to
compile the first time on a machine (then numba's cache serves it at once).  A
study of a few cases of a small system needs only a few seconds of stepping in
plain Python.  So, unless told otherwise, a batch runs on

* the machine code where numba's cache already holds it (a fast start, fast steps);
* else, as plain Python (:func:`ncstab.plain_python.plain_module`: the same text,
  the same numbers) when its estimated work is small: :data:`PYTHON_WORK`;
* else the machine code, compiled now (ncstab says so on a terminal).

``PathOptions.backend`` (a study file's ``[options] backend``) overrides the
choice: ``"compiled"`` (always the machine code), ``"python"`` (always plain
Python: slow, for a reader following the loop in a debugger) or ``"auto"`` (the
default, as above).  A kernel's evaluation of stored states for the Dataset
follows the same rule (:func:`evaluates_plain`).
"""

from __future__ import annotations

import os
from typing import Any

__all__ = ["PYTHON_ROWS", "PYTHON_WORK", "evaluates_plain", "machine_code_cached", "runs_plain"]

#: The largest batch run as plain Python when the machine code is not cached yet:
#: cases x (state size)^3.  A step of the loop in plain Python costs about as the cube
#: of the state size (the tangent's factorization of a small dense system, the model's
#: kernel): 0.5 ms per unit of this work for a whole case, measured on 441 cases of
#: Ziegler's pendulum (state size 4: 13.5 s) and on a ring of six grains (state size
#: 14: 1.5 s a case).  At the bound, about 30 s of plain Python, against 30-120 s of
#: compiling (benchmarks/bench_cold_start.py).
PYTHON_WORK = 60_000
#: The most states a kernel evaluates as plain Python for the Dataset when its machine
#: code is not cached yet: a ring of six grains' kernel takes about 0.2 ms a state in
#: plain Python (3 s at the bound), and 4-8 s to compile.
PYTHON_ROWS = 16_384


def machine_code_cached(function: Any, kind: Any = None) -> bool:
    """Whether numba's cache on disk holds machine code of ``function`` (a dispatcher
    compiled with ``cache=True``): its index file exists; with ``kind``, a model's record
    (:mod:`ncstab.paths.loop_records`), the index holds code for that kind of model (the
    loop's entry points are compiled once per kind, into one index)."""
    cache_file = getattr(getattr(function, "_cache", None), "_cache_file", None)
    index = getattr(cache_file, "_index_path", None)
    if not (index and os.path.exists(index)):
        return False
    return kind is None or any(type(kind).__name__ in str(key[0]) for key in cache_file._load_index())


def runs_plain(backend: str, cases: int, state_size: int, entry: Any, kind: Any = None) -> bool:
    """Whether a batch of ``cases`` cases of state size ``state_size`` runs as plain
    Python under ``backend`` (``PathOptions.backend``), the loop's compiled entry point
    being ``entry`` and the model's record ``kind`` (see the module docstring)."""
    if backend != "auto":
        return backend == "python"
    if machine_code_cached(entry, kind):
        return False
    return cases * state_size**3 <= PYTHON_WORK


def evaluates_plain(rows: int, entry: Any) -> bool:
    """Whether a kernel evaluates ``rows`` states as plain Python, its compiled batch
    function being ``entry`` (the rule of ``"auto"`` in :func:`runs_plain`)."""
    return not machine_code_cached(entry) and rows <= PYTHON_ROWS
