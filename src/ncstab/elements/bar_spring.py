"""Rigid bars whose rise is linear in the dofs: rotational springs between them, and the axial load.

A bar's rise is the sine of its angle from the axis, linear in the dofs
(Hencky's column: bar i rises by w_i - w_{i-1} over its unit length, so
theta_i = asin(w_i - w_{i-1})).  A rotational spring between bars a and b
measures q = theta_b - theta_a; with theta = asin(r), dtheta/dr = (1 - r^2)^(-1/2),
d2theta/dr2 = r (1 - r^2)^(-3/2):

    J = theta_b' a_b - theta_a' a_a,      H = theta_b'' a_b a_b^T - theta_a'' a_a a_a^T

on the spring's own dofs (a_a, a_b the rises' coefficients there).  An axial dead
load P does the work P sum_i (1 - cos theta_i) (docs/models.md,
``column``): its generalized load Q_ext = sum_i r_i / cos(theta_i) a_i and its
derivative sum_i cos(theta_i)^(-3) a_i a_i^T, per bar (:func:`shortening`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["BarSprings", "bar_angles", "shortening"]


@dataclass(frozen=True, eq=False)
class BarSprings:
    """Rotational springs between pairs of bars whose rises are linear in the dofs.

    Attributes
    ----------
    names
        Spring names, ``(m,)``.
    dofs
        Global dof index of each spring's local dofs, ``(m, L)``; a padding
        entry (a dof that is not there, such as a pinned end) has index 0 and
        zero coefficients.
    rises
        Coefficients of the rises of bar a (row 0) and bar b (row 1) on the
        local dofs, ``(m, 2, L)``.
    weight
        Weight of every spring in the internal virtual work.
    rest
        Each spring's q where it is stress-free ``(m,)`` (a stress-free shape that is not
        straight: an imperfect column), or None for 0.  J and H do not depend on it.
    """

    names: tuple[str, ...]
    dofs: np.ndarray
    rises: np.ndarray
    weight: float = 1.0
    rest: np.ndarray | None = None

    @property
    def size(self) -> int:
        return len(self.names)

    def kinematics(self, u: np.ndarray, second: bool = True):
        """q = theta_b - theta_a - rest ``(m, 1)``, J ``(m, 1, L)``, H ``(m, 1, L, L)`` (or None)."""
        r = np.einsum("mkl,ml->mk", self.rises, u[self.dofs])
        cosine2 = 1.0 - r * r
        theta = np.arcsin(r)
        slope = 1.0 / np.sqrt(cosine2)
        sign = np.array([-1.0, 1.0])
        q = (theta @ sign)[:, None] if self.rest is None else (theta @ sign - self.rest)[:, None]
        J = np.einsum("k,mk,mkl->ml", sign, slope, self.rises)[:, None, :]
        if not second:
            return q, J, None
        bend = r * slope / cosine2
        H = np.einsum("k,mk,mka,mkb->mab", sign, bend, self.rises, self.rises)[:, None]
        return q, J, H


def bar_angles(rise_dofs: np.ndarray, rise_signs: np.ndarray, u: np.ndarray) -> np.ndarray:
    """Rises of bars given as signed sums of dofs: ``r_i = sum_k sign_ik u[dof_ik]``.

    ``rise_dofs``, ``rise_signs``: ``(bars, K)``; a missing term has sign 0.
    Returns the rises ``(bars,)`` (the sine of each bar's angle).
    """
    return np.einsum("bk,bk->b", rise_signs, u[rise_dofs])


def shortening(rise_dofs: np.ndarray, rise_signs: np.ndarray, u: np.ndarray, lengths: np.ndarray | None = None):
    """The axial load's work per unit P and its derivatives, bar by bar.

    ``lengths``: each bar's length L_i ``(bars,)`` in units of the reference length a (``None``:
    every bar of length 1, Hencky's column); bar i shortens the chain by L_i (1 - cos theta_i).

    Returns
    -------
    work : float
        sum_i L_i (1 - cos theta_i).
    load : (bars, K)
        dW/dr_i a_i on each bar's dofs: L_i r_i / cos(theta_i) times the signs.
    stiffness : (bars, K, K)
        d2W/dr_i2 a_i a_i^T = L_i cos(theta_i)^(-3) sign sign^T.
    rises : (bars,)
    """
    r = bar_angles(rise_dofs, rise_signs, u)
    cosine = np.sqrt(1.0 - r * r)
    length = np.ones_like(r) if lengths is None else np.asarray(lengths, dtype=float)
    work = float(np.sum(length * (1.0 - cosine)))
    load = (length * r / cosine)[:, None] * rise_signs
    stiffness = (length * cosine ** -3)[:, None, None] * rise_signs[:, :, None] * rise_signs[:, None, :]
    return work, load, stiffness, r
