"""The stability indicators of one state, compiled: what the stage loop and the Dataset share.

One implementation for every caller.  The compiled stage loop computes them at
every state it evaluates, to watch their signs (det K for a limit point, the
least eigenvalue of K_sym for Hill's condition, the discriminant of K's
characteristic polynomial for flutter without inertia, det K_SS for the
controllability of a mixed control: :mod:`ncstab.paths.loop_diamond_model`,
:mod:`ncstab.paths.loop_general_output`); the Dataset computes them at every
stored state with :func:`stored_state_indicators`, which runs the same functions
over the states, one after the other, in a generated module of the cache folder
(:func:`ncstab.generated_modules.compiled_module`), or as plain Python while that
module's machine code is not cached and the states are few
(:func:`ncstab.paths.loop_route.evaluates_plain`).

For two dofs every indicator is a closed form, the operations of
:mod:`ncstab.operators.indicators` in the same order (the same numbers, bit for
bit); beyond, LAPACK's LU (det K, det K_SS) and symmetric eigenvalues (Hill),
and the eigenvalues of K for the discriminant.
"""

from __future__ import annotations

import functools
import math
import threading
from typing import Any

import numpy as np

from ncstab.jit import hot, njit

__all__ = [
    "INDICATOR_NAMES", "controlled_determinant", "determinant", "determinant_2", "discriminant_2",
    "eigenvalue_discriminant", "hill", "hill_2", "machine_code", "normalised_work", "normalised_work_2", "state_values",
    "runs_plain", "state_values_2", "stored_state_indicators",
]

#: The scalar indicators of :func:`state_values`, in its order (the Dataset's variables).
INDICATOR_NAMES = ("det_K", "hill", "d2W", "flutter", "mixed_control")


@hot
def determinant_2(k00, k01, k10, k11):
    """det K of a 2 x 2 matrix (seed Eq. 36: zero at a limit point under force control)."""
    return k00 * k11 - k01 * k10


@hot
def hill_2(k00, k01, k10, k11):
    """The least eigenvalue of K_sym = (K + K^T) / 2 of a 2 x 2 K: its mean diagonal minus
    the radius of its Mohr circle (K_sym's diagonal is K's, 0.5 (k + k) = k exactly)."""
    mean = 0.5 * (k00 + k11)
    return mean - np.hypot(0.5 * (k00 - k11), 0.5 * (k01 + k10))  # the C library's, as numpy's


@hot
def discriminant_2(k00, k01, k10, k11):
    """(tr K)^2 - 4 det K = (K11 - K22)^2 + 4 K12 K21 of a 2 x 2 K: negative where K has a
    complex pair of eigenvalues (flutter without inertia)."""
    difference = k00 - k11
    return difference * difference + 4 * k01 * k10


@njit
def determinant(matrix):
    """det of a finite n x n matrix: closed forms for n <= 2, LAPACK's LU beyond."""
    n = matrix.shape[0]
    if n == 1:
        return matrix[0, 0]
    if n == 2:
        return determinant_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    return np.linalg.det(np.ascontiguousarray(matrix))


@njit
def hill(matrix):
    """The least eigenvalue of (K + K^T) / 2 of a finite n x n K (Hill's condition holds
    while it is positive): closed forms for n <= 2, LAPACK's symmetric eigenvalues beyond."""
    n = matrix.shape[0]
    if n == 1:
        return matrix[0, 0]
    if n == 2:
        return hill_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    return np.linalg.eigvalsh(0.5 * (matrix + matrix.T))[0]


@njit
def eigenvalue_discriminant(matrix):
    """prod_{i<j} (lambda_i - lambda_j)^2 over the eigenvalues of a real n x n matrix (real,
    negative where it has one complex pair: the discriminant of its characteristic
    polynomial; :func:`discriminant_2` for n = 2).  NaN where an entry is not finite."""
    n = matrix.shape[0]
    for i in range(n):
        for j in range(n):
            if not np.isfinite(matrix[i, j]):
                return np.nan
    if n == 2:
        return discriminant_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1])
    eigenvalues = np.linalg.eigvals(matrix.astype(np.complex128))
    product = 1.0 + 0.0j
    for i in range(n):
        for j in range(i + 1, n):
            product = product * (eigenvalues[i] - eigenvalues[j]) ** 2
    return product.real


