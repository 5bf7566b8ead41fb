"""ncstab: stability analysis of non-conservative discrete systems.

The main entry points:

* :func:`ncstab.follow` -- follow a loading programme for laws and sweeps;
* :func:`ncstab.make_law`, :class:`ncstab.DiamondChain`,
  :func:`ncstab.tangent_operator` -- the building blocks.
"""

__version__ = "0.1.0"

from ncstab.laws import make_law  # noqa: E402
from ncstab.paths import PathOptions, SystemSpec, follow  # noqa: E402
from ncstab.operators import tangent_operator  # noqa: E402
from ncstab.studies import open_study  # noqa: E402
from ncstab.systems import DiamondChain  # noqa: E402

__all__ = ["DiamondChain", "PathOptions", "SystemSpec", "follow", "make_law", "open_study", "tangent_operator", "__version__"]
