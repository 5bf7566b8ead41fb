"""The size of a study's system, known before anything is built: its dofs, and for an
assembled system (more than :data:`~ncstab.systems.registry.DERIVED_DOFS_LIMIT` dofs) the
memory and time its run will take, said before it starts and refused (exit code 2) when
the memory is not there.

The cost model of the sparse engine is fitted to runs of rings and columns on two shared
cores (``benchmarks/bench_system_size.py``; docs/models.md, "Systems of any size"):

* time per stored state ``t(n) = 1e-2 + 1.3e-5 n + 5e-10 n^2`` seconds (measured: a ring
  of 1,000 grains 21 ms, of 10,000 grains 126 ms, of 50,000 grains 1.7 s; a column of
  1,000 links 17 ms); the n^2 term is the growth seen above 10^4 dofs (fill-in of the
  factorizations, cache misses), kept so that large systems are not under-estimated;
* working memory ``15 kB per dof`` (measured resident growth: 27 MB at 1,000 grains,
  150 MB at 10,000, 710 MB at 50,000), on top of the stored states.

An estimate is a guide within a factor of about 3, not a promise.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

__all__ = ["SystemCost", "check_system_size", "study_dofs", "system_cost"]

#: Seconds per stored state of the sparse engine: constant, per dof, per dof squared.
SECONDS_PER_STATE = (1e-2, 1.3e-5, 5e-10)
#: Resident bytes per dof while the sparse engine follows a path (factorizations, Lanczos).
WORKING_BYTES_PER_DOF = 15_000
#: A run estimated to take longer than this says so on stderr before it starts.
ANNOUNCED_SECONDS = 10.0


def study_dofs(study) -> int:
    """The number of dofs of ``study``'s system, from its settings alone (nothing built)."""
    from ncstab.paths.options import SystemSpec
    from ncstab.systems import SYSTEMS

    system = study.system
    if isinstance(system, SystemSpec):
        return int(SYSTEMS[system.name].dof_count(**system.settings))
    return int(system.n_dof)


@dataclass(frozen=True)
class SystemCost:
    """What following ``cases`` paths of an ``n``-dof assembled system costs, estimated.

    Attributes
    ----------
    n
        Dofs of the system.
    states
        Stored states of all cases together.
    seconds
        Wall time on one core, about.
    memory_bytes
        Working memory of one path plus the stored states of every case.
    """

    n: int
    states: float
    seconds: float
    memory_bytes: float


def system_cost(study) -> SystemCost | None:
    """The :class:`SystemCost` of ``study``, or None when its system is derived whole
    (at most :data:`~ncstab.systems.registry.DERIVED_DOFS_LIMIT` dofs: the compiled loop
    costs microseconds a state)."""
    from ncstab.studies.preflight import size_estimate
    from ncstab.systems.registry import DERIVED_DOFS_LIMIT

    n = study_dofs(study)
    if n <= DERIVED_DOFS_LIMIT:
        return None
    estimate = size_estimate(study)
    states = estimate.cases * estimate.mean_states
    a, b, c = SECONDS_PER_STATE
    seconds = states * (a + b * n + c * n * n)
    memory = WORKING_BYTES_PER_DOF * n + states * estimate.bytes_per_state
    return SystemCost(n, states, seconds, memory)


def _setting_key(study) -> str:
    from ncstab.paths.options import SystemSpec
    from ncstab.systems import SYSTEMS

    system = study.system
    if isinstance(system, SystemSpec) and SYSTEMS[system.name].size_setting:
        return f"[system] {SYSTEMS[system.name].size_setting}"
    return "[system]"


def check_system_size(study, announce: bool = True) -> SystemCost | None:
    """Refuse a system whose run needs more memory than is available; say how long a
    long run will take (on stderr, when over :data:`ANNOUNCED_SECONDS`).

    Raises
    ------
    LimitError
        Naming the setting that sets the size (``[system] grains``, ``[system] links``)
        and the memory estimated.
    """
    from ncstab.sizes import available_memory, readable_count, readable_duration, readable_size
    from ncstab.studies.errors import LimitError

    cost = system_cost(study)
    if cost is None:
        return None
    memory = available_memory()
    key = _setting_key(study)
    if memory is not None and cost.memory_bytes > memory:
        raise LimitError(
            key, readable_size(cost.memory_bytes),
            f"study {study.name!r}: a system of {cost.n:,} dofs followed over about "
            f"{readable_count(cost.states)} stored states needs about {readable_size(cost.memory_bytes)} of memory, "
            f"more than the {readable_size(memory)} available; use a smaller system ({key}) or fewer cases",
        )
    if announce and cost.seconds > ANNOUNCED_SECONDS:
        print(
            f"ncstab: study {study.name!r}: {cost.n:,} dofs, about {readable_count(cost.states)} stored states: "
            f"about {readable_duration(cost.seconds)} and {readable_size(cost.memory_bytes)} of memory (estimate)",
            file=sys.stderr,
        )
    return cost
