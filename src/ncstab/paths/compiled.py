"""The compiled stepper: the engine's stepping loop as one numba loop per case.

By default (``PathOptions(backend="auto")``, or ``"compiled"`` asked for) the
linear stages of the deformable reduced diamond (the fused state kernel of
:mod:`ncstab.operators.tangent`, seed Eq. 4 and 30-34) run through this module
instead of the numpy passes of :class:`ncstab.paths.stepper.BatchStepper`, the
cases of a stage shared out over numba's threads (:mod:`ncstab.paths.threads`).
It takes the same steps: the same DOP853 tableau and error norm, the same
step-size control, the same Newton projection onto equilibrium for laws with a
total form, the same cofactor tangent of the constrained rate system, the same
event indicators located by the same Illinois iteration on the same DOP853
interpolant, the same cuts at stage targets, stop events and contact switches
(``secondary_contacts = "activate"``: the spring switches where its gap
crossing cuts the step, the direction of motion kept, as in
:func:`ncstab.paths.contacts.switch_contacts`).  It differs from the numpy
stepper at most by rounding (numpy may evaluate transcendental functions with
SIMD code, numba with the C library), and its result for a case depends
neither on the batch nor on the thread.  It does not orient the tangent by
continuity with the previous step (:func:`ncstab.paths.tangent_field.path_tangent`).

What it does not cover runs on the numpy stepper (see
:func:`unsupported_reason`): cycle stages, ``no_tension`` laws (kinks), the
pure-shear limit (``normal = "rigid"``) and general models.  Stage entry, the
first stored state of a stage and the assembly of the result stay with the
numpy stepper: this module runs each case from the start of a stage to its
end (target, stop event or failure).

numba is a dependency of ncstab (it stays optional at import: without it the
compiled backend asks for it).  The loop is one per form of law (a total
form, or a rate form with T an internal variable), generated as a module in
the cache folder ``compiled`` (:mod:`ncstab.cache`) and compiled once per
machine (about 26 s on a 2-core machine; numba caches the machine code beside
the module).  The law is an argument of the loop: its generated state kernel,
compiled as a C callback (:data:`LAW_SIGNATURE`, under a second), so a new law
does not compile the loop again.  The cases of a stage run side by side on
threads (the loop releases the GIL; :mod:`ncstab.paths.compiled_stages`).
"""
from __future__ import annotations

import functools
import hashlib
import importlib.util
import inspect
import math
import os
import re
import sys
import tempfile
import textwrap
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as dop

try:  # optional dependency
    import numba

    NUMBA_AVAILABLE = True
except ImportError:  # pragma: no cover - exercised where numba is absent
    numba = None
    NUMBA_AVAILABLE = False

from ncstab.cache import cache_directory
from ncstab.paths.events import (
    CYCLE_COLUMN,
    INDICATOR_EVENTS,
    INDICATOR_GAP,
    SIGN_NOISE,
    TARGET_COLUMN,
    TINY,
    TURNING_COLUMN,
)
from ncstab.paths.programme import CycleStage

__all__ = [
    "EVENT_FIELDS",
    "NUMBA_AVAILABLE",
    "Outcome",
    "StageLoop",
    "stage_runner",
    "unsupported_reason",
]

#: Columns of the per-event value table.
EVENT_FIELDS = (
    "s", "s_lower", "s_upper", "lam", "u0", "u1", "F0", "F1", "l", "alpha", "N", "T",
    "K00", "K01", "K10", "K11",
)


class StageLoop(NamedTuple):
    """The compiled functions of one law: ``run`` (cases through their stage),
    ``start`` (cases entering a stage) and ``law`` (the law's kernel, passed to both)."""

    run: Callable[..., None]
    start: Callable[..., None]
    law: Any = None
    uses_alpha: bool = True


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
#: switch only with "activate", which this stepper does not run.
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


def unsupported_reason(batch: Any, programme: Any) -> str | None:
    """Why the compiled stepper cannot run this batch (``None`` if it can).

    Parameters
    ----------
    batch
        The engine's batch of cases.
    programme
        The loading programme.
    """
    from ncstab.paths.model import CaseBatch
    from ncstab.paths.rigid_model import RigidCaseBatch

    if isinstance(batch, RigidCaseBatch):
        return "the pure-shear limit (normal = 'rigid') runs on the numpy stepper"
    if type(batch) is not CaseBatch:
        return "general models (any system but the seed's reduced diamond) run on the numpy stepper"
    if batch.law.definition.no_tension:
        return "no_tension laws (a kink at contact opening) run on the numpy stepper"
    if any(isinstance(stage, CycleStage) for stage in programme.stages):
        return "cycle stages run on the numpy stepper"
    kernels = batch._kernels
    if kernels is None or len(kernels) != 1 or batch.n_dof != 2:
        return "this system has no fused state kernel; it runs on the numpy stepper"
    return None


def _body(kernel: Callable[..., list]) -> str:
    """The generated kernel's statements (its source without the ``def`` line)."""
    source = inspect.getsource(kernel)
    return source[source.index(":\n") + 2 :]


@functools.cache
def _runner(kernel: Callable[..., list], n_parameters: int, rate_form: bool) -> StageLoop:
    """The loop for one law's fused kernel: the loop of its form (two per machine,
    compiled once) and the law's own kernel (compiled once per law, a second or two)."""
    uses_alpha = re.search(r"\balpha_\b", _body(kernel)) is not None
    loop = _load_module(_loop_source(rate_form), "ncstab_stage_loop").LOOP
    law = _load_module(_kernel_source(kernel, n_parameters, 10 if rate_form else 8), "ncstab_law").LAW
    return StageLoop(loop.run, loop.start, law, uses_alpha)


