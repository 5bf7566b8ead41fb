"""Closed forms of the seed's pure-shear limit of the diamond (rigid normal, k_n -> infinity).

Seed Eq. (60)-(68): the branch length fixed by the law, the normal force a
reaction; forces in units of ``2R k_t`` (Eq. 62), lengths and displacements
in units of ``2R``, angles in radians.  Vectorised numpy functions that
broadcast like ufuncs, also named in :mod:`ncstab.systems.closed_forms`
with the seed's other closed forms.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = [
    "PURE_SHEAR_MODELS",
    "pure_shear_blocking_alpha",
    "pure_shear_displacement",
    "pure_shear_load_rotation",
    "pure_shear_max_displacement",
]

#: Shear spring models of the pure-shear limit: rotational shear springs
#: (McNamara et al. 2008; also the hypoelastic laws, seed Eq. 60) and
#: translational shear springs (Turco et al. 2019, seed Eq. 63).
PURE_SHEAR_MODELS = ("rotational", "translational")



def _check_model(model: str) -> str:
    if model not in PURE_SHEAR_MODELS:
        raise ValueError(f"model must be one of {PURE_SHEAR_MODELS}, got {model!r}")
    return model


def pure_shear_load_rotation(
    alpha: ArrayLike, alpha0: ArrayLike, F2hat: ArrayLike = 0.0, model: str = "rotational"
) -> np.ndarray:
    r"""Load-rotation curve of the pure-shear limit, forces in units of 2R k_t.

    * ``"rotational"`` (McNamara et al. 2008 and the hypoelastic laws, which
      coincide with it here, seed Eq. 60): seed Eq. (62),
      :math:`\hat F_1 = [2(\alpha - \alpha_0) + \hat F_2\cos\alpha]/\sin\alpha`
      (Eq. 66, first branch, for F2hat = 0);
    * ``"translational"`` (Turco et al. 2019): seed Eq. (65),
      :math:`\hat F_1 = [\sin(2\alpha - 2\alpha_0) + \hat F_2\cos(2\alpha - \alpha_0)]
      /\sin(2\alpha - \alpha_0)`.

    This is the first branch, before the secondary contact blocks the chain
    (:func:`pure_shear_blocking_alpha`).

    Parameters
    ----------
    alpha, alpha0 : array_like
        Branch orientation and its initial value (rad).
    F2hat : array_like, optional
        Constant lateral force F2/(2R k_t).
    model : {"rotational", "translational"}
        Shear spring model.

    Returns
    -------
    ndarray
        F1hat = F1/(2R k_t), broadcast shape of the inputs.
    """
    _check_model(model)
    alpha, alpha0, F2hat = (np.asarray(a, dtype=float) for a in (alpha, alpha0, F2hat))
    if model == "rotational":
        return (2 * (alpha - alpha0) + F2hat * np.cos(alpha)) / np.sin(alpha)
    return (np.sin(2 * alpha - 2 * alpha0) + F2hat * np.cos(2 * alpha - alpha0)) / np.sin(
        2 * alpha - alpha0
    )


def pure_shear_displacement(
    alpha: ArrayLike, alpha0: ArrayLike, model: str = "rotational"
) -> np.ndarray:
    r"""Vertical displacement Delta_1* in the pure-shear limit.

    * ``"rotational"``: l* = 1 (Eq. 60), seed Eq. (61):
      :math:`\Delta_1^* = \cos\alpha_0 - \cos\alpha`;
    * ``"translational"``: l* = cos(alpha - alpha0) (Eq. 63), seed Eq. (64):
      :math:`\Delta_1^* = \cos\alpha_0 - \cos\alpha\cos(\alpha - \alpha0)`.

    Parameters
    ----------
    alpha, alpha0 : array_like
        Branch orientation and its initial value (rad).
    model : {"rotational", "translational"}
        Shear spring model.

    Returns
    -------
    ndarray
        Delta_1* = Delta_1/(2R), broadcast shape of the inputs.
    """
    _check_model(model)
    alpha, alpha0 = (np.asarray(a, dtype=float) for a in (alpha, alpha0))
    if model == "rotational":
        return np.cos(alpha0) - np.cos(alpha)
    return np.cos(alpha0) - np.cos(alpha) * np.cos(alpha - alpha0)


def pure_shear_blocking_alpha(alpha0: ArrayLike, model: str = "rotational") -> np.ndarray:
    r"""alpha_max at which the secondary contact blocks the pure-shear chain.

    The top and bottom grains touch when the vertical half-diagonal
    l* cos(alpha) of the diamond falls to 1/2:

    * ``"rotational"``: 2 cos(alpha) = 1, alpha_max = pi/3 (seed Eq. 66-67);
    * ``"translational"``: cos(alpha) cos(alpha - alpha0) = 1/2 (seed Eq. 68),
      i.e. cos(2 alpha - alpha0) = 1 - cos(alpha0), solved in closed form:
      alpha_max = (alpha0 + arccos(1 - cos alpha0)) / 2.

    Parameters
    ----------
    alpha0 : array_like
        Initial orientation (rad).
    model : {"rotational", "translational"}
        Shear spring model.

    Returns
    -------
    ndarray
        alpha_max (rad), shape of ``alpha0``; NaN where alpha0 is not in
        (0, pi/3) (the grains would already touch or overlap at rest).
    """
    _check_model(model)
    alpha0 = np.asarray(alpha0, dtype=float)
    valid = (alpha0 > 0) & (alpha0 < np.pi / 3)
    if model == "rotational":
        return np.where(valid, np.pi / 3, np.nan)
    safe = np.where(valid, alpha0, np.pi / 4)
    return np.where(valid, (safe + np.arccos(1 - np.cos(safe))) / 2, np.nan)


def pure_shear_max_displacement(alpha0: ArrayLike) -> np.ndarray:
    r"""Delta_1*,max at which the pure-shear chain is blocked.

    Seed Eq. (67)-(68): :math:`\Delta_{1,\max}^* = \cos\alpha_0 - \tfrac12`
    for both shear spring models ((sqrt(2) - 1)/2 for alpha0 = pi/4).

    Parameters
    ----------
    alpha0 : array_like
        Initial orientation (rad).

    Returns
    -------
    ndarray
        Delta_1*,max, shape of ``alpha0``.
    """
    return np.cos(np.asarray(alpha0, dtype=float)) - 0.5
