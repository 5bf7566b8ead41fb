"""A tip load P on a chain of rigid bars given by their absolute angles: follower or dead.

Bar i (i = 1 .. n, from the base) has the length l_i and makes the angle phi_i with
the vertical (a dof); the tip is at x = sum_i l_i sin(phi_i), y = sum_i l_i cos(phi_i).
A load P acts at the tip (Ziegler 1952; Beck's column as n grows):

* **follower** -- along the last bar, toward the base: F = -P (sin phi_n, cos phi_n).  Its
  virtual work F . dx_tip = -P sum_i l_i sin(phi_n - phi_i) dphi_i gives, per unit P,

      Q_i = -l_i sin(phi_n - phi_i)          (Q_n = 0),
      dQ_i/dphi_i = l_i cos(phi_n - phi_i),  dQ_i/dphi_n = -l_i cos(phi_n - phi_i)   (i < n).

  dQ/du is not symmetric: the load has no potential, and K = K_int - P dQ/du is not
  symmetric either (the physics of the destabilisation paradox).
* **dead** -- vertical, downward: F = (0, -P), the potential P y_tip, so

      Q_i = l_i sin(phi_i),                  dQ_i/dphi_i = l_i cos(phi_i)   (diagonal).

The assembly (:mod:`ncstab.operators.assembly`) adds R -= P Q (dR/dP = -Q) and
K -= P dQ/du; dQ/du is given as 2 x 2 blocks on the dof pairs (phi_i, phi_n)
(follower) or (phi_i, phi_i) (dead, one entry), scattered like element matrices.
For two bars of unit length on the straight state, with the springs of Ziegler's
pendulum: K_follower = [[2 - P, P - 1], [-1, 1]] and K_dead = [[2 - P, -1], [-1, 1 - P]].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["TIP_LOADS", "TipLoad", "tip_load_terms"]

#: The kinds of tip load.
TIP_LOADS = ("follower", "dead")


@dataclass(frozen=True, eq=False)
class TipLoad:
    """A follower or dead load P at the tip of a chain of bars (see the module docstring).

    Attributes
    ----------
    kind
        ``"follower"`` or ``"dead"``.
    dofs
        The dof of each bar's absolute angle, from the base to the tip, ``(n,)``.
    lengths
        Each bar's length ``(n,)``, or None (every bar of length 1).
    parameter, units, description
        The load parameter's name, units and description (what a Dataset writes).
    """

    kind: str
    dofs: np.ndarray
    lengths: np.ndarray | None = None
    parameter: str = "P"
    units: str = "k/l"
    description: str = "tip load P (units k/l)"

    def __post_init__(self) -> None:
        if self.kind not in TIP_LOADS:
            raise ValueError(f"tip load: kind = {self.kind!r} is not allowed; allowed: {', '.join(TIP_LOADS)}")

    @property
    def size(self) -> int:
        return len(self.dofs)


def tip_load_terms(load: TipLoad, u: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The generalized load per unit P and its derivative as element blocks.

    Returns
    -------
    vector : (n,)
        Q_i on the bars' dofs ``load.dofs`` (module docstring).
    pairs : (b, 2)
        The dof pair of each block of dQ/du.
    blocks : (b, 2, 2)
        dQ/du on each pair (rows Q of the pair, columns its dofs).
    """
    phi = u[load.dofs]
    n = len(phi)
    length = np.ones(n) if load.lengths is None else np.asarray(load.lengths, dtype=float)
    blocks = np.zeros((n, 2, 2))
    if load.kind == "follower":
        relative = phi[-1] - phi
        vector = -length * np.sin(relative)
        slope = length * np.cos(relative)
        slope[-1] = 0.0  # Q_n = 0 identically
        pairs = np.stack([load.dofs, np.full(n, load.dofs[-1])], axis=1)
        blocks[:, 0, 0], blocks[:, 0, 1] = slope, -slope
    else:
        vector = length * np.sin(phi)
        pairs = np.stack([load.dofs, load.dofs], axis=1)
        blocks[:, 0, 0] = length * np.cos(phi)
    return vector, pairs, blocks
