"""A batched Dormand--Prince 8(5,3) step with per-case step sizes.

The same Butcher tableau and error estimator as ``scipy.integrate.DOP853``
(Hairer, Norsett & Wanner), applied to a batch of autonomous systems
``dy/ds = f(y)`` of shape (B, m), each case with its own step ``h`` (B,).
"""

from __future__ import annotations

from typing import Callable

import numpy as np
from scipy.integrate._ivp import dop853_coefficients as dop

__all__ = [
    "END_STAGE",
    "ERROR_EXPONENT",
    "combine_stages",
    "dense_output",
    "dop853_step",
    "error_norm",
    "evaluate_dense",
    "initial_step_size",
    "step_factor",
]

_A = dop.A[: dop.N_STAGES, : dop.N_STAGES]
_B = dop.B
_E3 = dop.E3
_E5 = dop.E5
#: Index of the stage evaluated at the end of the step (first same as last).
END_STAGE = dop.N_STAGES
#: Step-size controller exponent -1/(order + 1) with error order 7 (as scipy).
ERROR_EXPONENT = -1.0 / 8.0


def step_factor(err: np.ndarray) -> np.ndarray:
    """Step-size factor 0.9 err^(-1/8), clipped to [0.2, 10] (10 where err = 0).

    The eighth root is taken as three square roots: a square root is correctly
    rounded on every machine, where numpy's ``power`` may take SIMD code that
    rounds differently from the C library, so the step sizes (and with them
    every stored state) would depend on the processor and on the backend
    (:mod:`ncstab.paths.compiled` takes the same roots).  Non-finite ``err``
    (a failed step) gives NaN, for the caller to replace.
    """
    with np.errstate(divide="ignore", invalid="ignore"):
        factor = np.clip(0.9 / np.sqrt(np.sqrt(np.sqrt(err))), 0.2, 10.0)
    return np.where(err == 0, 10.0, factor)


def initial_step_size(
    y0: np.ndarray,
    f0: np.ndarray,
    f1: np.ndarray,
    probe: float,
    rtol: float,
    atol: float,
) -> np.ndarray:
    """First step length of each case: Hairer's estimate from a probe step.

    Hairer, Norsett & Wanner (1993, Sect. II.4; the starting-step algorithm of
    ``scipy.integrate.solve_ivp``) with the probe step ``probe`` given, not
    guessed from |y0| (a path starts at the undeformed state y0 = 0, where the
    guess falls back to 1e-6 and the estimate is capped at 1e-4):

        d1 = ||f0||,  d2 = ||f1 - f0|| / probe,  h1 = (0.01 / max(d1, d2))^(1/8),
        h = min(100 probe, h1)

    in the RMS norm scaled by ``atol + rtol |y0|``; h1 is the step whose
    leading local error term, for a method of order 7 (the exponent of the
    step-size control, :data:`ERROR_EXPONENT`), is about 1 % of the tolerance.
    Where d1 and d2 are both below 1e-15, h = max(1e-6, 1e-3 probe); where
    they are not finite, the probe itself.

    Parameters
    ----------
    y0
        ``(B, m)`` states at the start.
    f0, f1
        ``(B, m)`` dy/ds at ``y0`` and at ``y0 + probe f0``.
    probe
        The probe step (> 0).
    rtol, atol
        The step's tolerances.

    Returns
    -------
    numpy.ndarray
        ``(B,)`` step lengths.  The eighth root is taken as three square
        roots, as in :func:`step_factor` (the same on every processor).
    """
    scale = atol + np.abs(y0) * rtol
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        d1 = np.sqrt(np.mean(np.square(f0 / scale), axis=-1))
        d2 = np.sqrt(np.mean(np.square((f1 - f0) / scale), axis=-1)) / probe
        largest = np.maximum(d1, d2)
        h1 = np.sqrt(np.sqrt(np.sqrt(0.01 / largest)))
    h1 = np.where(largest <= 1e-15, max(1e-6, 1e-3 * probe), h1)
    return np.where(np.isfinite(largest), np.minimum(100 * probe, h1), probe)


def combine_stages(coefficients: np.ndarray, stages: np.ndarray) -> np.ndarray:
    """``sum_k coefficients[k] * stages[k]``, term by term in stage order.

    Elementwise on purpose: ``np.tensordot`` goes through BLAS, whose rounding
    of a case depends on the length and memory alignment of the whole batch,
    so that the same case followed in another batch (a chunk of a large sweep,
    ``ncstab.studies.run_study_chunked``) would differ in the last bits.  Here
    every case gets the same operations in the same order, whatever the batch.
    Terms after the first whose weight is exactly zero are skipped (a third
    of the DOP853 tableau): they would add +-0 (a non-finite stage they would
    turn into NaN reaches the result through the non-zero weights of the
    stages computed from it anyway).

    Parameters
    ----------
    coefficients
        ``(K,)`` or ``(P, K)`` weights.
    stages
        ``(K, B, m)`` stage derivatives (or any ``(K, ...)`` array).

    Returns
    -------
    numpy.ndarray
        ``(B, m)``, or ``(P, B, m)`` for 2-D coefficients.
    """
    if coefficients.ndim == 2:
        return np.stack([combine_stages(row, stages) for row in coefficients])
    total = np.multiply(coefficients[0], stages[0])
    term = np.empty_like(total)
    for weight, stage in zip(coefficients[1:], stages[1:]):
        if weight != 0:
            total += np.multiply(weight, stage, out=term)
    return total


