"""The compiled stepper: the engine's stepping loop as one numba loop per case.

Every case of every system runs through this loop, the cases of a stage
shared out over threads (:mod:`ncstab.paths.threads`,
:mod:`ncstab.paths.compiled_stages`).  Per case it takes DOP853 steps of the
unit tangent of the constrained rate system (the cofactor tangent, oriented
by continuity with the motion at the start of its step, so it goes straight
on through a singular point of the control), with scipy's tableau, error norm
and step-size control; projects each step's end onto equilibrium by Newton
for laws with a total form; cuts each accepted step into pieces of at most
``sample_step`` on its DOP853 interpolant, stores every piece's end and checks
its indicators' signs there; locates each sign change to ``event_tol`` by the
Illinois iteration on that interpolant; cuts the step at a stage target, a
stop event, a contact switch (``secondary_contacts = "activate"``: the spring
switches where its gap crossing cuts the step; a ``no_tension`` law's normal
contact opens or closes where its overlap crosses zero, :mod:`ncstab.paths.contacts`)
or a closed turn of a cycle stage (the circle of its control path); steps
over simple bifurcation points (:mod:`ncstab.paths.over_steps`) or returns
the case there to switch branch; finds the domain's edge inside a step
(:mod:`ncstab.paths.domain_edge`).  Its result for a case depends neither on
the batch nor on the thread (each case runs through the loop alone).

One loop steps every system: the reduced diamond (its law's fused kernel,
:mod:`ncstab.paths.loop_diamond_model` and :mod:`ncstab.paths.loop_diamond`),
general models (:mod:`ncstab.paths.loop_general`,
:mod:`ncstab.paths.loop_general_output`, :mod:`ncstab.paths.compiled_general`)
and the pure-shear limit (``normal = "rigid"``, :mod:`ncstab.paths.compiled_rigid`).
What depends on the model the loop asks of it through
:mod:`ncstab.paths.loop_dispatch`, by the model's record
(:class:`~ncstab.paths.loop_records.DiamondModel`,
:class:`~ncstab.paths.loop_records.GeneralModel`).  Stage entry, branch
switching and the assembly of the result are done once per stage or event,
in numpy, by :class:`ncstab.paths.stepper.BatchStepper`: this module runs each
case from the start of a stage to its end (target, stop event, branch switch
or failure).

numba is a dependency of ncstab (imported lazily: without it the engine asks
for it).  The loop is plain modules of compiled functions calling each other:
:mod:`ncstab.paths.loop_cases` (each case through its stage),
:mod:`ncstab.paths.loop_steps` (a DOP853 step, dense output, event location),
:mod:`ncstab.paths.loop_step_limits` (the domain's edge, and the over step
across a simple bifurcation point), :mod:`ncstab.paths.loop_start` (a stage's
start), the model's modules above, DOP853's numerics
(:mod:`ncstab.paths.loop_numerics`), the indicators' signs
(:mod:`ncstab.paths.loop_signs`) and the records a case's arrays travel in
(:mod:`ncstab.paths.loop_records`).  It is compiled once per kind of model and
machine, from its entry points (:func:`stage_loop`), and numba keeps the machine
code in the cache folder ``compiled`` (:mod:`ncstab.engine_cache`,
:mod:`ncstab.cache`).  The form of law (a total form, or a rate form with T
an internal variable) is a field of the model's record, and the law an argument
of the loop: its generated state kernel, compiled as a C callback
(:data:`LAW_SIGNATURE`, under a second), so a new law does not compile the loop
again.  The cases of a stage run side by side on threads (the loop releases the
GIL; :mod:`ncstab.paths.compiled_stages`).
"""
from __future__ import annotations

import functools
import re
from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as dop

try:  # optional dependency
    import numba

    NUMBA_AVAILABLE = True
except ImportError:  # pragma: no cover - exercised where numba is absent
    numba = None
    NUMBA_AVAILABLE = False

from ncstab.paths.events import (
    INDICATOR_EVENTS,
    INDICATOR_GAP,
)

__all__ = [
    "EVENT_FIELDS",
    "NUMBA_AVAILABLE",
    "Outcome",
    "StageLoop",
    "stage_loop",
    "stage_runner",
]

#: Columns of the per-event value table.
EVENT_FIELDS = (
    "s", "s_lower", "s_upper", "lam", "u0", "u1", "F0", "F1", "l", "alpha", "N", "T",
    "K00", "K01", "K10", "K11",
)


class StageLoop(NamedTuple):
    """The compiled functions of one law: ``run`` (cases through their stage),
    ``start`` (cases entering a stage), ``settle`` (states projected, and the rate of
    lambda there), ``law`` (the law's kernel, passed to all three), whether it reads
    alpha, and ``kind``, the model's record the loop dispatches on
    (:class:`ncstab.paths.loop_records.DiamondModel` or ``GeneralModel``)."""

    run: Callable[..., None]
    start: Callable[..., None]
    settle: Callable[..., None]
    law: Any = None
    uses_alpha: bool = True
    kind: Any = None


#: Slots of a case's row ``p`` before the law's parameters: kappa, whether the
#: secondary springs act (1.0) or not (0.0), the contact-state bits (a float),
#: whether the law reads alpha (1.0) or not; the law's parameters follow.
KAPPA_SLOT, ACTIVATE_SLOT, STATE_SLOT, ALPHA_SLOT, FIRST_PARAMETER = 0, 1, 2, 3, 4


