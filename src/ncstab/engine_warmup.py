"""Compile the compiled stepper's loops ahead of time: ``ncstab cache compile`` and the tests' warm-up.

numba compiles the compiled stepper's loop once per kind of model (the reduced
diamond, the general models) and machine, and keeps its machine code in the
cache folder ``compiled`` (:mod:`ncstab.cache`): 30-90 s a loop on 2 cores.  A
small study does not wait for it (it runs the loop as plain Python,
:mod:`ncstab.paths.loop_route`); a large one compiles first.
:func:`compile_loops` pays that cost up front, in several processes at once,
each compiling the loop of one kind of model, by following one tiny path per
item through the public API with ``backend = "compiled"``:

* a law's name: the reduced diamond with that law (the diamond's loop, and the
  law's own kernel);
* ``general-total``: the general models' loop (a column of four links, with its
  model kernel);
* ``general-rate``: the model kernel of a ring of four grains with Cundall-Strack
  (a rate law), without the loop: it goes with the diamond's items, so that the
  two processes take about as long;
* ``dataset``: the indicators of the stored states and the growth rate of two-dof
  dynamics (:func:`ncstab.operators.stored_states.compile_batches`, a few seconds),
  with the diamond's items too.

Run as a module (``python -m ncstab.engine_warmup ITEM ...``) it compiles the items
named, in this process.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor, as_completed
from pathlib import Path

__all__ = ["ENGINE_ITEMS", "GENERAL_ITEMS", "compile_items", "compile_loops", "groups_by_model"]

#: The general models' items: their loop (a column's path), a ring's kernel under a rate law.
GENERAL_ITEMS = ("general-total", "general-rate")
#: What ``ncstab cache compile`` compiles: the diamond's loop (with a law of each form,
#: whose kernels are compiled too), the general models' items and the Dataset's indicators.
ENGINE_ITEMS = ("mcnamara", "cundall_strack", *GENERAL_ITEMS, "dataset")
#: Seconds one process may take (a loop compiles in 30-90 s on 2 cores, more under load).
PROCESS_TIMEOUT = 900


def compile_items(items: Sequence[str]) -> None:
    """Follow one tiny path per item with ``backend = "compiled"`` (see the module docstring).

    Raises
    ------
    RuntimeError
        When an item did not run on the compiled stepper.
    """
    from ncstab.paths import PathOptions, SystemSpec, follow

    options = PathOptions(backend="compiled", max_step=1.0)
    for item in items:
        if item == "general-total":
            programme = [{"hold": {"F2": 0.0, "F3": 0.0}, "drive": {"F1": 1e-3}}]
            path = follow(SystemSpec("column", links=4), None, programme, {}, options)
        elif item == "general-rate":  # the model kernel only: general-total compiles the loop
            import numpy as np

            from ncstab.paths.api import case_batch, resolve_model

            model = resolve_model(SystemSpec("ring", grains=4, secondary_contacts="ignore"), ["cundall_strack"])
            case_batch(model.laws[0], model, {"gamma": np.array([1.0])}, 1)._kernel.callback  # noqa: B018 - compiles it
            continue
        elif item == "dataset":
            from ncstab.operators.stored_states import compile_batches

            compile_batches()
            continue
        else:
            programme = [{"hold": {"F2": 0.0}, "drive": {"D1": 0.01}}]
            path = follow(SystemSpec(secondary_contacts="ignore"), item, programme, {"gamma": 1.0}, options)
        engine = path.results[0].engine
        if not engine.startswith("compiled stepper"):
            raise RuntimeError(f"{item} did not run on the compiled stepper: {engine}")


def groups_by_model(items: Sequence[str], processes: int) -> list[tuple[str, ...]]:
    """``items`` in at most ``processes`` groups, the general models' loop
    (``general-total``) apart from the rest (the reduced diamond's laws, a ring's kernel):
    the loop is compiled once per kind of model (the laws and models add their small
    kernels), so no two processes compile the same loop."""
    kinds: dict[bool, list[str]] = {}
    for item in items:
        kinds.setdefault(item == "general-total", []).append(item)
    groups: list[list[str]] = [[] for _ in range(max(1, min(processes, len(kinds))))]
    for k, members in enumerate(kinds.values()):
        groups[k % len(groups)].extend(members)
    return [tuple(group) for group in groups if group]


def compile_loops(
    items: Sequence[str], processes: int, done: Callable[[tuple[str, ...], float], None] | None = None
) -> float:
    """Compile ``items`` into the cache in ``processes`` Python processes at once (this
    ncstab, this environment: the same cache root); ``done(group, seconds)`` as each
    process ends.  Returns the wall seconds.

    Raises
    ------
    RuntimeError
        When a process fails, naming its items and the last line it printed.
    """
    source = str(Path(__file__).resolve().parent.parent)
    path = os.pathsep.join([source, *filter(None, [os.environ.get("PYTHONPATH")])])
    environment = dict(os.environ, PYTHONPATH=path)
    start = time.perf_counter()

    def compile_group(group: tuple[str, ...]) -> tuple[tuple[str, ...], subprocess.CompletedProcess[str], float]:
        began = time.perf_counter()
        finished = subprocess.run([sys.executable, "-m", "ncstab.engine_warmup", *group], capture_output=True,
                                  text=True, env=environment, timeout=PROCESS_TIMEOUT, check=False)
        return group, finished, time.perf_counter() - began

    groups = groups_by_model(items, processes)
    with ThreadPoolExecutor(len(groups)) as pool:
        for future in as_completed([pool.submit(compile_group, group) for group in groups]):
            group, finished, seconds = future.result()
            if finished.returncode != 0:
                last = (finished.stderr.strip().splitlines() or [f"exit code {finished.returncode}"])[-1]
                raise RuntimeError(f"{', '.join(group)}: {last}")
            if done is not None:
                done(group, seconds)
    return time.perf_counter() - start


if __name__ == "__main__":
    compile_items(sys.argv[1:])