def error_norm(stages: np.ndarray, h: np.ndarray, scale: np.ndarray) -> np.ndarray:
    """DOP853 error norm per case (scipy's ``_estimate_error_norm``, batched).

    Parameters
    ----------
    stages
        Stage derivatives, shape ``(N_STAGES + 1, B, m)``.
    h
        Step sizes, ``(B,)``.
    scale
        ``atol + rtol * max(|y0|, |y1|)``, ``(B, m)``.
    """
    err5 = combine_stages(_E5, stages) / scale
    err3 = combine_stages(_E3, stages) / scale
    err5_sq = np.sum(err5**2, axis=-1)
    err3_sq = np.sum(err3**2, axis=-1)
    denominator = err5_sq + 0.01 * err3_sq
    m = scale.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        norm = np.abs(h) * err5_sq / np.sqrt(denominator * m)
    return np.where(denominator > 0, norm, 0.0)


def dop853_step(
    rhs: Callable[[np.ndarray], np.ndarray],
    y0: np.ndarray,
    h: np.ndarray,
    rtol: float,
    atol: float,
    f0: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """One DOP853 step of size ``h`` (per case) from ``y0``.

    Parameters
    ----------
    rhs
        ``f(y) -> dy/ds`` on arrays of shape (B, m).
    y0
        States, ``(B, m)``.
    h
        Step sizes, ``(B,)`` (may differ per case).
    rtol, atol
        Tolerances for the error estimate.
    f0
        ``rhs(y0)`` if already known.

    Returns
    -------
    (y1, err, stages)
        New states ``(B, m)``, error norms ``(B,)`` (accept where <= 1;
        ``inf`` where a stage produced non-finite numbers) and the stage
        derivatives ``(N_STAGES + 1, B, m)`` (for :func:`dense_output`).
    """
    hb = h[:, None]
    stages = np.empty((dop.N_STAGES_EXTENDED,) + y0.shape)
    stages[0] = rhs(y0) if f0 is None else f0
    with np.errstate(all="ignore"):
        for s in range(1, dop.N_STAGES):
            dy = combine_stages(_A[s, :s], stages[:s]) * hb
            stages[s] = rhs(y0 + dy)
        y1 = y0 + hb * combine_stages(_B, stages[: dop.N_STAGES])
        stages[dop.N_STAGES] = rhs(y1)
        scale = atol + np.maximum(np.abs(y0), np.abs(y1)) * rtol
        err = error_norm(stages[: dop.N_STAGES + 1], h, scale)
    bad = ~np.isfinite(y1).all(axis=-1) | ~np.isfinite(err)
    err = np.where(bad, np.inf, err)
    return y1, err, stages


def dense_output(
    rhs: Callable[[np.ndarray], np.ndarray],
    y0: np.ndarray,
    y1: np.ndarray,
    h: np.ndarray,
    stages: np.ndarray,
) -> np.ndarray:
    """Coefficients of the DOP853 7th-order interpolant over a step (scipy's).

    Computes the three extra stages for the cases given (a subset of a step:
    pass the matching slices) and returns ``F`` of shape
    ``(INTERPOLATOR_POWER, B, m)`` for :func:`evaluate_dense`.
    """
    stages = stages.copy()
    hb = h[:, None]
    with np.errstate(all="ignore"):
        for s in range(dop.N_STAGES + 1, dop.N_STAGES_EXTENDED):
            dy = combine_stages(dop.A[s, :s], stages[:s]) * hb
            stages[s] = rhs(y0 + dy)
    f_old, f_new = stages[0], stages[dop.N_STAGES]
    delta = y1 - y0
    coefficients = np.empty((dop.INTERPOLATOR_POWER,) + y0.shape)
    coefficients[0] = delta
    coefficients[1] = hb * f_old - delta
    coefficients[2] = 2 * delta - hb * (f_new + f_old)
    coefficients[3:] = hb[None] * combine_stages(dop.D, stages)
    return coefficients


def evaluate_dense(y0: np.ndarray, coefficients: np.ndarray, fraction: np.ndarray) -> np.ndarray:
    """y at ``fraction`` (B,) of each step, from :func:`dense_output` (scipy's Horner form)."""
    x = fraction[:, None]
    y = np.zeros_like(y0)
    for i, f in enumerate(coefficients[::-1]):
        y += f
        y *= x if i % 2 == 0 else 1 - x
    return y + y0