class Outcome:
    """How a case's run of a stage ended (``code`` returned per case)."""

    PAUSED = 0  #: the record buffer is full: call again
    TARGET = 1  #: the stage target is reached
    STOPPED = 2  #: a stop event of the stage (its column returned)
    STEP_SIZE_UNDERFLOW = 3
    LEFT_DOMAIN = 4  #: reason returned: 0 non-finite, 1 l* <= 0, 2 alpha
    MAX_STEPS = 5
    SINGULAR_BRANCH = 6  #: a contact switch led onto a branch whose control is singular
    BRANCH_SWITCH = 7  #: at a simple bifurcation point where the stage switches branch (not stored)


_N_COLUMNS = len(INDICATOR_EVENTS)
_STAGES = dop.N_STAGES  # 12
_EXTENDED = dop.N_STAGES_EXTENDED  # 16
_A = np.ascontiguousarray(dop.A, dtype=float)
_B = np.ascontiguousarray(dop.B, dtype=float)
_E3 = np.ascontiguousarray(dop.E3, dtype=float)
_E5 = np.ascontiguousarray(dop.E5, dtype=float)
_D = np.ascontiguousarray(dop.D, dtype=float)
_POWER = dop.INTERPOLATOR_POWER
#: Columns whose crossing always cuts the step: the normal contact of a
#: no_tension law switches branch (crossings.event_tables); secondary contacts
#: switch only with "activate" (the stage's break columns).
BREAK_ALWAYS = tuple(gap == 4 for gap in INDICATOR_GAP)


def _terms(weights: np.ndarray, lengths: Any) -> tuple[np.ndarray, np.ndarray]:
    """Per row of ``weights``: the stage indices that combine_stages sums (the first
    term, then the non-zero weights among the first ``lengths[row]``), and their count."""
    terms = np.zeros(weights.shape, dtype=np.int64)
    counts = np.zeros(weights.shape[0], dtype=np.int64)
    for row, length in enumerate(lengths):
        kept = [0] + [k for k in range(1, int(length)) if weights[row, k] != 0]
        terms[row, : len(kept)] = kept
        counts[row] = len(kept) if length > 0 else 0
    return terms, counts


#: The C signature of a law's kernel in the compiled loop:
#: ``LAW(l, alpha, cos, sin, T, p, ev)`` (see :func:`_kernel_source`).
LAW_SIGNATURE = (
    numba.types.void(*[numba.types.float64] * 5, *[numba.types.CPointer(numba.types.float64)] * 2)
    if NUMBA_AVAILABLE
    else None
)


@functools.cache
def _runner(
    kernels: tuple[Callable[..., list], ...], overlap: Callable[..., Any] | None, n_parameters: int, rate_form: bool,
    plain: bool = False,
) -> StageLoop:
    """The loop for one law's fused kernels: the diamond's loop (compiled once per
    machine) and the law's own kernel (compiled once per law, a second or two); with
    ``plain``, both as plain Python (:mod:`ncstab.plain_python`), nothing compiled."""
    from ncstab.paths.compiled_source import kernel_body, kernel_source, load_module
    from ncstab.paths.loop_records import DiamondModel

    uses_alpha = any(re.search(r"\balpha_\b", kernel_body(kernel)) for kernel in kernels)
    uses_alpha |= overlap is not None and re.search(r"\balpha\b", kernel_body(overlap)) is not None
    law = load_module(kernel_source(kernels, overlap, n_parameters, 10 if rate_form else 8), "ncstab_law", plain).LAW
    return stage_loop(DiamondModel(rate_form), plain)._replace(law=law, uses_alpha=uses_alpha)


def stage_loop(kind: Any, plain: bool = False) -> StageLoop:
    """The stage loop's entry points (:func:`ncstab.paths.loop_cases.run_cases`,
    :func:`ncstab.paths.loop_start.start` and :func:`~ncstab.paths.loop_start.settle`)
    for the model whose record is ``kind``; with ``plain``, those of the loop's modules run
    as plain Python (:func:`ncstab.plain_python.plain_import`)."""
    if plain:
        from ncstab.plain_python import plain_import

        cases, start = plain_import("ncstab.paths.loop_cases"), plain_import("ncstab.paths.loop_start")
    else:
        from ncstab.paths import loop_cases as cases
        from ncstab.paths import loop_start as start
    return StageLoop(cases.run_cases, start.start, start.settle, kind=kind)


@functools.cache
def _overlap_function(definition: Any) -> Callable[..., Any]:
    """delta(l, alpha, *parameters), the normal overlap of a no_tension law (before any
    bracket), as a scalar function whose source the kernel module takes (sympy once)."""
    import sympy as sp
    from sympy.printing.numpy import NumPyPrinter

    from ncstab.laws.definition import ALPHA, L

    arguments = [L, ALPHA, *definition.parameter_symbols]
    return sp.lambdify(arguments, definition.normal_overlap, modules="numpy", printer=NumPyPrinter)


def stage_runner(batch: Any, plain: bool = False) -> StageLoop:
    """The compiled stage loop for this batch's law (compiled on first use), or with
    ``plain`` its text as plain Python.

    Raises
    ------
    RuntimeError
        When numba is not installed.
    """
    if not NUMBA_AVAILABLE:
        raise RuntimeError(
            "ncstab's path engine is compiled with numba, a dependency of ncstab that is not "
            "installed here: pip install numba"
        )
    definition = batch.law.definition
    overlap = _overlap_function(definition) if definition.no_tension else None
    return _runner(
        tuple(batch._kernels), overlap, len(definition.parameter_names), not batch.law.has_total_form, plain
    )
