"""ncstab: stability analysis of non-conservative discrete systems.

The main entry points:

* :func:`ncstab.follow` -- follow a loading programme for laws and sweeps;
* :func:`ncstab.analyse` -- K, Hill's eigenvalue and modes of a granular packing;
* :func:`ncstab.boundary` -- a stability boundary traced as a curve (continuation);
* :func:`ncstab.make_law`, :class:`ncstab.DiamondChain`,
  :func:`ncstab.tangent_operator` -- the building blocks.

The names are imported on first use (:mod:`ncstab.lazy_imports`), so that
``import ncstab`` and ``ncstab --version`` import neither sympy nor scipy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ncstab.lazy_imports import lazy_attributes

__version__ = "0.1.0"

__all__ = ["DiamondChain", "PathOptions", "SystemSpec", "analyse", "boundary", "follow", "make_law", "open_study", "tangent_operator", "__version__"]

__getattr__, __dir__ = lazy_attributes(
    __name__,
    {
        "DiamondChain": "ncstab.systems",
        "PathOptions": "ncstab.paths",
        "analyse": "ncstab.analyse_command",
        "boundary": "ncstab.boundaries",
        "SystemSpec": "ncstab.paths",
        "follow": "ncstab.paths",
        "make_law": "ncstab.laws",
        "open_study": "ncstab.studies",
        "tangent_operator": "ncstab.operators",
    },
    globals(),
)

if TYPE_CHECKING:  # pragma: no cover
    from ncstab.analyse_command import analyse
    from ncstab.boundaries import boundary
    from ncstab.laws import make_law
    from ncstab.operators import tangent_operator
    from ncstab.paths import PathOptions, SystemSpec, follow
    from ncstab.studies import open_study
    from ncstab.systems import DiamondChain
