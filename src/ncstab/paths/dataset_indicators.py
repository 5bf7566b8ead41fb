"""The indicators of a path Dataset at every stored state.

A path Dataset (docs/archive.md) holds, at every stored state, K's symmetric and
skew parts, det K, the least eigenvalue of K_sym (Hill's condition), the
normalised second-order work, the ``flutter`` variable and the determinant of
the mixed control.  They come from K, du and the stage by the compiled per-state
functions the stage loop uses for its events
(:func:`ncstab.operators.stored_states.stored_state_indicators`, reading the
stored states where the recorder keeps them: no copies).  The ``flutter``
variable of a system with inertia is max Re s of M(u) s^2 + C s + K: in the same
pass for two dofs with M = I and C = 0 (the reduced diamond), else from
:mod:`ncstab.paths.dataset_dynamics`.

Each state's values come from that state alone, so they are computed in blocks
of about :data:`BLOCK_STATES` states (whole cases), dealt out to the study's
threads (:func:`~ncstab.paths.threads.in_shares`; the kernel and numpy release
the GIL): the blocks never change a number (tests/test_dataset_indicators.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.paths.dataset_dynamics import case_parameters, state_dynamics
from ncstab.paths.threads import in_shares

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.result import PathResult

__all__ = ["BLOCK_STATES", "state_indicators"]

#: States per block (whole cases, at least one): 32,768 states make a block's K 1 MB and
#: the dynamics' temporaries a few hundred kB, which stay in the cache.
BLOCK_STATES = 1 << 15


def _identity(matrix, n: int, zero: bool = False) -> bool:
    """Whether a system's matrix (rows of numbers or expressions) is the n x n identity
    (``zero``: None, or every entry zero), to the last bit."""
    if matrix is None:
        return zero
    try:
        entries = [[float(entry) for entry in row] for row in matrix]
    except (TypeError, ValueError):  # an expression of the dofs or parameters
        return False
    target = np.zeros((n, n)) if zero else np.eye(n)
    return np.shape(entries) == (n, n) and bool((np.array(entries) == target).all())


def state_indicators(
    result: "PathResult", K: np.ndarray, u: np.ndarray, du: np.ndarray, stage: np.ndarray
) -> dict[str, np.ndarray]:
    """The indicators at every stored state.

    Parameters
    ----------
    result
        The paths (its system's inertia and parameters, its stages' controls).
    K, u, du, stage
        ``(law, *sweep, step, n, n)``, ``(law, *sweep, step, n)`` (twice) and
        ``(law, *sweep, step)``: the stored states, possibly views with room
        between the cases (the recorder's padded rows).

    Returns
    -------
    dict
        ``K_sym``, ``K_skew`` (shaped like K), ``det_K``, ``hill``, ``d2W``,
        ``flutter`` and ``mixed_control`` (shaped like ``stage``).
    """
    # (imported here: numba, with scipy, is not for commands that only read archives)
    from ncstab.operators.one_state import INDICATOR_NAMES
    from ncstab.operators.stored_states import runs_plain, stored_state_indicators

    lead, length, n = stage.shape[:-1], stage.shape[-1], u.shape[-1]
    cases = int(np.prod(lead, dtype=np.int64))
    controlled = np.zeros((len(result.programme.stages), n), dtype=bool)
    for k in range(controlled.shape[0]):
        controlled[k, result.force_controlled(k)] = True
    rows = {"K": K.reshape(cases, length, n, n), "u": u.reshape(cases, length, n),
            "du": du.reshape(cases, length, n), "stage": stage.reshape(cases, length)}
    symmetric, skew = np.empty(rows["K"].shape), np.empty(rows["K"].shape)
    values = np.empty((len(INDICATOR_NAMES), cases, length))
    definition = result.model.definition
    identity = n == 2 and _identity(definition.mass, n) and _identity(definition.damping, n, zero=True)
    inertia = definition.mass is not None and not identity  # (M = I, C = 0: in the compiled pass)
    per_case = case_parameters(result, ()) if inertia else ()  # one value per (law, case)
    plain = runs_plain(cases * length)

    def block(share: slice) -> None:
        stored_state_indicators(rows["K"][share], rows["du"][share], rows["stage"][share], controlled,
                                rows["u"][share] if identity else None,
                                (symmetric[share], skew[share], values[:, share]), plain)
        if inertia:  # max Re s of M s^2 + C s + K
            parameters = tuple(np.repeat(p[share], length) for p in per_case)
            values[INDICATOR_NAMES.index("flutter"), share] = state_dynamics(
                result, rows["u"][share], rows["K"][share], parameters)

    per_block = max(1, BLOCK_STATES // max(length, 1))
    in_shares(block, [*range(0, cases, per_block), cases], "dataset")
    out = {name: value.reshape(lead + (length,)) for name, value in zip(INDICATOR_NAMES, values)}
    out["K_sym"], out["K_skew"] = symmetric.reshape(K.shape), skew.reshape(K.shape)
    return out
