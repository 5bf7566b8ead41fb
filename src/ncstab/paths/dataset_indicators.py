"""The indicators of a path Dataset at every stored state, in blocks of whole cases.

A path Dataset (docs/archive.md) holds, at every stored
state, K's symmetric and skew parts, det K, the least eigenvalue of K_sym
(Hill's condition), the normalised second-order work, the ``flutter`` variable
and the determinant of the mixed control.  They come from K, u, du and the
stage by :mod:`ncstab.operators` (and :mod:`ncstab.paths.dataset_dynamics`),
each state's values from that state alone.

They are computed here in blocks of about :data:`BLOCK_STATES` states (whole
cases), dealt out to the study's threads (:func:`~ncstab.paths.threads.in_shares`;
numpy releases the GIL in its loops).  A block's temporaries fit in the cache,
where the whole sweep's (65,536 cases: 2.7 million states, 22 MB per
temporary) were fresh pages touched one by one.  The blocks depend on the
number of states only, never on the thread count; each block's arrays are
contiguous, like the whole sweep's, so each state's values are bit for bit
those of the operators on the whole sweep (tests/test_dataset_indicators.py).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from ncstab.operators.indicators import det_K, hill_eigenvalue, skew_part, symmetric_part
from ncstab.paths.dataset_dynamics import case_parameters, flutter_variable
from ncstab.paths.threads import in_shares

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.paths.result import PathResult

__all__ = ["BLOCK_STATES", "normalised_work", "state_indicators"]

#: States per block (whole cases, at least one): 32,768 states make a block's K
#: 1 MB and each temporary 256 kB.  On the 65,536-case Cundall--Strack sweep
#: (2.7 million states, 2 cores) the indicators took 0.85 s on one thread and
#: 0.49 s on two with it; 4,096 states per block: 0.90 s and 0.99 s (the threads
#: wait on each other's Python between numpy's loops), 262,144: 0.93 s and 0.54 s.
BLOCK_STATES = 1 << 15


def normalised_work(K: np.ndarray, du: np.ndarray) -> np.ndarray:
    """d2W along the path, du . K du / (|K du| |du|): the cosine between dF = K du and du."""
    dF = np.einsum("...ij,...j->...i", K, du)
    with np.errstate(invalid="ignore", divide="ignore"):
        return np.einsum("...i,...i->...", dF, du) / (np.linalg.norm(dF, axis=-1) * np.linalg.norm(du, axis=-1))


def state_indicators(
    result: "PathResult", K: np.ndarray, u: np.ndarray, du: np.ndarray, stage: np.ndarray
) -> tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]:
    """K and u as contiguous arrays, and the indicators at every stored state.

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
    K, u
        Contiguous copies.
    indicators
        ``K_sym``, ``K_skew`` (shaped like K), ``det_K``, ``hill``, ``d2W``,
        ``flutter`` and ``mixed_control`` (shaped like ``stage``).
    """
    lead, length, n = stage.shape[:-1], stage.shape[-1], u.shape[-1]
    cases = int(np.prod(lead, dtype=np.int64))
    rows_of = {"K": K.reshape(cases, length, n, n), "u": u.reshape(cases, length, n),
               "du": du.reshape(cases, length, n), "stage": stage.reshape(cases, length)}
    K_out, u_out = np.empty((cases, length, n, n)), np.empty((cases, length, n))
    out = {name: np.empty((cases, length, n, n)) for name in ("K_sym", "K_skew")}
    out.update({name: np.empty((cases, length)) for name in ("det_K", "hill", "d2W", "flutter", "mixed_control")})
    per_case = case_parameters(result, ())  # one value per (law, case), repeated over a block's states

    def block(rows: slice) -> None:
        K_out[rows] = rows_of["K"][rows]
        u_out[rows] = rows_of["u"][rows]
        K_block, u_block = K_out[rows], u_out[rows]
        out["K_sym"][rows] = symmetric_part(K_block)
        out["K_skew"][rows] = skew_part(K_block)
        out["det_K"][rows] = det_K(K_block)
        out["hill"][rows] = hill_eigenvalue(K_block)
        out["d2W"][rows] = normalised_work(K_block, np.ascontiguousarray(rows_of["du"][rows]))
        out["flutter"][rows] = flutter_variable(result, u_block, K_block, tuple(np.repeat(p[rows], length) for p in per_case))
        out["mixed_control"][rows] = result.mixed_control(K_block, rows_of["stage"][rows])

    per_block = max(1, BLOCK_STATES // max(length, 1))
    in_shares(block, [*range(0, cases, per_block), cases], "dataset")
    shaped = {name: value.reshape(lead + value.shape[1:]) for name, value in out.items()}
    return K_out.reshape(K.shape), u_out.reshape(u.shape), shaped
