"""The dynamic indicators of an assembled system with inertia, for the sparse engine.

An :class:`~ncstab.systems.assembled.AssembledSystem` whose ``inertia`` gives M(u) and C
(Ziegler's chain, :mod:`ncstab.systems.assembled_chain`) and that has at most
:data:`~ncstab.paths.assembled_result.STORED_K_LIMIT` dofs has, at every state, the roots s
of det(M s^2 + C s + K) = 0 -- its linearised dynamics about the state, computed dense by
the functions of the derived route (:mod:`ncstab.operators.dynamics`: the companion
matrix's eigenvalues, one implementation) on the system's ``pencil`` (the same polynomial,
a well-conditioned M).  From them:

* ``growth`` = max Re s (what :func:`~ncstab.operators.dynamics.flutter_indicator` gives, taken
  from the roots already computed): the Dataset's ``flutter``;
* ``onset`` = level - max {Re s : |Im s| > noise}, noise = :data:`GROWTH_NOISE` max(1, |s|_max),
  level = noise for an undamped system (C = 0) and 0 for a damped one: > 0 while no
  oscillating root grows, < 0 past a flutter onset (a complex pair crossed into Re s > 0).  Its sign change is the ``flutter_onset`` event, located like every
  event of the engine (:mod:`ncstab.paths.assembled_events`).  A real root through 0 (s = 0:
  divergence) is no oscillating root, and is the ``divergence`` event instead, the sign change
  of det K_SS of the stage's control (as the derived route tests it);
* ``frequency`` (:func:`~ncstab.operators.dynamics.critical_frequency`): omega of the
  critical pair, the Dataset's ``flutter_onset_frequency`` at the located onset.

The level: an undamped pair about to coalesce (+-i omega twice) is a nearly defective
eigenvalue, computed with an error of order sqrt(eps) |s| ~ 1e-8 |s|, and a spurious real
part of that size is no flutter.  Past the onset Re s grows like c sqrt(P - P_c), so the
level moves the located load by (GROWTH_NOISE / c)^2 (1e-13 for Ziegler's pendulum).  A
damped pair crosses Re s = 0 as a simple root, linearly in P, and its real part is exact to
rounding: the level is 0 (a dashpot of 1e-5 makes Re s of order 1e-5, and any level would
move the onset).  The derived route's smooth indicators
(:func:`~ncstab.operators.dynamics.flutter_onset_indicator`: the frequencies' discriminant,
the Hurwitz determinant) are products over pairs of roots that overflow beyond about 15 dofs
(+-inf at 20 bars, NaN at 40); the roots themselves do not.
"""

from __future__ import annotations

import numpy as np

from ncstab.operators.dynamics import critical_frequency, dynamic_spectrum

__all__ = ["GROWTH_NOISE", "dynamic_indicators", "has_dynamics"]

#: Below this part of max(1, |s|_max) a root's real or imaginary part carries no sign.
GROWTH_NOISE = 1e-7


def has_dynamics(system) -> bool:
    """Whether the sparse engine computes the dynamic indicators of ``system``: a mass matrix
    M(u) (``inertia``) and at most ``STORED_K_LIMIT`` dofs (a dense spectrum)."""
    from ncstab.paths.assembled_result import STORED_K_LIMIT

    return getattr(system, "inertia", None) is not None and system.n_dof <= STORED_K_LIMIT


def dynamic_indicators(system, u: np.ndarray, K) -> dict[str, float]:
    """``onset``, ``growth`` and ``frequency`` at the state ``u`` of tangent ``K`` (module docstring)."""
    M, C, stiffness = system.inertia.pencil(u, K)
    damping = C if np.any(C) else None
    roots = dynamic_spectrum(M, damping, stiffness)
    if not np.all(np.isfinite(roots)):
        return {"onset": np.nan, "growth": np.nan, "frequency": np.nan}
    noise = GROWTH_NOISE * max(1.0, float(np.max(np.abs(roots))))
    oscillating = roots.real[np.abs(roots.imag) > noise]
    level = noise if damping is None else 0.0  # a damped system's roots are simple: Re s exact to rounding
    return {
        "onset": float(level - oscillating.max()) if oscillating.size else noise,
        "growth": float(roots.real.max()),  # flutter_indicator's max Re s, of the roots already at hand
        "frequency": float(critical_frequency(M, damping, stiffness)),
    }
