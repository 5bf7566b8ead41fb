"""Integer powers printed as the products numba computes for them.

numba compiles ``x ** k`` for a constant integer ``k`` as an unrolled binary
exponentiation (``numba.cpython.numbers.static_power_impl``: the running product
times each squaring whose bit is set, and ``1.0 / r`` for ``k < 0``), where
CPython and numpy call the C library's ``pow``.  The two may differ by a
rounding (``x ** 3``, ``x ** -2``).  The kernels ncstab prints for numba are also
run as plain Python (:mod:`ncstab.plain_python`); printed as these products, an
integer power gives the same bits either way, and the compiled code does not change.
"""

from __future__ import annotations

__all__ = ["LARGEST_UNROLLED", "power_product"]

#: Exponents beyond this are printed as powers (``pow`` either way).
LARGEST_UNROLLED = 64


def power_product(base: str, exponent: int) -> str:
    """``base ** exponent`` (a non-zero integer, at most :data:`LARGEST_UNROLLED` in size)
    as the products numba computes, in its order: ``power_product("x", 3)`` is
    ``(x*(x*x))``, ``power_product("x", -2)`` is ``(1.0/(x*x))``.  ``base`` must be an
    atom or parenthesised."""
    if exponent == 0 or abs(exponent) > LARGEST_UNROLLED:
        raise ValueError(f"exponent {exponent}: only non-zero integers up to {LARGEST_UNROLLED} in size are unrolled")
    result, square, bits = None, base, abs(exponent)
    while bits:
        if bits & 1:
            result = square if result is None else f"({result}*{square})"
        bits >>= 1
        if bits:
            square = f"({square}*{square})"
    return f"(1.0/{result})" if exponent < 0 else f"({result})" if result == base else result