def _loop_source(rate_form: bool) -> str:
    """The stage loop of every law of one form as the text of a module (:func:`_build_runner`'s body).

    A module on disk, not closures: numba caches the machine code of a file's
    functions next to it, so the loop compiles once per form and machine, not
    once per process.  The law is an argument of the loop's functions (a
    first-class function of :data:`LAW_SIGNATURE`), so a new law compiles its
    kernel only.
    """
    builder = inspect.getsource(_build_runner)
    body = textwrap.dedent(builder[builder.index('    """', builder.index("def _build_runner")) :])
    body = body[body.index('"""', 3) + 3 :]  # after the docstring
    body = body.replace("cache=False", "cache=True").replace("return StageLoop(run_cases, start)", "LOOP = StageLoop(run_cases, start)")
    header = f'''"""The compiled stage loop of the laws {"with" if rate_form else "without"} a rate form,
generated by ncstab.paths.compiled: do not edit."""
import math

import numba
import numpy
import numpy as np

from ncstab.paths.compiled import (
    _A, _B, _D, _E3, _E5, _EXTENDED, _N_COLUMNS, _POWER, _STAGES, ACTIVATE_SLOT, ALPHA_SLOT, BREAK_ALWAYS,
    KAPPA_SLOT, STATE_SLOT, Outcome, StageLoop, _terms,
)
from ncstab.paths.events import CYCLE_COLUMN, INDICATOR_GAP, SIGN_NOISE, TARGET_COLUMN, TINY, TURNING_COLUMN

rate_form = {rate_form!r}
'''
    return header + body


def _kernel_source(kernel: Callable[..., list], n_parameters: int, n_outputs: int) -> str:
    """One law's kernel as the text of a module: the generated state kernel, and
    ``LAW``, a C callback of :data:`LAW_SIGNATURE` that the loop calls.

    ``LAW(l, alpha, cos, sin, T, p, ev)`` reads the law's parameters from the
    case's row ``p`` (from :data:`FIRST_PARAMETER`) and writes the kernel's
    outputs (N, T, F0, F1, K00, K01, K10, K11[, dT/dD1, dT/dD2]) to ``ev[2:]``.
    """
    kernel_source = inspect.getsource(kernel)
    start = kernel_source.rindex("return [")
    kernel_source = kernel_source[:start] + "return (" + kernel_source[start + len("return [") :].rstrip()
    if not kernel_source.endswith("]"):
        raise ValueError("unexpected kernel source: the return list does not end the function")
    kernel_source = kernel_source[:-1] + ",)\n"
    name = re.search(r"def (\w+)\(", kernel_source).group(1)
    arguments = ", ".join(f"q[{FIRST_PARAMETER + k}]" for k in range(n_parameters))
    stores = "\n    ".join(f"out[{2 + k}] = float(r[{k}])" for k in range(n_outputs))
    return f'''"""One law's kernel for the compiled stage loop, generated by ncstab.paths.compiled: do not edit."""
import math

import numba
import numpy
import numpy as np

from ncstab.paths.compiled import LAW_SIGNATURE


@numba.njit(inline="always", cache=True)
{kernel_source}

@numba.cfunc(LAW_SIGNATURE, cache=True, error_model="numpy")
def LAW(l, a, c, s, t, p, ev):
    q = numba.carray(p, ({FIRST_PARAMETER + n_parameters},))
    out = numba.carray(ev, (16,))
    r = {name}(l, a, c, s, t, {arguments})
    {stores}
'''


#: The C signature of a law's kernel in the compiled loop:
#: ``LAW(l, alpha, cos, sin, T, p, ev)`` (see :func:`_kernel_source`).
LAW_SIGNATURE = (
    numba.types.void(*[numba.types.float64] * 5, *[numba.types.CPointer(numba.types.float64)] * 2)
    if NUMBA_AVAILABLE
    else None
)

#: The cache folder of the generated loops and numba's machine code (:mod:`ncstab.cache`).
CACHE_KIND = "compiled"


def _write_module(directory: Path, name: str, source: str) -> Path:
    """``directory/name.py`` holding ``source`` (written atomically unless it already does)."""
    directory.mkdir(parents=True, exist_ok=True)
    path = directory / f"{name}.py"
    if not path.exists() or path.read_text(encoding="utf-8") != source:
        scratch = directory / f".{name}.{os.getpid()}.tmp"
        scratch.write_text(source, encoding="utf-8")
        os.replace(scratch, path)
    return path


#: Held while a generated module is written and executed.
_LOADING = threading.Lock()


