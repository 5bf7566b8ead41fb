"""The stability indicators at every stored state of a path: the stage loop's functions in one pass.

:mod:`ncstab.operators.one_state` holds the indicators of one state, which the
compiled stage loop calls for its events.  Here they run over every stored state
(:func:`stored_state_indicators`, for the Dataset) and over a batch of 2 x 2
M^-1 K (:func:`undamped_growths`, for :func:`ncstab.operators.flutter_indicator`),
one state after the other: compiled by numba in a generated module of the cache
folder (:func:`ncstab.generated_modules.compiled_module`), or run as plain Python
while that module's machine code is not cached and the states are few
(:func:`ncstab.paths.loop_route.evaluates_plain`).  A state's values depend on it
alone, never on its batch.
"""

from __future__ import annotations

import functools
import threading
from typing import Any

import numpy as np

from ncstab.operators.one_state import (
    INDICATOR_NAMES, batch_of_growths, batch_of_states, controlled_determinant, determinant, determinant_2,
    discriminant_2, eigenvalue_discriminant, hill, hill_2, normalised_work, normalised_work_2, state_values,
    state_values_2, undamped_growth_2,
)

__all__ = [
    "batch_signature", "compile_batches", "machine_code", "runs_plain", "stored_state_indicators", "undamped_growths",
]


def batch_signature() -> Any:
    """The signature :func:`stored_state_indicators` compiles: inputs of any layout, read
    only or not (a view of the recorder's padded rows, a contiguous stack, an archive's
    arrays), and outputs of any layout (a block's share of the Dataset's arrays): one
    compilation."""
    from numba import types

    def array(dtype: Any, ndim: int, readonly: bool = False) -> Any:
        return types.Array(dtype, ndim, "A", readonly=readonly)

    return types.void(
        array(types.float64, 4, True), array(types.float64, 3, True), array(types.float64, 3, True),
        array(types.int64, 2, True), array(types.boolean, 2, True), types.boolean,
        array(types.float64, 4), array(types.float64, 4), array(types.float64, 3),
    )


@functools.cache
def _module(plain: bool = False) -> Any:
    """This module's functions in a generated module of the cache folder (compiled, or
    with ``plain`` run as plain Python)."""
    from ncstab.generated_modules import compiled_module

    return compiled_module(
        __name__, determinant_2, hill_2, discriminant_2, determinant, hill, eigenvalue_discriminant,
        controlled_determinant, normalised_work_2, normalised_work, state_values_2, state_values,
        undamped_growth_2, batch_of_states, batch_of_growths, plain=plain,
    )


_COMPILING = threading.Lock()


@functools.cache
def _compiled_batch() -> Any:
    batch = _module().batch_of_states
    batch.compile(batch_signature())
    batch.disable_compile()
    return batch


def machine_code() -> Any:
    """The compiled batch for :func:`batch_signature` (from numba's cache, or compiled now;
    one thread at a time), taking arrays of any layout without compiling again."""
    with _COMPILING:
        return _compiled_batch()


def compile_batches() -> None:
    """Compile (or load from numba's cache) both batches: :func:`stored_state_indicators`'s
    and :func:`undamped_growths`' (``ncstab cache compile``, the tests' warm-up)."""
    machine_code()
    _module().batch_of_growths(np.eye(2)[None], np.empty(1))


def stored_state_indicators(
    stiffness: np.ndarray, du: np.ndarray, stage: np.ndarray, controlled: np.ndarray, u: np.ndarray | None = None,
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
    u
        ``(cases, steps, 2)``, the states of a two-dof system whose M is the identity
        and C zero: ``flutter`` is then max Re s of M s^2 + K
        (:func:`undamped_growth_2`, NaN where K or u is not finite); None: K's
        discriminant, the ``flutter`` variable of a system without inertia (a system
        with other inertia replaces it, :mod:`ncstab.paths.dataset_dynamics`).
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
        ``INDICATOR_NAMES[k]`` at every state.
    """
    cases, steps = stage.shape
    if out is None:
        out = (np.empty(stiffness.shape), np.empty(stiffness.shape), np.empty((len(INDICATOR_NAMES), cases, steps)))
    if cases * steps:
        if plain is None:
            plain = runs_plain(cases * steps)
        arguments = (stiffness, du, du if u is None else u, np.asarray(stage, dtype=np.int64),
                     np.asarray(controlled, dtype=np.bool_), u is not None, *out)
        if plain:
            with np.errstate(all="ignore"):
                _module(plain=True).batch_of_states(*arguments)
        else:
            machine_code()(*arguments)
    return out


def undamped_growths(product: np.ndarray) -> np.ndarray:
    """``(...)``: :func:`undamped_growth_2` of each ``(..., 2, 2)`` P = M^-1 K, one after the
    other (compiled, or as plain Python where :func:`runs_plain` says so)."""
    rows = np.ascontiguousarray(np.asarray(product, dtype=float).reshape(-1, 2, 2))
    out = np.empty(rows.shape[0])
    if out.size:
        if runs_plain(out.size, _module().batch_of_growths):
            with np.errstate(all="ignore"):
                _module(plain=True).batch_of_growths(rows, out)
        else:
            _module().batch_of_growths(rows, out)
    return out.reshape(np.shape(product)[:-2])


def runs_plain(states: int, batch: Any = None) -> bool:
    """Whether ``batch`` (by default :func:`stored_state_indicators`'s) runs ``states`` states
    as plain Python: its machine code not cached yet, and few states
    (:func:`ncstab.paths.loop_route.evaluates_plain`)."""
    from ncstab.paths.loop_route import evaluates_plain

    return evaluates_plain(states, _module().batch_of_states if batch is None else batch)
