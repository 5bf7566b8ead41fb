"""The dynamic variables of a path Dataset, from the stored states: M(u) s^2 + C s + K.

At every stored state (or located event) of a system with inertia, the
system's mass and damping matrices (:func:`ncstab.systems.compile.compile_system`)
with the stored K give the growth rate max Re s (the ``flutter`` variable),
the critical frequency at a flutter onset, or the 2n roots (``spectrum_re``,
``spectrum_im``).  (A system without inertia has the discriminant of K as its
``flutter`` variable, and a two-dof system with M = I and C = 0 its growth rate,
both from :mod:`ncstab.operators.stored_states`.)
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.result import PathResult

__all__ = ["case_parameters", "dynamics_at_states", "state_dynamics", "stored_spectrum"]


def case_parameters(result: "PathResult", extra: tuple[int, ...]) -> tuple[np.ndarray, ...]:
    """The system's parameters per case, broadcast over the trailing dims ``extra``
    and flattened: one value per (law, case, *extra)."""
    values = result.grid.case_values()
    size = result.grid.size
    out = []
    for spec in result.model.definition.parameters:
        per_case = np.asarray(values.get(spec.name, np.full(size, spec.default)), dtype=float)
        per_case = np.broadcast_to(per_case, (len(result.laws), size))
        out.append(np.broadcast_to(per_case.reshape(per_case.shape + (1,) * len(extra)), per_case.shape + extra).ravel())
    return tuple(out)


def dynamics_at_states(result: "PathResult", u: np.ndarray, K: np.ndarray, critical: bool = False) -> np.ndarray:
    """max Re s (or, ``critical``, the critical frequency) of M(u) s^2 + C s + K at
    states ``u`` ``(law, *sweep, *extra, n)`` with their K, NaN where K is."""
    return state_dynamics(result, u, K, case_parameters(result, u.shape[len(result.shape):-1]), critical)


def state_dynamics(
    result: "PathResult", u: np.ndarray, K: np.ndarray, parameters: tuple[np.ndarray, ...], critical: bool = False
) -> np.ndarray:
    """max Re s (or, ``critical``, the critical frequency) of M(u) s^2 + C s + K at
    states ``u`` ``(..., n)`` with their K ``(..., n, n)``, NaN where K is.

    ``parameters``: the system's parameters, one flat array each with a value per
    state in ``u``'s order (:func:`case_parameters`).  Each state's value depends on
    that state alone (:func:`ncstab.operators.dynamics.flutter_indicator`)."""
    from ncstab.operators.dynamics import critical_frequency, flutter_indicator

    return _at_finite_states(result, u, K, parameters, critical_frequency if critical else flutter_indicator, ())


def stored_spectrum(result: "PathResult", u: np.ndarray, K: np.ndarray) -> np.ndarray:
    """The 2n roots of det(M(u) s^2 + C s + K) at every stored state (NaN padding kept)."""
    from ncstab.operators.dynamics import dynamic_spectrum

    n = u.shape[-1]
    parameters = case_parameters(result, u.shape[len(result.shape):-1])
    return _at_finite_states(result, u, K, parameters, dynamic_spectrum, (2 * n,), complex)


def _at_finite_states(
    result: "PathResult", u: np.ndarray, K: np.ndarray, parameters: tuple[np.ndarray, ...],
    function: Callable[..., np.ndarray], tail: tuple[int, ...], dtype: type = float,
) -> np.ndarray:
    """``function(M, C, K)`` ``(..., *tail)`` at the states ``u`` ``(..., n)`` whose u and
    K are finite, with M(u) and C(u) from the system's compiled matrices and
    ``parameters`` (one value per state); NaN at the others (padding, failed cases)."""
    from ncstab.systems.compile import compile_system

    compiled = compile_system(result.model.definition)
    n = u.shape[-1]
    flat_u, flat_K = u.reshape(-1, n), K.reshape(-1, n, n)
    finite = np.isfinite(flat_K).all(axis=(-2, -1)) & np.isfinite(flat_u).all(axis=-1)
    out = np.full((flat_u.shape[0], *tail), np.nan, dtype=dtype)
    if finite.any():
        values = tuple(p[finite] for p in parameters)
        mass = compiled.mass(flat_u[finite], values)
        damping = compiled.damping(flat_u[finite], values)
        with np.errstate(invalid="ignore"):
            out[finite] = function(mass, damping, flat_K[finite])
    return out.reshape(u.shape[:-1] + tail)
