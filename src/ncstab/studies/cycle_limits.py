"""The memory of a study's cycle stages, estimated before anything runs.

The compiled stepper keeps, for every case it runs at once and every turn of
the programme's cycle stages, the work and the forces where the turn closes
and a flag (:mod:`ncstab.paths.compiled_stages`: four floats and a boolean),
allocated when the cases start; the archive then keeps per-turn tables.  A
study asking for ``turns = 1000000000`` would allocate 30 GiB per case before
its first step: :func:`check_cycle_turns` refuses it first, naming the stage's
``turns`` (exit code 2).
"""

from __future__ import annotations

from ncstab.sizes import available_memory, readable_size
from ncstab.studies.errors import LimitError

__all__ = ["TURN_BYTES", "check_cycle_turns", "cycle_turns"]

#: Bytes per case and turn while the cases run: W, F1, F2, T where the turn closes
#: (float64) and whether it closed (one byte) -- a lower bound of what is held.
TURN_BYTES = 4 * 8 + 1


def cycle_turns(study) -> list[tuple[int, int]]:
    """(stage number from 1, turns) of each cycle stage of the study's programme."""
    return [(number, int(stage.turns)) for number, stage in enumerate(study.programme.stages, start=1)
            if hasattr(stage, "turns")]


def check_cycle_turns(study, cases_in_memory: int | None = None, memory: int | None = None) -> float:
    """Refuse cycle stages whose per-turn tables do not fit in memory.

    Parameters
    ----------
    study
        The validated study.
    cases_in_memory
        Cases run at once (a chunk on each worker); default every case.
    memory
        Bytes available; default :func:`~ncstab.sizes.available_memory`.

    Returns
    -------
    float
        The estimated bytes (0 without a cycle stage).

    Raises
    ------
    LimitError
        Naming ``loading[k].cycle.turns`` of the stage with the most turns and the estimate.
    """
    stages = cycle_turns(study)
    if not stages:
        return 0.0
    cases = study.n_cases if cases_in_memory is None else min(study.n_cases, int(cases_in_memory))
    total = sum(turns for _, turns in stages)
    need = float(cases) * total * TURN_BYTES
    memory = available_memory() if memory is None else memory
    if memory is not None and need > memory:
        number, turns = max(stages, key=lambda item: item[1])
        key = f"loading[{number}].cycle.turns"
        raise LimitError(
            key, readable_size(need),
            f"{key} = {turns:,}: the turn tables of {cases:,} case(s) x {total:,} turns need at least "
            f"{readable_size(need)} of memory, more than the {readable_size(memory)} available; use fewer "
            "turns (or fewer cases per chunk: --chunk-cases)",
        )
    return need
