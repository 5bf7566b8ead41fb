"""The signs of the compiled loop's event indicators: plain compiled functions.

The stage loops (the diamond's and the general models',
:mod:`ncstab.paths.compiled_source`) import them: values within rounding of zero
carry no sign, a contact indicator exactly at zero takes the sign of its
contact's state, and the stage target's indicator (:mod:`ncstab.paths.events`).
"""

from __future__ import annotations

import numba

from ncstab.paths.events import SIGN_NOISE, TINY

__all__ = ["significant", "signed_gap", "target_indicator"]

# Not cached beside ncstab's files: a loop compiles them into its own machine code (cached
# in ncstab's cache folder).
njit_signs = numba.njit(cache=False, error_model="numpy")


@njit_signs
def significant(value, size):
    """``value``, or 0 within rounding of zero (:data:`SIGN_NOISE` of the ``size`` of what
    it is built on): no sign."""
    return 0.0 if abs(value) <= SIGN_NOISE * size else value


@njit_signs
def signed_gap(value, secondary, bit):
    """A contact indicator; exactly at zero it takes the sign of its contact's state
    (``bit`` of ``secondary`` set: closed, -:data:`TINY`)."""
    if value == 0:
        return -TINY if (secondary & bit) > 0 else TINY
    return value


@njit_signs
def target_indicator(lam, lam_end, target_sign):
    """The stage target's indicator, (lambda - lambda_end) signed by the target's direction."""
    return (lam - lam_end) * target_sign
