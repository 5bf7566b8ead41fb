"""Coulomb friction and contact opening: each contact's state and its branches of the incremental tangent.

For a packing's tangent (:func:`ncstab.operators.packing_analysis.packing_tangent`) each
contact c has, on its dofs u_e = (x_a, y_a, theta_a, x_b, y_b, theta_b), the elastic rates of
its forces (in the law's units, N* = N/rho, T* = T/rho)::

    r_el = (dN_el, dT_el) = g du_e,   g = [-D*_0 J ; (D*_1 - T* e_0) J / l]      (2, 6)

(Q* = (-N*, l T*), so dQ*_1 = T* dl + l dT*), and its block of K is
``rho^2 (J^T D* J + Q* H) = K_geo + G r_el`` with ``G = rho^2 J^T diag(-1, l)`` (6, 2).
A branch b replaces the elastic rates by ``r = P_b r_el``; its block is the elastic one plus
the rank-2 correction ``G (P_b - I) g`` (the geometric terms of the current forces are kept:
they vanish at N = T = 0):

=======  ==========  ===================================  =================================
code     branch      rates r = P_b r_el                   where (linear in r_el, so in d)
=======  ==========  ===================================  =================================
0        stick       (dN_el, dT_el)                       sliding: s dT_el - mu dN_el <= 0;
                                                          open: dN_el >= 0, |dT_el| <= mu dN_el
1        slide +     (dN_el, +mu dN_el)                   sliding with s = +1: dT_el - mu dN_el >= 0;
                                                          open: also dN_el >= 0
2        slide -     (dN_el, -mu dN_el)                   as 1 with s = -1
3        separate    (0, 0)                               open only: dN_el <= 0
=======  ==========  ===================================  =================================

A contact is *open* where N <= OPEN_TOLERANCE max |N| (N <= 0 up to rounding), *sliding* where
|T| >= mu N (1 - SLIDING_TOLERANCE), s = sign T, else *sticking* (its only branch is 0: inside the
cone an infinitesimal increment is elastic).  A sliding contact either slides on the cone
(dT = mu s dN, the plastic multiplier positive: the elastic trial s dT_el - mu dN_el > 0) or unloads
elastically.  An open contact (a cone of zero width at the origin) separates freely when its normal
increment opens it, and when it closes it sticks if |dT_el| <= mu dN_el, else slides with s the sign
of the trial dT_el.  At a boundary between two branches both give the same rates (the correction
vanishes there), so the second-order work is continuous in d.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
from scipy import sparse

__all__ = ["OPEN_TOLERANCE", "SLIDING_TOLERANCE", "STATE_MEANINGS", "FrictionBranches", "contact_states",
           "friction_branches"]

#: A contact is sliding where |T| >= mu N (1 - SLIDING_TOLERANCE).
SLIDING_TOLERANCE = 1e-9
#: A contact is open where N <= OPEN_TOLERANCE * max |N| over the contacts.
OPEN_TOLERANCE = 1e-12
#: ``contact_state`` values 0, 1, 2.
STATE_MEANINGS = ("stick", "slide", "open")
STICK, SLIDE_POSITIVE, SLIDE_NEGATIVE, SEPARATE = 0, 1, 2, 3


def contact_states(normal: np.ndarray, tangential: np.ndarray, mu: np.ndarray) -> np.ndarray:
    """``(c,)`` int8: 0 stick, 1 slide (|T| >= mu N to SLIDING_TOLERANCE), 2 open (N <= 0 to OPEN_TOLERANCE)."""
    normal, tangential = np.asarray(normal, float), np.asarray(tangential, float)
    scale = float(np.max(np.abs(normal))) if normal.size else 0.0
    state = np.zeros(normal.shape, dtype=np.int8)
    state[np.abs(tangential) >= mu * normal * (1 - SLIDING_TOLERANCE)] = 1
    state[normal <= OPEN_TOLERANCE * scale] = 2
    return state


def _rate_matrices(mu: np.ndarray) -> np.ndarray:
    """``(k, 4, 2, 2)``: P_b of the four branch codes for each contact's mu."""
    P = np.zeros((len(mu), 4, 2, 2))
    P[:, STICK] = np.eye(2)
    P[:, SLIDE_POSITIVE, 0, 0] = P[:, SLIDE_NEGATIVE, 0, 0] = 1.0
    P[:, SLIDE_POSITIVE, 1, 0], P[:, SLIDE_NEGATIVE, 1, 0] = mu, -mu
    return P


