"""The shape of a Dataset's sweep, and the figure layout that fits it.

=====================================  ===================  ======================================
cases (all laws)                       layout               what a path figure kind draws
=====================================  ===================  ======================================
up to :data:`MAX_CURVES` (12)          ``"curves"``         one curve per case, events, closed forms
more, two swept parameters             ``"parameter_plane"`` a field over the two parameters per law
more, one (or three or more)           ``"fan"``            every path in one collection per law,
                                                            its envelope and a few labelled cases
=====================================  ===================  ======================================

Swept parameters of length 1 do not count: a sweep of 1 x 64 values is a
1-D sweep.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import xarray as xr

__all__ = ["MAX_CURVES", "SweepShape", "sweep_shape"]

#: Most cases drawn as individual curves (with labels, closed forms and events).
MAX_CURVES = 12


@dataclass(frozen=True)
class SweepShape:
    """What a Dataset sweeps.

    Attributes
    ----------
    laws
        Law names (``["law"]`` for a Dataset without a ``law`` dimension).
    dims
        The case dimensions (of ``n_steps``), in order, ``law`` included if present.
    swept
        Swept parameters with more than one value, in order (``law`` excluded).
    sizes
        Length of every dimension of ``dims``.
    """

    laws: tuple[str, ...]
    dims: tuple[str, ...]
    swept: tuple[str, ...]
    sizes: dict[str, int]

    @property
    def n_cases(self) -> int:
        return math.prod(self.sizes.values())

    @property
    def layout(self) -> str:
        """``"curves"``, ``"parameter_plane"`` or ``"fan"`` (module table)."""
        if self.n_cases <= MAX_CURVES:
            return "curves"
        return "parameter_plane" if len(self.swept) == 2 else "fan"


def sweep_shape(dataset: xr.Dataset) -> SweepShape:
    """The sweep of a path Dataset, read from the dimensions of ``n_steps``.

    Raises
    ------
    ValueError
        If the Dataset has no ``n_steps`` (not a path Dataset).
    """
    if "n_steps" not in dataset:
        raise ValueError("not a path Dataset: missing variable n_steps")
    dims = tuple(str(d) for d in dataset["n_steps"].dims)
    sizes = {d: int(dataset.sizes[d]) for d in dims}
    laws = (
        tuple(str(v) for v in np.atleast_1d(dataset["law"].values))
        if "law" in dims and "law" in dataset.coords
        else ("law",)
    )
    swept = tuple(d for d in dims if d != "law" and sizes[d] > 1)
    return SweepShape(laws=laws, dims=dims, swept=swept, sizes=sizes)
