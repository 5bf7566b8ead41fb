"""Compiled model kernels: the first-run cost of a new model and the start-up of a cached one.

For each model below, two fresh processes share a new, empty cache directory
(``NCSTAB_CACHE_DIR``): the first prints the model's kernel with sympy and
numba compiles it (the cost of a model never run on this machine), the second
finds both in the cache (the start-up of every later run).  Each process
times, from after ``import ncstab``:

* ``build`` -- the model batch (``case_batch``: the system's and the laws'
  definitions, no kernel yet);
* ``kernel`` -- :class:`ncstab.operators.model_kernel.ModelKernel`: printing the
  module (sympy) or finding it, and importing it;
* ``first call`` -- the first evaluation: numba compiles, or loads its machine
  code from the cache;
* ``one path`` -- a whole ``follow`` of one case (whatever else the engine
  compiles on first use included).

Run:  python benchmarks/bench_model_kernels.py

This is a benchmark, not a test: nothing here asserts a time.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile

MODELS = {
    "ring, 6 grains, cundall_strack": ("ring", {"grains": 6, "secondary_contacts": "ignore"}, "cundall_strack"),
    "ring, 6 grains, mcnamara, gaps activated": ("ring", {"grains": 6, "secondary_contacts": "activate"}, "mcnamara"),
    "diamond on its axes, turco+no_tension": ("diamond", {"reduction": "axes"}, "turco+no_tension"),
    "column, 6 links": ("column", {"links": 6}, None),
    "ziegler, follower load": ("ziegler", {"load": "follower"}, None),
}

SCRIPT = r"""
import json, sys, time
import numpy as np
import ncstab
from ncstab.paths import SystemSpec
from ncstab.paths.api import case_batch, resolve_model
from ncstab.operators.model_kernel import model_kernel

name, settings, law = json.loads(sys.argv[1])
start = time.perf_counter()
spec = SystemSpec(name, **settings)
model = resolve_model(spec, [law] if law else None)
values = {"gamma": np.array([1.0])} if law else {}
batch = case_batch(model.laws[0], model, values, 1)
built = time.perf_counter()
kernel = model_kernel(batch.definition, batch.laws, batch.activate_secondary)
loaded = time.perf_counter()
batch.evaluate(np.full((1, batch.n_dof), 0.01), np.zeros((1, batch.n_internal)))
called = time.perf_counter()
programme = [{"drive": {"P": 0.5}}] if batch.has_load else [{"hold": {f: 0.0 for f in batch.force_names[1:]}, "drive": {batch.dof_names[0]: 0.05}}]
path = ncstab.follow(spec, [law] if law else None, programme, {"gamma": 1.0} if law else {})
assert path.status.ravel()[0] == "finished", path.status
done = time.perf_counter()
print(json.dumps({"build": built - start, "kernel": loaded - built, "first call": called - loaded, "one path": done - called}))
"""


def run(model: tuple, cache: str) -> dict[str, float]:
    environment = {**os.environ, "NCSTAB_CACHE_DIR": cache, "NUMPY_MADVISE_HUGEPAGE": "0"}
    done = subprocess.run([sys.executable, "-c", SCRIPT, json.dumps(model)], capture_output=True, text=True,
                          env=environment, check=True)
    return json.loads(done.stdout.strip().splitlines()[-1])


def main() -> None:
    print(f"{'model':42s} {'run':6s} {'build':>7s} {'kernel':>7s} {'first call':>11s} {'one path':>9s}")
    for label, model in MODELS.items():
        with tempfile.TemporaryDirectory(prefix="ncstab-bench-kernels-") as cache:
            for run_name in ("new", "cached"):
                times = run(model, cache)
                print(f"{label:42s} {run_name:6s} {times['build']:6.2f}s {times['kernel']:6.2f}s "
                      f"{times['first call']:10.2f}s {times['one path']:8.2f}s")


if __name__ == "__main__":
    main()