@dataclass(frozen=True, eq=False)
class FrictionBranches:
    """The branches of the contacts at the Coulomb limit or open (see the module docstring).

    Attributes
    ----------
    K_elastic : (n, n) CSR
        K with every contact sticking.
    mu : (c,)
        Each contact's Coulomb ratio.
    state : (c,) int8
        0 stick, 1 slide, 2 open.
    limit : (k,) int
        The contacts that are not sticking (the only ones with a choice of branch).
    dofs : (k, 6) int
        Their dofs (held ones point at slot n).
    rates : (k, 2, 6)
        Their g: (dN*_el, dT*_el) = g du_e.
    lift : (k, 6, 2)
        Their G = rho^2 J^T diag(-1, l).
    sign : (k,)
        s = sign T of a sliding contact (0 for an open one).
    """

    K_elastic: Any
    mu: np.ndarray
    state: np.ndarray
    limit: np.ndarray
    dofs: np.ndarray
    rates: np.ndarray
    lift: np.ndarray
    sign: np.ndarray

    @property
    def n(self) -> int:
        return self.K_elastic.shape[0]

    @property
    def open(self) -> np.ndarray:
        """``(k,)`` bool: which limit contacts are open."""
        return self.state[self.limit] == 2

    def elastic_rates(self, d: np.ndarray) -> np.ndarray:
        """``(k, 2)``: (dN*_el, dT*_el) of the limit contacts for the increment ``d`` (n,)."""
        full = np.append(np.asarray(d, float), 0.0)
        return np.einsum("kre,ke->kr", self.rates, full[self.dofs])

    def constraints(self, pattern: np.ndarray) -> np.ndarray:
        """``(k, 3, 2)``: rows a with a . r_el >= 0 where each limit contact is on ``pattern``'s branch (zero rows pad)."""
        mu = self.mu[self.limit]
        k = len(self.limit)
        A = np.zeros((k, 3, 2))
        opened = self.open
        s = np.where(pattern == SLIDE_NEGATIVE, -1.0, 1.0)
        sliding = (pattern == SLIDE_POSITIVE) | (pattern == SLIDE_NEGATIVE)
        stick = pattern == STICK
        A[sliding, 0] = np.column_stack([-mu, s])[sliding]
        A[sliding & opened, 1] = (1.0, 0.0)
        closed_stick = stick & ~opened
        A[closed_stick, 0] = np.column_stack([mu, -self.sign])[closed_stick]
        open_stick = stick & opened
        A[open_stick, 0] = np.column_stack([mu, -np.ones(k)])[open_stick]
        A[open_stick, 1] = np.column_stack([mu, np.ones(k)])[open_stick]
        A[open_stick, 2] = (1.0, 0.0)
        A[pattern == SEPARATE, 0] = (-1.0, 0.0)
        return A

    def constraint_rows(self, pattern: np.ndarray) -> np.ndarray:
        """``(3k, n)``: the cone of ``pattern`` as {d : rows @ d >= 0} over the free dofs (zero rows kept)."""
        A = np.einsum("kjr,kre->kje", self.constraints(pattern), self.rates)
        k = len(self.limit)
        rows = np.zeros((k, 3, self.n + 1))
        np.add.at(rows, (np.arange(k)[:, None, None], np.arange(3)[None, :, None], self.dofs[:, None, :]), A)
        return rows[:, :, :self.n].reshape(-1, self.n)

    def select(self, d: np.ndarray) -> np.ndarray:
        """``(k,)`` the branch code each limit contact takes for the increment ``d`` (the module's table)."""
        r = self.elastic_rates(d)
        mu = self.mu[self.limit]
        slip = self.sign * r[:, 1] - mu * r[:, 0]
        pattern = np.where(slip > 0, np.where(self.sign > 0, SLIDE_POSITIVE, SLIDE_NEGATIVE), STICK)
        opened = self.open
        closing = r[:, 0] > 0
        trial = np.where(r[:, 1] - mu * r[:, 0] > 0, SLIDE_POSITIVE,
                         np.where(-r[:, 1] - mu * r[:, 0] > 0, SLIDE_NEGATIVE, STICK))
        return np.where(opened, np.where(closing, trial, SEPARATE), pattern).astype(np.int8)

    def consistent(self, d: np.ndarray, pattern: np.ndarray, tolerance: float = 1e-10) -> bool:
        """Whether ``d`` lies in ``pattern``'s cone (every constraint >= -tolerance max |r_el|)."""
        r = self.elastic_rates(d)
        values = np.einsum("kjr,kr->kj", self.constraints(pattern), r)
        scale = float(np.max(np.abs(r))) if r.size else 0.0
        return bool(np.all(values >= -tolerance * max(scale, 1e-300)))

    def tangent(self, pattern: np.ndarray):
        """K_P ``(n, n)`` CSR: K_elastic plus each limit contact's G (P_b - I) g for its branch in ``pattern``."""
        if not len(self.limit):
            return self.K_elastic
        P = _rate_matrices(self.mu[self.limit])[np.arange(len(self.limit)), pattern] - np.eye(2)
        blocks = np.einsum("ker,krs,ksf->kef", self.lift, P, self.rates)
        rows = np.repeat(self.dofs, 6, axis=1).ravel()
        cols = np.tile(self.dofs, (1, 6)).ravel()
        keep = (rows < self.n) & (cols < self.n)
        correction = sparse.csr_matrix((blocks.ravel()[keep], (rows[keep], cols[keep])), shape=(self.n, self.n))
        return (self.K_elastic + correction).tocsr()

    def sticking(self) -> np.ndarray:
        return np.zeros(len(self.limit), dtype=np.int8)

    def all_sliding(self) -> np.ndarray:
        """Every sliding contact on its slide branch, every open one separating."""
        return np.where(self.open, SEPARATE, np.where(self.sign > 0, SLIDE_POSITIVE, SLIDE_NEGATIVE)).astype(np.int8)

    def choices(self) -> list[tuple[int, ...]]:
        """Each limit contact's possible branch codes (sliding: stick, slide; open: all four)."""
        return [(STICK, SLIDE_POSITIVE, SLIDE_NEGATIVE, SEPARATE) if o else
                (STICK, SLIDE_POSITIVE if s > 0 else SLIDE_NEGATIVE) for o, s in zip(self.open, self.sign)]

    def full_state(self, pattern: np.ndarray) -> np.ndarray:
        """``(c,)`` int8 the contact states an increment on ``pattern`` leaves: 0 stick, 1 slide, 2 open (separating)."""
        state = np.zeros(len(self.state), dtype=np.int8)
        state[self.limit] = np.select([pattern == SEPARATE, pattern != STICK], [2, 1], 0)
        return state