@njit
def controlled_determinant(matrix, controlled):
    """det K_SS over the force-controlled dofs S (``controlled``, a boolean per dof): the
    controllability of a mixed control, lost where it vanishes (seed Eq. 35: K22 with F2
    held and Delta_1 driven; det K under force control; 1 under a kinematic control)."""
    n = matrix.shape[0]
    m, last = 0, 0
    for i in range(n):
        if controlled[i]:
            m += 1
            last = i
    if m == 0:
        return 1.0
    if m == 1:
        return matrix[last, last]
    if m == n:
        return determinant(matrix)
    sub = np.empty((m, m))
    row = 0
    for i in range(n):
        if controlled[i]:
            column = 0
            for j in range(n):
                if controlled[j]:
                    sub[row, column] = matrix[i, j]
                    column += 1
            row += 1
    return determinant(sub)


@hot
def normalised_work_2(k00, k01, k10, k11, du0, du1):
    """du . K du / (|K du| |du|) of two dofs: the cosine between dF = K du and du along the
    path (numpy's einsum and norms, in their order)."""
    f0 = k00 * du0 + k01 * du1
    f1 = k10 * du0 + k11 * du1
    return (f0 * du0 + f1 * du1) / (math.sqrt(f0 * f0 + f1 * f1) * math.sqrt(du0 * du0 + du1 * du1))


@njit
def normalised_work(matrix, du):
    """du . K du / (|K du| |du|) of n dofs (:func:`normalised_work_2` for two)."""
    n = du.shape[0]
    if n == 2:
        return normalised_work_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1], du[0], du[1])
    work, force_norm, du_norm = 0.0, 0.0, 0.0
    for i in range(n):
        force = 0.0
        for j in range(n):
            force += matrix[i, j] * du[j]
        work += force * du[i]
        force_norm += force * force
        du_norm += du[i] * du[i]
    return work / (math.sqrt(force_norm) * math.sqrt(du_norm))


@hot
def state_values_2(k00, k01, k10, k11, du0, du1, controlled0, controlled1, staged):
    """:func:`state_values` of two dofs, from K's entries and du's (``staged``: whether the
    state has a stage, whose force-controlled dofs are ``controlled0``, ``controlled1``)."""
    mixed = np.nan
    if staged:
        if controlled0 and controlled1:
            mixed = determinant_2(k00, k01, k10, k11)
        elif controlled0:
            mixed = k00
        elif controlled1:
            mixed = k11
        else:
            mixed = 1.0
    return (determinant_2(k00, k01, k10, k11), hill_2(k00, k01, k10, k11),
            normalised_work_2(k00, k01, k10, k11, du0, du1), discriminant_2(k00, k01, k10, k11), mixed)


@njit
def state_values(matrix, du, controlled):
    """:data:`INDICATOR_NAMES` of one state with tangent ``matrix`` (n x n), increment
    ``du`` along the path and force-controlled dofs ``controlled`` (a boolean per dof; empty
    where the state has no stage: det K_SS NaN).  NaN where K is not finite (the closed
    forms of two dofs give what IEEE arithmetic gives, as numpy's do)."""
    n = matrix.shape[0]
    if n == 2:
        staged = controlled.shape[0] == 2
        return state_values_2(matrix[0, 0], matrix[0, 1], matrix[1, 0], matrix[1, 1], du[0], du[1],
                              staged and controlled[0], staged and controlled[1], staged)
    finite = True
    for i in range(n):
        for j in range(n):
            finite = finite and np.isfinite(matrix[i, j])
    det_k, least, mixed = np.nan, np.nan, np.nan
    if finite:
        det_k = determinant(matrix)
        least = hill(matrix)
        if controlled.shape[0] == n:
            mixed = controlled_determinant(matrix, controlled)
    return det_k, least, normalised_work(matrix, du), eigenvalue_discriminant(matrix), mixed