def _load_module(source: str, prefix: str) -> Any:
    """Import the generated module ``source`` from the cache folder ``<cache root>/compiled``.

    The file is named ``prefix`` and a hash of its text, of what it imports and of the
    numba and numpy versions (a changed input is a new file, compiled anew),
    and written atomically (several processes, e.g. dask workers, may write it at
    once).  Where the cache directory cannot be written, a temporary one
    serves this process only.
    """
    # The module's text, and what it imports: this file and the event columns
    # (numba freezes imported globals into the cached machine code).
    stamp = repr((INDICATOR_EVENTS, INDICATOR_GAP, SIGN_NOISE, TINY, numba.__version__, np.__version__))
    own = Path(__file__).read_text(encoding="utf-8")
    digest = hashlib.sha256((source + stamp + own).encode()).hexdigest()[:20]
    name = f"{prefix}_{digest}"
    # One thread at a time (the threads of a dask worker run chunks side by side):
    # another thread must not find the module half executed.
    with _LOADING:
        if name in sys.modules:
            return sys.modules[name]
        try:
            path = _write_module(cache_directory(CACHE_KIND), name, source)
        except OSError:  # a read-only home, say
            path = _write_module(Path(tempfile.mkdtemp(prefix="ncstab-compiled-")), name, source)
        spec = importlib.util.spec_from_file_location(name, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[name] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[name]
            raise
        return module


def stage_runner(batch: Any) -> StageLoop:
    """The compiled stage loop for this batch's law (compiled on first use).

    Raises
    ------
    RuntimeError
        When numba is not installed.
    """
    if not NUMBA_AVAILABLE:
        raise RuntimeError(
            "PathOptions.backend = 'compiled' needs numba, a dependency of ncstab: pip install numba "
            "(or use backend = 'numpy')"
        )
    (kernel,) = batch._kernels
    return _runner(kernel, len(batch.law.definition.parameter_names), not batch.law.has_total_form)


def _build_runner(rate_form: bool) -> StageLoop:
    """The stage loop around one law's state kernel (a template: see below).

    Every helper mirrors a numpy function of the engine, operation for
    operation (cited in its comment), so that both backends take the same
    steps.  The loop is built from this function's *text*: its body, after
    this docstring, becomes the body of a generated module whose globals
    ``rate_form`` is this function's parameter (:func:`_loop_source`), so that
    numba can cache it on disk.  It is not called.  The law is an argument,
    ``law``, of every function that evaluates the model (a C callback of
    :data:`LAW_SIGNATURE`, :func:`_kernel_source`).
    """
    # The helpers are called from compiled code only: no CPython or C wrapper is
    # built for them.  Those of every DOP853 stage (evaluate, tangent, the stage
    # sums) are inlined in numba's IR: a third off the stepping for 6 s of the
    # first compilation (20 s without, 26 s with; see docs/paths.md).
    njit = numba.njit(cache=False, error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
    hot = numba.njit(cache=False, error_model="numpy", inline="always")
    A, B, E3, E5, D = _A, _B, _E3, _E5, _D
    A_TERMS, A_COUNT = _terms(_A, np.arange(_EXTENDED))
    B_TERMS, B_COUNT = _terms(_B[None, :], [_STAGES])
    E5_TERMS, E5_COUNT = _terms(_E5[None, :], [_STAGES + 1])
    E3_TERMS, E3_COUNT = _terms(_E3[None, :], [_STAGES + 1])
    D_TERMS, D_COUNT = _terms(_D, [_EXTENDED] * _D.shape[0])
    B_TERMS, B_COUNT, E5_TERMS, E5_COUNT = B_TERMS[0], B_COUNT[0], E5_TERMS[0], E5_COUNT[0]
    E3_TERMS, E3_COUNT = E3_TERMS[0], E3_COUNT[0]
    n_columns, target_column, turning_column = _N_COLUMNS, TARGET_COLUMN, TURNING_COLUMN
    gap_columns = (INDICATOR_GAP.index(1), INDICATOR_GAP.index(2))  # the two diagonals (ev[12], ev[13])
    sign_noise, tiny = SIGN_NOISE, TINY
    half_pi = math.pi / 2
    N_INT = 1 if rate_form else 0  # internal variables: T for a rate form (one contact family)
    M = 4 + N_INT  # y = (v0, v1, lambda, [T], W)
    cut_always = np.array([c in (TARGET_COLUMN, CYCLE_COLUMN) or BREAK_ALWAYS[c] for c in range(_N_COLUMNS)])
    switch_bits = np.array(INDICATOR_GAP, dtype=np.int64)
    # The case's row p: kappa, whether the secondary springs act, the contact-state
    # bits, whether the law reads alpha, then the law's parameters (KAPPA_SLOT, ...).
    kappa_slot, activate_slot, state_slot, alpha_slot = KAPPA_SLOT, ACTIVATE_SLOT, STATE_SLOT, ALPHA_SLOT
    Outcome_PAUSED, Outcome_TARGET, Outcome_STOPPED = Outcome.PAUSED, Outcome.TARGET, Outcome.STOPPED
    Outcome_STEP_SIZE_UNDERFLOW, Outcome_LEFT_DOMAIN = Outcome.STEP_SIZE_UNDERFLOW, Outcome.LEFT_DOMAIN
    Outcome_MAX_STEPS = Outcome.MAX_STEPS

    @hot
    def evaluate(v0, v1, t_in, law, p, cos0, sin0, ev):
        # model.CaseBatch._evaluate_fused: ev = (l, alpha, N, T, F0, F1, K00, K01, K10, K11,
        # dT/dD1, dT/dD2, gap0, gap1, vertical, horizontal); alpha only where the law
        # reads it (else NaN here, see angle())
        vertical = cos0 - v0
        horizontal = sin0 - v1
        length = np.sqrt(vertical * vertical + horizontal * horizontal)
        alpha = np.arctan2(horizontal, vertical) if p[alpha_slot] > 0 else np.nan
        law(length, alpha, vertical / length, horizontal / length, t_in, p.ctypes, ev.ctypes)  # ev[2:]
        ev[0] = length
        ev[1] = alpha
        ev[14] = vertical
        ev[15] = horizontal
        if not rate_form:
            ev[10] = np.nan
            ev[11] = np.nan
        ev[12] = gap(vertical)
        ev[13] = gap(horizontal)
        if p[activate_slot] > 0:
            # model.CaseBatch._evaluate_fused: the secondary-contact springs whose bit is set
            kappa, state = p[kappa_slot], int(p[state_slot])
            ev[4] += kappa * ((1.0 - 2.0 * vertical) if (state & 1) > 0 else 0.0)
            ev[6] += 2.0 * kappa * (1.0 if (state & 1) > 0 else 0.0)
            ev[5] += kappa * ((1.0 - 2.0 * horizontal) if (state & 2) > 0 else 0.0)
            ev[9] += 2.0 * kappa * (1.0 if (state & 2) > 0 else 0.0)

    @njit
    def gap(extent):
        # the secondary-contact gap along one diagonal (model: 2 (cos alpha0 - Delta_1) - 1, ...)
        return extent * 2 - 1

    @njit
    def signed_gap(value, secondary, bit):
        # events.indicator_values: a gap exactly at zero takes the sign of the contact's state
        if value == 0:
            return -tiny if (secondary & bit) > 0 else tiny
        return value

    @njit
    def angle(ev):
        # alpha = arctan2(horizontal, vertical), computed once where the law did not need it
        if np.isnan(ev[1]):  # evaluate() leaves it NaN where the law does not read it
            ev[1] = np.arctan2(ev[15], ev[14])
        return ev[1]

    @hot
    def tangent(ev, fc0, fc1, g0, g1, orientation, aux):
        # tangent_field._path_tangent_2 with du/dv = I, dF/dv = K: aux = (dv0, dv1, du0, du1, dlam, det_m)
        k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
        m00 = k00 if fc0 else 1.0
        m01 = k01 if fc0 else 0.0
        m10 = k10 if fc1 else 0.0
        m11 = k11 if fc1 else 1.0
        det_m = m00 * m11 - m01 * m10
        dv0 = m11 * g0 - m01 * g1
        dv1 = m00 * g1 - m10 * g0
        du0 = 1.0 * dv0 + 0.0 * dv1
        du1 = 0.0 * dv0 + 1.0 * dv1
        df0 = k00 * dv0 + k01 * dv1
        df1 = k10 * dv0 + k11 * dv1
        norm = np.sqrt((du0 * du0 + du1 * du1) + (df0 * df0 + df1 * df1) + det_m * det_m)
        # (1 / norm) * orientation, as one division: orientation is +-1, so the
        # same number (one rounding), one operation shorter on the critical path
        scale = orientation / norm if norm > 0 else np.nan
        aux[0] = dv0 * scale
        aux[1] = dv1 * scale
        aux[2] = du0 * scale
        aux[3] = du1 * scale
        aux[4] = det_m * scale
        aux[5] = det_m

    def rhs_py(y, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, dy, ev, aux):
        # rhs.state_derivative: dy/ds = (dv, dlambda, dinternal, dW)
        t_in = y[3] if N_INT else 0.0
        evaluate(y[0], y[1], t_in, law, p, cos0, sin0, ev)
        tangent(ev, fc0, fc1, g0, g1, orientation, aux)
        dy[0] = aux[0]
        dy[1] = aux[1]
        dy[2] = aux[4]
        if N_INT:
            dy[3] = ev[10] * aux[0] + ev[11] * aux[1]
        dy[3 + N_INT] = 0.5 * (ev[4] * aux[2] + ev[5] * aux[3])

    # Inlined where every step evaluates it (the DOP853 stages), called elsewhere:
    # inlining it everywhere costs seconds of compilation for no measurable gain.
    rhs_hot = hot(rhs_py)
    rhs = njit(rhs_py)

    @njit
    def motion(ev, aux, out):
        # contacts.switch_contacts.motion: (du, dF = K dv, dlambda) of the tangent in aux
        out[0] = aux[2]
        out[1] = aux[3]
        out[2] = ev[6] * aux[0] + ev[7] * aux[1]
        out[3] = ev[8] * aux[0] + ev[9] * aux[1]
        out[4] = aux[4]

    @njit
    def motion_product(before, ev, aux):
        # the sum over (du, dF, dlambda) of motion(after) * motion(before), in order
        total = aux[2] * before[0]
        total += aux[3] * before[1]
        total += (ev[6] * aux[0] + ev[7] * aux[1]) * before[2]
        total += (ev[8] * aux[0] + ev[9] * aux[1]) * before[3]
        total += aux[4] * before[4]
        return total

    @njit
    def significant(value, size):
        # events.indicator_values.significant
        return 0.0 if abs(value) <= sign_noise * size else value

    @njit
    def indicators(ev, aux, lam, fc0, fc1, lam_end, target_sign, secondary, out):
        # events.indicator_values (linear stage, no no_tension overlap)
        k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
        m00 = k00 if fc0 else 1.0
        m01 = k01 if fc0 else 0.0
        m10 = k10 if fc1 else 0.0
        m11 = k11 if fc1 else 1.0
        scale = np.nan
        for value in (k00, k01, k10, k11, m00, m01, m10, m11):
            a = abs(value)
            if not np.isnan(a) and not (a <= scale):  # nanmax
                scale = a
        if not (np.isfinite(scale) and scale > 0):
            scale = 1.0
        square = scale * scale
        out[0] = significant(k00 * k11 - k01 * k10, square)
        s00 = 0.5 * (k00 + k00)
        s01 = 0.5 * (k01 + k10)
        s11 = 0.5 * (k11 + k11)
        mean = 0.5 * (s00 + s11)
        radius = np.hypot(0.5 * (s00 - s11), s01)
        out[1] = significant(mean - radius, scale)
        out[2] = significant(m00 * m11 - m01 * m10, square)
        difference = k00 - k11
        out[3] = significant(difference * difference + 4 * k01 * k10, square)
        out[4] = signed_gap(ev[12], secondary, 1)
        out[5] = signed_gap(ev[13], secondary, 2)
        out[6] = aux[4]
        out[7] = np.nan
        out[8] = np.nan
        out[9] = target_indicator(lam, lam_end, target_sign)

    @njit
    def target_indicator(lam, lam_end, target_sign):
        # events.indicator_values: the stage target, (lambda - lambda_end) sign
        return (lam - lam_end) * target_sign

    @hot
    def combine(weights, terms, n_terms, stages, out):
        # integrator.combine_stages for every component: term by term in stage order,
        # the first term and the non-zero weights after it (terms: their stage indices).
        # One accumulator per component (m is 4 or 5, fixed per law), side by side.
        w = weights[0]
        a0, a1, a2, a3 = w * stages[0, 0], w * stages[0, 1], w * stages[0, 2], w * stages[0, 3]
        a4 = w * stages[0, 4] if M == 5 else 0.0
        for t in range(1, n_terms):
            k = terms[t]
            w = weights[k]
            a0 += w * stages[k, 0]
            a1 += w * stages[k, 1]
            a2 += w * stages[k, 2]
            a3 += w * stages[k, 3]
            if M == 5:
                a4 += w * stages[k, 4]
        out[0], out[1], out[2], out[3] = a0, a1, a2, a3
        if M == 5:
            out[4] = a4

    @njit
    def error_norm(y0, y1, h, rtol, atol, stages, work):
        # integrator.dop853_step's error norm (integrator.error_norm); inf where y1 or the
        # norm is not finite
        sums, sums3 = work[1], work[2]
        err5_sq = 0.0
        err3_sq = 0.0
        finite = True
        combine(E5, E5_TERMS, E5_COUNT, stages, sums)
        combine(E3, E3_TERMS, E3_COUNT, stages, sums3)
        for j in range(M):
            scale = atol + max_nan(abs(y0[j]), abs(y1[j])) * rtol
            e5 = sums[j] / scale
            e3 = sums3[j] / scale
            err5_sq += e5 * e5
            err3_sq += e3 * e3
            finite = finite and np.isfinite(y1[j])
        denominator = err5_sq + 0.01 * err3_sq
        err = abs(h) * err5_sq / np.sqrt(denominator * M) if denominator > 0 else 0.0
        if not (finite and np.isfinite(err)):
            err = np.inf
        return err

    @njit
    def max_nan(a, b):
        # np.maximum: NaN if either is NaN
        if np.isnan(a) or np.isnan(b):
            return np.nan
        return max(a, b)

    @njit
    def residual(ev, y, fc0, fc1, offset, slope):
        # StageArrays.residual: P u + Q F - g(lambda), max norm; returns (r0, r1, size)
        lam = y[2]
        r0 = (ev[4] if fc0 else y[0]) - (offset[0] + slope[0] * lam)
        r1 = (ev[5] if fc1 else y[1]) - (offset[1] + slope[1] * lam)
        a0, a1 = abs(r0), abs(r1)
        size = np.nan if (np.isnan(a0) or np.isnan(a1)) else max(a0, a1)
        return r0, r1, size

    @njit
    def project(y, fc0, fc1, offset, slope, law, p, cos0, sin0, newton_tol, newton_max_iter, ev):
        # projection.project + _correction_2, one case; ev left at the final state
        g0, g1 = slope[0], slope[1]
        for _ in range(newton_max_iter + 1):
            evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
            r0, r1, size = residual(ev, y, fc0, fc1, offset, slope)
            if size <= newton_tol:
                return True
            if not np.isfinite(size):
                return False
            k00, k01, k10, k11 = ev[6], ev[7], ev[8], ev[9]
            m00 = k00 if fc0 else 1.0
            m01 = k01 if fc0 else 0.0
            m10 = k10 if fc1 else 0.0
            m11 = k11 if fc1 else 1.0
            a00 = (m00 * m00 + m01 * m01) + g0 * g0
            a01 = (m00 * m10 + m01 * m11) + g0 * g1
            a11 = (m10 * m10 + m11 * m11) + g1 * g1
            det = a00 * a11 - a01 * a01
            z0 = (a11 * r0 - a01 * r1) / det
            z1 = (a00 * r1 - a01 * r0) / det
            singular = (
                np.isfinite(a00) and np.isfinite(a01) and np.isfinite(a11)
                and not (np.isfinite(z0) and np.isfinite(z1))
            )
            if singular:  # rank-deficient normal matrix: least squares
                normal = np.empty((2, 2))
                normal[0, 0] = m00 * m00 + m01 * m01 + g0 * g0
                normal[0, 1] = m00 * m10 + m01 * m11 + g0 * g1
                normal[1, 0] = m10 * m00 + m11 * m01 + g1 * g0
                normal[1, 1] = m10 * m10 + m11 * m11 + g1 * g1
                right = np.empty(2)
                right[0], right[1] = r0, r1
                solution = np.linalg.lstsq(normal, right)[0]
                z0, z1 = solution[0], solution[1]
            dv0 = -(m00 * z0 + m10 * z1)
            dv1 = -(m01 * z0 + m11 * z1)
            y[0] += dv0
            y[1] += dv1
            y[2] += g0 * z0 + g1 * z1
            du0 = 1.0 * dv0 + 0.0 * dv1
            du1 = 0.0 * dv0 + 1.0 * dv1
            y[3 + N_INT] += 0.5 * (ev[4] * du0 + ev[5] * du1)
        evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
        return False

    @njit
    def dense_coefficients(y0, y_raw, h, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, stages,
                           coefficients, work, ev, aux):
        # integrator.dense_output (the three extra stages, unprojected)
        m = y0.size
        state, sums = work[0], work[1]
        for s in range(_STAGES + 1, _EXTENDED):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(m):
                state[j] = y0[j] + sums[j] * h
            rhs(state, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, stages[s], ev, aux)
        for j in range(m):
            delta = y_raw[j] - y0[j]
            f_old, f_new = stages[0, j], stages[_STAGES, j]
            coefficients[0, j] = delta
            coefficients[1, j] = h * f_old - delta
            coefficients[2, j] = 2 * delta - h * (f_new + f_old)
        for k in range(_POWER - 3):
            combine(D[k], D_TERMS[k], D_COUNT[k], stages, sums)
            for j in range(m):
                coefficients[3 + k, j] = h * sums[j]

    @njit
    def dense_value(y0, coefficients, fraction, out):
        # integrator.evaluate_dense (scipy's Horner form)
        for j in range(y0.size):
            value = 0.0
            for i in range(_POWER):
                value += coefficients[_POWER - 1 - i, j]
                value *= fraction if i % 2 == 0 else 1 - fraction
            out[j] = value + y0[j]

    @njit
    def indicator_at(y, column, fc0, fc1, offset, slope, lam_end, target_sign, orientation, secondary, law, p,
                     cos0, sin0, newton_tol, newton_max_iter, ev, aux, values):
        # crossings.locate_crossings.evaluate: project (total form), evaluate, one column.
        # Without a projection the target and the gaps are functions of y alone: the
        # same operations without the law (bit for bit).
        if rate_form and column == target_column:
            return target_indicator(y[2], lam_end, target_sign)
        if rate_form and column == gap_columns[0]:
            return signed_gap(gap(cos0 - y[0]), secondary, 1)
        if rate_form and column == gap_columns[1]:
            return signed_gap(gap(sin0 - y[1]), secondary, 2)
        if not rate_form:
            project(y, fc0, fc1, offset, slope, law, p, cos0, sin0, newton_tol, newton_max_iter, ev)
        else:
            evaluate(y[0], y[1], y[3] if N_INT else 0.0, law, p, cos0, sin0, ev)
        if column == turning_column:
            tangent(ev, fc0, fc1, slope[0], slope[1], orientation, aux)
        else:
            aux[4] = np.nan
        indicators(ev, aux, y[2], fc0, fc1, lam_end, target_sign, secondary, values)
        return values[column]

    @njit
    def sign(x):
        if x > 0:
            return 1.0
        if x < 0:
            return -1.0
        return x  # 0 or NaN

    @njit
    def locate(column, h, phi0, phi1, y0, coefficients, fc0, fc1, offset, slope, lam_end, target_sign,
               orientation, secondary, law, p, cos0, sin0, newton_tol, newton_max_iter, event_tol,
               ev, aux, values, state):
        # events.locate_sign_changes, one pair: returns (sigma, lower, upper); state at sigma
        lower, upper = 0.0, h
        f_lower, f_upper = phi0, phi1
        side = 0
        sigma = np.nan
        last_width = upper - lower
        for iteration in range(200):
            width = upper - lower
            candidate = (lower * f_upper - upper * f_lower) / (f_upper - f_lower)
            bisect = not np.isfinite(candidate) or candidate <= lower or candidate >= upper
            if iteration % 5 == 4:
                bisect = bisect or width > 0.5 * last_width
                last_width = width
            if bisect:
                candidate = 0.5 * (lower + upper)
            dense_value(y0, coefficients, candidate / h, state)
            value = indicator_at(state, column, fc0, fc1, offset, slope, lam_end, target_sign, orientation,
                                 secondary, law, p, cos0, sin0, newton_tol, newton_max_iter, ev, aux, values)
            sigma = candidate
            a_side = sign(value) == sign(f_lower)
            b_side = sign(value) == sign(f_upper)
            exact = abs(value) <= tiny or not np.isfinite(value)
            if a_side:
                if side == 1:
                    f_upper *= 0.5
                lower, f_lower, side = candidate, value, 1
            if b_side:
                if side == -1:
                    f_lower *= 0.5
                upper, f_upper, side = candidate, value, -1
            if exact:
                lower = upper = candidate
            if upper - lower <= event_tol or exact:
                break
        return sigma, lower, upper

    @njit
    def store_record(recorded, i, position, arclength, stage_number, y, ev, aux):
        # stepper.BatchStepper.record, straight into the recorder's padded arrays
        # (``recorded``: one array per field, in the order of BatchStepper.record_fields())
        (r_s, r_stage, r_u, r_lam, r_internal, r_work, r_f, r_l, r_alpha, r_n, r_t, r_k, r_du,
         r_dlam) = recorded
        r_s[i, position] = arclength
        r_stage[i, position] = stage_number
        r_u[i, position, 0] = y[0]
        r_u[i, position, 1] = y[1]
        r_lam[i, position] = y[2]
        for k in range(M - 4):
            r_internal[i, position, k] = y[3 + k]
        r_work[i, position] = y[M - 1]
        r_f[i, position, 0] = ev[4]
        r_f[i, position, 1] = ev[5]
        r_l[i, position] = ev[0]
        r_alpha[i, position] = angle(ev)
        r_n[i, position] = ev[2]
        r_t[i, position] = ev[3]
        r_k[i, position, 0, 0] = ev[6]
        r_k[i, position, 0, 1] = ev[7]
        r_k[i, position, 1, 0] = ev[8]
        r_k[i, position, 1, 1] = ev[9]
        r_du[i, position, 0] = aux[2]
        r_du[i, position, 1] = aux[3]
        r_dlam[i, position] = aux[4]

    @njit
    def store_event(row, arclength, sigma, lower, upper, y, ev):
        # crossings.store_first_events, one event of one case
        row[0] = arclength + sigma
        row[1] = arclength + lower
        row[2] = arclength + upper
        row[3] = y[2]
        row[4] = y[0]
        row[5] = y[1]
        row[6] = ev[4]
        row[7] = ev[5]
        row[8] = ev[0]
        row[9] = angle(ev)
        row[10] = ev[2]
        row[11] = ev[3]
        row[12] = ev[6]
        row[13] = ev[7]
        row[14] = ev[8]
        row[15] = ev[9]

    @njit
    def dop853(y0, f0, h, rtol, atol, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, stages, y1, work, ev,
               aux):
        # integrator.dop853_step; leaves ev, aux at the end state y1 (its last stage)
        state, sums = work[0], work[1]
        for j in range(M):
            stages[0, j] = f0[j]
        for s in range(1, _STAGES):
            combine(A[s], A_TERMS[s], A_COUNT[s], stages, sums)
            for j in range(M):
                state[j] = y0[j] + sums[j] * h
            rhs_hot(state, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, stages[s], ev, aux)
        combine(B, B_TERMS, B_COUNT, stages, sums)
        for j in range(M):
            y1[j] = y0[j] + h * sums[j]
        rhs_hot(y1, fc0, fc1, g0, g1, orientation, law, p, cos0, sin0, stages[_STAGES], ev, aux)
        return error_norm(y0, y1, h, rtol, atol, stages, work)

    @numba.njit(cache=False, error_model="numpy", nogil=True)
    def run_cases(cases, y, derivative, indicator_table, step_size, arclength, accepted, rejected, located,
                  force_controlled, offset, slope, lam_end, target_sign, orientation, secondary_state,
                  law, parameters, cos0, sin0, stop_row, break_row, event_columns, event_found, event_values, event_stage,
                  stage_number, recorded, record_count, code, detail, rtol, atol, newton_tol,
                  newton_max_iter, min_step, max_step, max_steps, event_tol):
        """Run cases ``cases`` through their current (linear) stage, one after the other;
        see :class:`Outcome`.

        Mirrors one case's passes of stepper.BatchStepper: a DOP853 step (projected),
        the step-size control, the domain check, crossings located, the cut, the
        first events, the commit and the end of the stage.  A case reads and
        writes its own rows only, so cases may run on any thread in any order
        (the loop releases the GIL: :mod:`ncstab.paths.compiled_stages` runs
        strided shares of the cases on Python threads side by side).
        """
        capacity = recorded[0].shape[1]
        stages = np.empty((_EXTENDED, M))
        y0 = np.empty(M)
        y_raw = np.empty(M)
        y_new = np.empty(M)
        dy_new = np.empty(M)
        work = np.empty((3, M))
        coefficients = np.empty((_POWER, M))
        located_states = np.empty((n_columns, M))
        ev = np.empty(16)
        aux = np.empty(6)
        ev_new = np.empty(16)
        aux_new = np.empty(6)
        values = np.empty(n_columns)
        after = np.empty(n_columns)
        before = np.empty(n_columns)
        sigma = np.empty(n_columns)
        lower = np.empty(n_columns)
        upper = np.empty(n_columns)
        change = np.zeros(n_columns, dtype=np.bool_)
        motion_before = np.empty(5)
        for i in cases:
            fc0, fc1 = force_controlled[i, 0], force_controlled[i, 1]
            g0, g1 = slope[i, 0], slope[i, 1]
            p = parameters[i]
            sec = secondary_state[i]
            p[state_slot] = sec
            c0, s0 = cos0[i], sin0[i]
            orient = orientation[i]
            code[i] = Outcome_PAUSED
            while record_count[i] < capacity:
                h = min(step_size[i], max_step)
                for j in range(M):
                    y0[j] = y[i, j]
                err = dop853(y0, derivative[i], h, rtol, atol, fc0, fc1, g0, g1, orient, law, p, c0, s0,
                             stages, y_raw, work, ev_new, aux_new)
                for j in range(M):
                    y_new[j] = y_raw[j]
                if not rate_form and np.isfinite(err) and not project(
                    y_new, fc0, fc1, offset[i], slope[i], law, p, c0, s0, newton_tol, newton_max_iter, ev_new
                ):
                    err = np.inf
                accept = err <= 1.0
                if err == 0:
                    factor = 10.0
                elif np.isfinite(err):
                    factor = min(max(0.9 / np.sqrt(np.sqrt(np.sqrt(err))), 0.2), 10.0)  # integrator.step_factor
                else:
                    factor = 0.25
                if not accept:
                    factor = min(factor, 0.9)
                step_size[i] = min(max(h * factor, 0.0), max_step)
                if not accept:
                    rejected[i] += 1
                    if step_size[i] < min_step:
                        code[i] = Outcome_STEP_SIZE_UNDERFLOW
                        break
                    continue
                if rate_form:  # the last DOP853 stage was evaluated at the end state
                    for j in range(M):
                        dy_new[j] = stages[_STAGES, j]
                else:
                    rhs(y_new, fc0, fc1, g0, g1, orient, law, p, c0, s0, dy_new, ev_new, aux_new)
                # --- _fail_outside_domain
                finite = np.isfinite(ev_new[4]) and np.isfinite(ev_new[5])
                for j in range(M):
                    finite = finite and np.isfinite(y_new[j])
                if not finite or not (ev_new[0] > 0) or not (abs(angle(ev_new)) < half_pi):
                    code[i] = Outcome_LEFT_DOMAIN
                    detail[i] = 0 if not finite else (1 if not (ev_new[0] > 0) else 2)
                    break
                # --- _complete: indicators, crossings located, cut, events, commit
                indicators(ev_new, aux_new, y_new[2], fc0, fc1, lam_end[i], target_sign[i],
                           sec, after)
                any_change = False
                for c in range(n_columns):
                    before[c] = indicator_table[i, c]
                    change[c] = sign(before[c]) * sign(after[c]) < 0
                change[target_column] = before[target_column] < 0 and after[target_column] >= 0
                for c in range(n_columns):
                    sigma[c] = np.inf
                    lower[c] = np.nan
                    upper[c] = np.nan
                    any_change = any_change or change[c]
                exact_target = change[target_column] and after[target_column] == 0
                if any_change:
                    searched = False
                    for c in range(n_columns):
                        searched = searched or (change[c] and not (c == target_column and exact_target))
                    if searched:
                        dense_coefficients(y0, y_raw, h, fc0, fc1, g0, g1, orient, law, p, c0, s0, stages,
                                           coefficients, work, ev, aux)
                    for c in range(n_columns):
                        if not change[c] or (c == target_column and exact_target):
                            continue
                        sigma[c], lower[c], upper[c] = locate(
                            c, h, before[c], after[c], y0, coefficients, fc0, fc1, offset[i], slope[i],
                            lam_end[i], target_sign[i], orient, sec, law, p, c0, s0,
                            newton_tol, newton_max_iter, event_tol, ev, aux, values, located_states[c],
                        )
                        located[i] += 1
                    if exact_target:
                        sigma[target_column] = lower[target_column] = upper[target_column] = h
                        for j in range(M):
                            located_states[target_column, j] = y_new[j]
                # _cut_points: the target, stop events (and contact switches, none here)
                cut_column = 0
                cut_sigma = np.inf
                for c in range(n_columns):
                    cutting = change[c] and (stop_row[c] or cut_always[c] or break_row[c])
                    if cutting and sigma[c] < cut_sigma:
                        cut_sigma = sigma[c]
                        cut_column = c
                is_cut = np.isfinite(cut_sigma)
                reach = cut_sigma if is_cut else h
                # _store_first_events
                for e in range(event_columns.shape[0]):
                    best = np.inf
                    best_column = -1
                    for k in range(event_columns.shape[1]):
                        c = event_columns[e, k]
                        if c >= 0 and (best_column < 0 or sigma[c] < best):
                            best = sigma[c]
                            best_column = c
                    if np.isfinite(best) and best <= reach + event_tol and not event_found[e, i]:
                        state = located_states[best_column]
                        rhs(state, fc0, fc1, g0, g1, orient, law, p, c0, s0, work[2], ev, aux)
                        event_found[e, i] = True
                        event_stage[e, i] = stage_number
                        store_event(event_values[e, i], arclength[i], sigma[best_column], lower[best_column],
                                    upper[best_column], state, ev)
                if is_cut:  # _move_to_cut_points
                    for j in range(M):
                        y_new[j] = located_states[cut_column, j]
                    switching = break_row[cut_column]
                    kept = 0.0
                    if switching:  # _switch_contacts_at: the direction of motion is kept
                        rhs(y_new, fc0, fc1, g0, g1, orient, law, p, c0, s0, work[2], ev, aux)
                        motion(ev, aux, motion_before)
                        sec = sec ^ switch_bits[cut_column]
                        p[state_slot] = sec
                        secondary_state[i] = sec
                        rhs(y_new, fc0, fc1, g0, g1, orient, law, p, c0, s0, work[2], ev, aux)
                        if motion_product(motion_before, ev, aux) < 0:
                            orient = -orient
                            orientation[i] = orient
                        kept = after[cut_column]
                    rhs(y_new, fc0, fc1, g0, g1, orient, law, p, c0, s0, dy_new, ev_new, aux_new)
                    indicators(ev_new, aux_new, y_new[2], fc0, fc1, lam_end[i], target_sign[i],
                               sec, after)
                    if switching:  # the post-crossing sign, so the crossing is not found twice
                        after[cut_column] = kept
                # _commit
                for j in range(M):
                    y[i, j] = y_new[j]
                    derivative[i, j] = dy_new[j]
                arclength[i] += reach
                accepted[i] += 1
                for c in range(n_columns):
                    indicator_table[i, c] = after[c]
                store_record(recorded, i, record_count[i], arclength[i], stage_number, y_new, ev_new, aux_new)
                record_count[i] += 1
                # _end_stages
                stop_hit = is_cut and cut_column != target_column and stop_row[cut_column]
                at_target = cut_column == target_column or after[target_column] >= 0
                target_hit = is_cut and not stop_hit and at_target
                if stop_hit:
                    code[i] = Outcome_STOPPED
                    detail[i] = cut_column
                    break
                if accepted[i] >= max_steps and not target_hit:
                    code[i] = Outcome_MAX_STEPS
                    break
                if target_hit:
                    code[i] = Outcome_TARGET
                    break

    @njit
    def initial_step_size(y0, f0, f1, probe, rtol, atol):
        # integrator.initial_step_size, one case (np.mean over m: a sum in order, then / m)
        s1 = 0.0
        s2 = 0.0
        for j in range(M):
            scale = atol + abs(y0[j]) * rtol
            a = f0[j] / scale
            b = (f1[j] - f0[j]) / scale
            s1 += a * a
            s2 += b * b
        d1 = np.sqrt(s1 / M)
        d2 = np.sqrt(s2 / M) / probe
        largest = np.nan if (np.isnan(d1) or np.isnan(d2)) else max(d1, d2)
        if not np.isfinite(largest):
            return probe
        if largest <= 1e-15:
            return min(100 * probe, max(1e-6, 1e-3 * probe))
        return min(100 * probe, np.sqrt(np.sqrt(np.sqrt(0.01 / largest))))

    @numba.njit(cache=False, error_model="numpy")
    def start(cases, y, derivative, indicator_table, arclength, force_controlled, slope, lam_end, target_sign,
              orientation, secondary_state, law, parameters, cos0, sin0, stage_number, recorded, record_count,
              step_size, probe, rtol, atol):
        """Cases ``cases`` start their (set up) stage: dy/ds, indicators, state stored
        (stage_entry._start_stage); the first step where ``step_size`` is NaN
        (stage_entry._estimate_first_steps)."""
        state = np.empty(M)
        ev = np.empty(16)
        aux = np.empty(6)
        f1 = np.empty(M)
        for i in cases:
            for j in range(M):
                state[j] = y[i, j]
            fc0, fc1, g0, g1 = force_controlled[i, 0], force_controlled[i, 1], slope[i, 0], slope[i, 1]
            parameters[i, state_slot] = secondary_state[i]
            rhs(state, fc0, fc1, g0, g1, orientation[i], law, parameters[i], cos0[i], sin0[i], derivative[i], ev, aux)
            indicators(ev, aux, state[2], fc0, fc1, lam_end[i], target_sign[i], secondary_state[i],
                       indicator_table[i])
            store_record(recorded, i, record_count[i], arclength[i], stage_number, state, ev, aux)
            record_count[i] += 1
            if np.isnan(step_size[i]):
                for j in range(M):
                    state[j] = y[i, j] + probe * derivative[i, j]
                rhs(state, fc0, fc1, g0, g1, orientation[i], law, parameters[i], cos0[i], sin0[i], f1, ev, aux)
                step_size[i] = initial_step_size(y[i], derivative[i], f1, probe, rtol, atol)

    return StageLoop(run_cases, start)