def friction_branches(tangent: Any, mu: Any) -> FrictionBranches:
    """The branches of a packing's tangent (:class:`~ncstab.operators.packing_analysis.PackingTangent`) with
    Coulomb ratio ``mu`` (scalar or ``(c,)``; ``None``: no friction, every contact sticks, K_P = K)."""
    forces = tangent.forces
    c = len(forces)
    mu = np.broadcast_to(np.asarray(np.inf if mu is None else mu, dtype=float), (c,)).copy()
    state = contact_states(forces[:, 0], forces[:, 1], mu) if np.isfinite(mu).all() else np.zeros(c, np.int8)
    limit = np.flatnonzero(state != 0)
    J, D, Q, length = (np.asarray(a)[limit] for a in (tangent.jacobian, tangent.law_tangent, tangent.conjugates,
                                                         tangent.lengths))
    w = tangent.contacts.weight[limit]
    T_star = Q[:, 1] / length
    normal = -np.einsum("kp,kpe->ke", D[:, 0], J)
    shear = (np.einsum("kp,kpe->ke", D[:, 1], J) - T_star[:, None] * J[:, 0]) / length[:, None]
    rates = np.stack([normal, shear], axis=1)
    lift = np.stack([-w[:, None] * J[:, 0], (w * length)[:, None] * J[:, 1]], axis=2)
    sign = np.where(state[limit] == 2, 0.0, np.sign(forces[limit, 1]))
    sign[(state[limit] == 1) & (sign == 0)] = 1.0  # mu = 0 and T = 0: either way
    return FrictionBranches(tangent.K.tocsr(), mu, state, limit, tangent.contacts.dofs[limit], rates, lift, sign)