def _states_batch(stiffness, du, stage, controlled, symmetric, skew, out):
    # every stored state of (cases, steps): K_sym, K_skew and state_values; stage < 0: padding
    n = stiffness.shape[2]
    none = controlled[0, :0]
    for b in range(stiffness.shape[0]):
        for t in range(stiffness.shape[1]):
            for i in range(n):
                for j in range(n):
                    symmetric[b, t, i, j] = 0.5 * (stiffness[b, t, i, j] + stiffness[b, t, j, i])
                    skew[b, t, i, j] = 0.5 * (stiffness[b, t, i, j] - stiffness[b, t, j, i])
            k = stage[b, t]
            if n == 2:  # from the entries, no views
                values = state_values_2(
                    stiffness[b, t, 0, 0], stiffness[b, t, 0, 1], stiffness[b, t, 1, 0], stiffness[b, t, 1, 1],
                    du[b, t, 0], du[b, t, 1], k >= 0 and controlled[k, 0], k >= 0 and controlled[k, 1], k >= 0,
                )
            else:
                values = state_values(stiffness[b, t], du[b, t], controlled[k] if k >= 0 else none)
            for v in range(len(values)):
                out[v, b, t] = values[v]

def batch_signature() -> Any:
    """The signature :func:`stored_state_indicators` compiles: inputs of any layout, read
    only or not (a view of the recorder's padded rows, a contiguous stack, an archive's
    arrays), and outputs of any layout (a block's share of the Dataset's arrays): one
    compilation."""
    from numba import types

    def array(dtype: Any, ndim: int, readonly: bool = False) -> Any:
        return types.Array(dtype, ndim, "A", readonly=readonly)

    return types.void(
        array(types.float64, 4, True), array(types.float64, 3, True), array(types.int64, 2, True),
        array(types.boolean, 2, True), array(types.float64, 4), array(types.float64, 4), array(types.float64, 3),
    )


@functools.cache
def _module(plain: bool = False) -> Any:
    """This module's functions in a generated module of the cache folder (compiled, or
    with ``plain`` run as plain Python)."""
    from ncstab.generated_modules import compiled_module

    return compiled_module(
        __name__, determinant_2, hill_2, discriminant_2, determinant, hill, eigenvalue_discriminant,
        controlled_determinant, normalised_work_2, normalised_work, state_values_2, state_values, _states_batch,
        plain=plain,
    )


_COMPILING = threading.Lock()


@functools.cache
def _compiled_batch() -> Any:
    batch = _module()._states_batch
    batch.compile(batch_signature())
    batch.disable_compile()
    return batch


def machine_code() -> Any:
    """The compiled batch for :func:`batch_signature` (from numba's cache, or compiled now;
    one thread at a time), taking arrays of any layout without compiling again."""
    with _COMPILING:
        return _compiled_batch()


def stored_state_indicators(
    stiffness: np.ndarray, du: np.ndarray, stage: np.ndarray, controlled: np.ndarray,
    out: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None, plain: bool | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """K_sym, K_skew and :data:`INDICATOR_NAMES` at stored states.

    Parameters
    ----------
    stiffness, du, stage
        ``(cases, steps, n, n)``, ``(cases, steps, n)`` and ``(cases, steps)``: K, the
        increment along the path and the stage of each stored state (-1: padding after
        a case's last state), any layout (views are read where they are).
    controlled
        ``(stages, n)`` booleans: the force-controlled dofs of each stage.
    out
        Where to write (``K_sym``, ``K_skew``, the indicators ``(5, cases, steps)``), any
        layout: new arrays where None.
    plain
        Whether to run the functions as plain Python; None: as
        :func:`ncstab.paths.loop_route.evaluates_plain` says for this many states.

    Returns
    -------
    K_sym, K_skew, indicators
        ``out``: the first two shaped like ``stiffness``; ``indicators[k]`` is
        ``INDICATOR_NAMES[k]`` at every state.  ``flutter`` is K's discriminant; a system
        with inertia replaces it (:mod:`ncstab.paths.dataset_dynamics`).
    """
    cases, steps = stage.shape
    if out is None:
        out = (np.empty(stiffness.shape), np.empty(stiffness.shape), np.empty((len(INDICATOR_NAMES), cases, steps)))
    if cases * steps:
        if plain is None:
            plain = runs_plain(cases * steps)
        arguments = (stiffness, du, np.asarray(stage, dtype=np.int64), np.asarray(controlled, dtype=np.bool_), *out)
        if plain:
            with np.errstate(all="ignore"):
                _module(plain=True)._states_batch(*arguments)
        else:
            machine_code()(*arguments)
    return out


def runs_plain(states: int) -> bool:
    """Whether :func:`stored_state_indicators` runs ``states`` states as plain Python (its
    machine code not cached yet, and few states: :func:`ncstab.paths.loop_route.evaluates_plain`)."""
    from ncstab.paths.loop_route import evaluates_plain

    return evaluates_plain(states, _module()._states_batch)
