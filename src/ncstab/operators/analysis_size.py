"""The cost of ``ncstab analyse`` of a packing, known from its size before anything is built:
refused (exit code 2) when its memory is not there, announced on stderr when long.

The cost model is measured with ``/usr/bin/time -f "%e s %M kB" ncstab analyse`` of
triangular lattices (:func:`~ncstab.systems.packing.triangular_lattice`, bottom row held,
law ``mcnamara``, 6 modes) on two shared cores:

=========  =======  ========  ==========
grains     dofs     wall      peak RSS
=========  =======  ========  ==========
900        2,610    1.7 s     195 MB
10,000     29,700   4.4 s     321 MB
40,000     119,400  26.5 s    1,038 MB
=========  =======  ========  ==========

* wall time ``t(n) = 1.5 + 6e-5 n + 1.25e-9 n^2`` seconds (1.5 s: starting Python and
  the imports; the two other terms fitted to the two larger runs: assembly grows as n,
  the shift-invert factorizations of K_sym faster);
* peak memory ``200 MB + 8 kB n + 8 n (modes + 2)`` bytes (the slope of the peak RSS
  between the two larger runs, 8.0 kB a dof, and the modes' vectors).

An estimate is a guide within a factor of about 3, not a promise.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

__all__ = ["ANNOUNCED_SECONDS", "MAX_MODES", "AnalysisCost", "analysis_cost", "check_analysis_size"]

#: Seconds of an analysis: constant, per dof, per dof squared (measured: module docstring).
SECONDS = (1.5, 6e-5, 1.25e-9)
#: Resident bytes: constant, per dof (measured: module docstring).
BYTES = (200e6, 8_000)
#: An analysis estimated to take longer than this says so on stderr before it starts.
ANNOUNCED_SECONDS = 30.0
#: The most modes ``--modes`` may ask for (each is a Lanczos vector over all dofs; ARPACK's
#: cost grows with their number).
MAX_MODES = 100


@dataclass(frozen=True)
class AnalysisCost:
    """The estimated cost of analysing an ``n``-dof packing: ``seconds`` and ``memory_bytes``."""

    n: int
    seconds: float
    memory_bytes: float


def analysis_cost(n_dof: int, modes: int = 6) -> AnalysisCost:
    """The :class:`AnalysisCost` of an analysis of ``n_dof`` free dofs with ``modes`` modes."""
    a, b, c = SECONDS
    n = float(n_dof)
    return AnalysisCost(int(n_dof), a + b * n + c * n * n, BYTES[0] + BYTES[1] * n + 8.0 * n * (modes + 2))


def check_analysis_size(packing, modes: int = 6, announce: bool = True) -> AnalysisCost:
    """Refuse an analysis of ``packing`` that needs more memory than is available, or more
    than :data:`MAX_MODES` modes; say on stderr how long a long one will take (over
    :data:`ANNOUNCED_SECONDS`).

    Raises
    ------
    LimitError
        ``--modes`` over its limit, or the packing (named) and its memory estimate.
    """
    from ncstab.sizes import available_memory, readable_duration, readable_size
    from ncstab.studies.errors import LimitError

    if int(modes) > MAX_MODES:
        raise LimitError("--modes", f"{modes} modes", f"--modes: {modes} is more than the limit of {MAX_MODES}")
    cost = analysis_cost(packing.n_dof, int(modes))
    memory = available_memory()
    source = getattr(packing, "source", "the packing")
    if memory is not None and cost.memory_bytes > memory:
        raise LimitError(
            "PACKING", readable_size(cost.memory_bytes),
            f"{source}: {packing.n_grains:,} grains ({cost.n:,} free dofs) need about "
            f"{cost.memory_bytes / 1e9:.3g} GB of memory to analyse, more than the "
            f"{memory / 1e9:.3g} GB available (estimate)")
    if announce and cost.seconds > ANNOUNCED_SECONDS:
        print(f"ncstab: {source}: {packing.n_grains:,} grains, {cost.n:,} dofs: the analysis takes about "
              f"{readable_duration(cost.seconds)} and {readable_size(cost.memory_bytes)} of memory (estimate)",
              file=sys.stderr, flush=True)
    return cost
