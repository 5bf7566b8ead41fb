"""Directional second-order work and the cone of unstable directions (2 dofs).

For a unit loading direction du = (cos theta, sin theta) the normalised
second-order work is the quadratic form of K_sym,

    d2W(theta) = du . K du = m + r cos(2 theta - 2 phi),

with m = (K11 + K22)/2, r = hypot((K11 - K22)/2, (K12 + K21)/2) and
2 phi = atan2((K12 + K21)/2, (K11 - K22)/2).  Its minimum over theta is m - r,
the smallest eigenvalue of K_sym (Hill's condition).  d2W < 0 on two opposite
cones of directions; their bounds are the exact roots of the quadratic form,
theta = phi +- (1/2) arccos(-m/r) (mod pi), computed in closed form -- never by
counting samples.  All functions broadcast over leading batch dimensions.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "second_order_work_form",
    "directional_second_order_work",
    "unstable_cone",
]


def second_order_work_form(stiffness: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(m, r, phi) of d2W(theta) = m + r cos(2 theta - 2 phi) for ``(..., 2, 2)`` K."""
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.shape[-2:] != (2, 2):
        raise ValueError(f"directional second-order work needs 2x2 operators, got shape {stiffness.shape}")
    k11, k22 = stiffness[..., 0, 0], stiffness[..., 1, 1]
    shear = 0.5 * (stiffness[..., 0, 1] + stiffness[..., 1, 0])
    half_difference = 0.5 * (k11 - k22)
    mean = 0.5 * (k11 + k22)
    radius = np.hypot(half_difference, shear)
    phi = 0.5 * np.arctan2(shear, half_difference)
    return mean, radius, phi


def directional_second_order_work(stiffness: np.ndarray, theta: np.ndarray) -> np.ndarray:
    """d2W(theta) = e(theta) . K e(theta) for unit directions e = (cos, sin).

    Evaluated as K11 cos^2 + (K12 + K21) cos sin + K22 sin^2: a product of the
    (..., 3) coefficients with the (3, M) direction basis (one matrix product,
    no trigonometry per (state, direction) pair).

    Parameters
    ----------
    stiffness
        ``(..., 2, 2)``.
    theta
        Directions (rad), shape ``(M,)``: broadcast as a trailing axis.

    Returns
    -------
    numpy.ndarray
        ``(..., M)``, normalised by |du|^2 = 1.
    """
    stiffness = np.asarray(stiffness, dtype=float)
    if stiffness.shape[-2:] != (2, 2):
        raise ValueError(f"directional second-order work needs 2x2 operators, got shape {stiffness.shape}")
    theta = np.asarray(theta, dtype=float)
    c, s = np.cos(theta), np.sin(theta)
    basis = np.stack([c * c, c * s, s * s])  # (3, M)
    coefficients = np.stack(
        [stiffness[..., 0, 0], stiffness[..., 0, 1] + stiffness[..., 1, 0], stiffness[..., 1, 1]], axis=-1
    )
    return coefficients @ basis


def unstable_cone(stiffness: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Width and bounds of the cone of directions where d2W < 0.

    Returns
    -------
    (width, lower, upper)
        ``width``: total angle over the full circle of directions where
        d2W < 0 (rad, in [0, 2 pi]; 0 when Hill's condition holds).
        ``lower``, ``upper``: the bounds of one of the two opposite cones
        (the other is shifted by pi), with lower < upper, lower in [0, pi);
        the exact roots of d2W; NaN where there is no cone or where every
        direction is unstable.  All three are NaN where K is not finite (the
        padding of a path Dataset past a case's last state).
    """
    mean, radius, phi = second_order_work_form(stiffness)
    # (a radius of a denormal's size overflows -mean / radius to an infinity: the
    # cone is then everything or nothing, as for radius 0)
    with np.errstate(invalid="ignore", divide="ignore", over="ignore"):
        ratio = np.where(radius > 0, -mean / radius, np.where(mean < 0, np.inf, -np.inf))
    half_opening = np.arccos(np.clip(ratio, -1.0, 1.0))  # cos(2 theta - 2 phi) < -m/r
    width = np.where(ratio >= 1, 2 * np.pi, np.where(ratio <= -1, 0.0, 2 * (np.pi - half_opening)))
    width = np.where(np.isfinite(stiffness).all(axis=(-2, -1)), width, np.nan)
    partial = (ratio > -1) & (ratio < 1)
    lower = np.mod(phi + 0.5 * half_opening, np.pi)
    upper = lower + (np.pi - half_opening)
    lower = np.where(partial, lower, np.nan)
    upper = np.where(partial, upper, np.nan)
    return width, lower, upper
