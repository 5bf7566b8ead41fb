"""The default engine through a study, against one solve_ivp per case (issue 14).

The study: the Cundall--Strack diamond, F2* held at 0 and Delta_1* driven from
0 to 0.2, gamma in [0.1, 2] x alpha0 in [pi/6, pi/3] (``--cases-per-side``
each, 64: 4,096 cases), secondary contacts ignored (the plain loop does not
switch springs), **default options** (``max_step = 1``: the steps the
tolerance needs, stored states and sign checks at most ``sample_step = 0.02``
apart on each step's interpolant; ``backend = "auto"``: the compiled stepper,
on every core).  The engine is timed as a
user runs it in Python: ``load_study`` + ``run_study`` (the Dataset built);
the baseline is the loop of :mod:`bench_sweep_cundall_strack` (one
``solve_ivp`` DOP853 per case of the seed's Eq. 38, the same rtol/atol), and
both are checked against a tight reference (rtol 1e-13) on a subset of cases.

For each thread count (``--threads 1 2``) it prints the median wall time,
the CPU time over wall time, and the ratio to the loop; the ratio of 1 to 2
threads is the speed-up.  The numba compilation of the law (once per machine)
happens before the timed runs and is reported apart.  It says whether numpy's
huge-page advice is on (the ``ncstab`` command switches it off; in Python it is
numpy's default unless ``NUMPY_MADVISE_HUGEPAGE=0`` is set: first touches of
memory stalled for seconds on a virtual machine).  A benchmark, not a test:
nothing here asserts a time.

Run:  python benchmarks/bench_default_engine.py [--cases-per-side 64] [--repeat 3] [--threads 1 2]
      [--compare "max_step = 0.02; sample_step = 0.02"]  (also the defaults before sample_step, same run)
"""

from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from bench_sweep_cundall_strack import TARGET, run_baseline  # noqa: E402

from ncstab.paths.threads import using_threads  # noqa: E402
from ncstab.studies import load_study, run_study  # noqa: E402

STUDY = """
[study]
name = "default_engine"
[system]
name = "diamond"
secondary_contacts = "ignore"
[laws]
names = ["cundall_strack"]
[parameters]
gamma = {{ start = 0.1, stop = 2.0, num = {side} }}
alpha0 = {{ start = "pi/6", stop = "pi/3", num = {side} }}
[[loading]]
hold = {{ F2 = 0.0 }}
drive = {{ D1 = {target} }}
"""


def run_engine(side: int, options: str = ""):
    """load_study + run_study; the Dataset and the end (D2, F1) per case.  ``options``:
    lines of an ``[options]`` table (none: the defaults)."""
    path = Path(tempfile.gettempdir()) / f"ncstab_bench_default_engine_{side}.toml"
    # backend = "compiled": the machine code in every run (a 4-case run would otherwise run
    # as plain Python on a new machine and leave the loop to compile in the timed runs)
    text = STUDY.format(side=side, target=TARGET) + f"[options]\nbackend = \"compiled\"\n{options}\n"
    path.write_text(text, encoding="utf-8")
    dataset = run_study(load_study(path))
    last = dataset["n_steps"].values.ravel() - 1
    rows = np.arange(last.size)
    u = dataset["u"].values.reshape(last.size, -1, 2)
    f = dataset["F"].values.reshape(last.size, -1, 2)
    return dataset, np.column_stack([u[rows, last, 1], f[rows, last, 0]])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases-per-side", type=int, default=64)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--threads", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--check", type=int, default=64, help="cases checked against the tight reference")
    parser.add_argument("--no-baseline", action="store_true", help="engine only (large sweeps)")
    parser.add_argument("--compare", default="", metavar="OPTIONS",
                        help='also time the engine with these [options] lines, e.g. "max_step = 0.02; sample_step = 0.02" '
                             "(the defaults before sample_step)")
    args = parser.parse_args()
    compared = "\n".join(part.strip() for part in args.compare.split(";") if part.strip())
    side = args.cases_per_side
    start = time.perf_counter()
    run_engine(2)  # sympy derivation and numba compilation (or the cached loop)
    print(f"first run of 4 cases (compilation or cache load): {time.perf_counter() - start:.1f} s")
    core = getattr(np, "_core", None) or np.core
    print(f"numpy's huge-page advice: {'on' if core.multiarray._get_madvise_hugepage() else 'off'} "
          "(NUMPY_MADVISE_HUGEPAGE=0 switches it off, as the ncstab command does; docs/paths.md)")
    dataset, engine_end = run_engine(side)
    print(f"{dataset.sizes['gamma'] * dataset.sizes['alpha0']} cases, engine: {dataset.attrs['engine']}")
    gamma, alpha0 = (m.ravel() for m in np.meshgrid(dataset["gamma"].values, dataset["alpha0"].values,
                                                     indexing="ij"))
    times: dict[str, list[float]] = {f"engine, {n} thread(s)": [] for n in args.threads}
    cpu: dict[str, list[float]] = {key: [] for key in times}
    if compared:
        run_engine(2, compared)
        for n in args.threads:
            times[f"[{args.compare}], {n} thread(s)"] = []
            cpu[f"[{args.compare}], {n} thread(s)"] = []
    if not args.no_baseline:
        times["solve_ivp loop"] = []
    for _ in range(args.repeat):  # interleaved: a slow spell of the machine hits every method
        for n in args.threads:
            for key, options in ((f"engine, {n} thread(s)", ""), (f"[{args.compare}], {n} thread(s)", compared)):
                if key not in times:
                    continue
                with using_threads(n):
                    wall, process = time.perf_counter(), time.process_time()
                    run_engine(side, options)
                    times[key].append(time.perf_counter() - wall)
                    cpu[key].append(time.process_time() - process)
        if not args.no_baseline:
            wall = time.perf_counter()
            baseline_end = run_baseline(gamma, alpha0, 1e-10, 1e-12)
            times["solve_ivp loop"].append(time.perf_counter() - wall)
    medians = {key: statistics.median(value) for key, value in times.items()}
    for key, value in medians.items():
        line = f"{key:24s} {value:8.3f} s"
        if key in cpu:
            line += f"   CPU/wall {statistics.median(cpu[key]) / value:.2f}"
        if "solve_ivp loop" in medians and key != "solve_ivp loop":
            line += f"   {medians['solve_ivp loop'] / value:6.1f}x the loop"
        print(line)
    if len(args.threads) > 1:
        one, most = f"engine, {min(args.threads)} thread(s)", f"engine, {max(args.threads)} thread(s)"
        print(f"speed-up of {max(args.threads)} threads over {min(args.threads)}: {medians[one] / medians[most]:.2f}x")
    if not args.no_baseline:
        check = np.linspace(0, gamma.size - 1, min(args.check, gamma.size)).astype(int)
        reference = run_baseline(gamma[check], alpha0[check], 1e-13, 1e-15)
        print(f"largest error against the tight reference: engine {np.abs(engine_end[check] - reference).max():.1e}, "
              f"loop {np.abs(baseline_end[check] - reference).max():.1e}")


if __name__ == "__main__":
    main()
