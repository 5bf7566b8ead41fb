"""Template, part 0 of the compiled stage loop: the signs of the event indicators.

Pasted first into every stage loop (the diamond's and the general models',
:mod:`ncstab.paths.compiled_source`): values within rounding of zero carry no
sign, a contact indicator exactly at zero takes the sign of its contact's state,
and the stage target's indicator (:mod:`ncstab.paths.events`).  The function
itself is never called.
"""

from __future__ import annotations

import numba

from ncstab.paths.events import SIGN_NOISE, TINY

__all__ = ["signs_part"]


def signs_part() -> None:
    """Define the indicators' sign helpers (a template: see the module docstring)."""
    njit_signs = numba.njit(cache=False, error_model="numpy", no_cpython_wrapper=True, no_cfunc_wrapper=True)
    sign_noise, tiny = SIGN_NOISE, TINY  # (tiny: read by the parts after this one too)

    @njit_signs
    def significant(value, size):
        # within rounding of zero (SIGN_NOISE of the
        # size of what it is built on), no sign
        return 0.0 if abs(value) <= sign_noise * size else value

    @njit_signs
    def signed_gap(value, secondary, bit):
        # a contact indicator exactly at zero takes the sign of its
        # contact's state (bit set: closed, -TINY)
        if value == 0:
            return -tiny if (secondary & bit) > 0 else tiny
        return value

    @njit_signs
    def target_indicator(lam, lam_end, target_sign):
        # the stage target, (lambda - lambda_end) sign
        return (lam - lam_end) * target_sign
