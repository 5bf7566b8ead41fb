"""Sweep throughput: the engine against one solve_ivp per case, same run.

The problem (issue 3): the Cundall--Strack diamond, F2* held at 0 and Delta_1*
driven from 0 to 0.2, for 4,096 cases (64 gamma in [0.1, 2] x 64 alpha0 in
[0.3, 1.2]).  Both methods must reach F1* and Delta_2* at Delta_1* = 0.2
within 1e-8 of a tight reference (solve_ivp DOP853, rtol 1e-13), checked on a
random subset of cases.  The baseline integrates the seed's Eq. (38) written
by hand with scalar math, which is the fastest plain-Python form of the loop,
at the engine's tolerances (rtol 1e-10, atol 1e-12).

Run:  python benchmarks/bench_sweep_cundall_strack.py [--cases-per-side 64] [--repeat 3]
      [--engine-runs 10] [--threads N]

The engine runs with **default options** (``PathOptions()``: rtol 1e-10, atol
1e-12, ``max_step`` 1, stored states and sign checks at most ``sample_step``
0.02 apart; the compiled stepper, numba, one compiled loop per case, on every
core unless ``--threads`` says fewer).  Its compilation (once per form of law
and machine, or loading it from the cache) happens before the timed runs and
is reported apart.

Prints the times (the median of ``--repeat`` runs of each method, taken in
turn in the same process), the ratios of those medians, the ratio run by run,
and the accuracy of each.  Each engine time is the mean of ``--engine-runs``
sweeps run back to back (10), so that every timed window lasts about 0.3 s or
more, like one run of the loop (about 2-3 s): a pause of the machine of a few
milliseconds would otherwise weigh ten to a hundred times more on one sweep
(0.03-0.13 s) than on the loop.  The engine also locates every event (the secondary-contact gaps
reach zero in many cases); a second baseline does that job too, with
solve_ivp event functions.  This is a benchmark, not a test: nothing here
asserts a time.
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np
from scipy.integrate import solve_ivp

import ncstab
from ncstab.paths import PathOptions, SystemSpec
from ncstab.paths.threads import thread_count, using_threads

TARGET = 0.2


def baseline_rhs(gamma: float, alpha0: float):
    """dy/dD1 for y = (D2, F1) with F2 = 0 held, from seed Eq. (38)."""
    c0, s0 = math.cos(alpha0), math.sin(alpha0)

    def rhs(d1: float, y: np.ndarray) -> list[float]:
        d2, f1 = y
        vertical, horizontal = c0 - d1, s0 - d2
        length = math.hypot(vertical, horizontal)
        c, s = vertical / length, horizontal / length
        k11 = 2 * c * c + 2 * gamma * s * s
        k12 = 2 * (1 - gamma) * c * s
        k21 = 2 * (1 - gamma) * c * s + s / length * f1
        k22 = 2 * s * s + 2 * gamma * c * c - c / length * f1
        dd2 = -k21 / k22
        return [dd2, k11 + k12 * dd2]

    return rhs


def secondary_gap_events(alpha0: float):
    """solve_ivp event functions for the two secondary-contact gaps (what the engine locates)."""
    c0, s0 = math.cos(alpha0), math.sin(alpha0)

    def top_bottom(d1: float, y: np.ndarray) -> float:
        return 2 * (c0 - d1) - 1

    def left_right(d1: float, y: np.ndarray) -> float:
        return 2 * (s0 - y[0]) - 1

    return [top_bottom, left_right]


def run_baseline(
    gammas: np.ndarray, alpha0s: np.ndarray, rtol: float, atol: float, events: bool = False
) -> np.ndarray:
    out = np.empty((gammas.size, 2))
    for k, (gamma, alpha0) in enumerate(zip(gammas, alpha0s)):
        sol = solve_ivp(
            baseline_rhs(gamma, alpha0), (0.0, TARGET), [0.0, 0.0], method="DOP853", rtol=rtol, atol=atol,
            events=secondary_gap_events(alpha0) if events else None,
        )
        out[k] = sol.y[:, -1]
    return out


def run_engine(gamma: np.ndarray, alpha0: np.ndarray, options: PathOptions) -> tuple[np.ndarray, object]:
    path = ncstab.follow(
        SystemSpec(secondary_contacts="ignore"),
        "cundall_strack",
        [{"hold": {"F2": 0.0}, "drive": {"D1": TARGET}}],
        {"gamma": list(gamma), "alpha0": list(alpha0)},
        options,
    )
    result = path.results[0]
    last = result.n_steps - 1
    rows = np.arange(last.size)
    d2 = result.steps["u"][rows, last, 1]
    f1 = result.steps["F"][rows, last, 0]
    return np.column_stack([d2, f1]), path


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--cases-per-side", type=int, default=64)
    parser.add_argument("--check", type=int, default=128, help="cases checked against the tight reference")
    parser.add_argument("--repeat", type=int, default=1, help="runs of each method; the median is reported")
    parser.add_argument("--engine-runs", type=int, default=10, help="back-to-back sweeps per timing of the engine")
    parser.add_argument("--threads", type=int, default=None,
                        help="threads of the compiled stepper (default: every core, as the engine)")
    args = parser.parse_args()
    side = args.cases_per_side
    gamma = np.linspace(0.1, 2.0, side)
    alpha0 = np.linspace(0.3, 1.2, side)
    gg, aa = (m.ravel() for m in np.meshgrid(gamma, alpha0, indexing="ij"))
    n = gg.size
    # the defaults (rtol 1e-10, atol 1e-12, max_step 1, sample_step 0.02), the machine code
    # always: the one-case warm-up would otherwise run as plain Python on a new machine
    options = PathOptions(backend="compiled")

    with using_threads(args.threads):
        start = time.perf_counter()
        run_engine(gamma[:1], alpha0[:1], options)  # sympy derivation, numba compilation (or the cache)
        compile_time = time.perf_counter() - start

        baseline_rtol, baseline_atol = options.rtol, options.atol
        times: dict[str, list[float]] = {"engine": [], "baseline": [], "baseline_events": []}

        def timed_engine(runs: int) -> tuple[float, tuple]:
            """Mean time of ``runs`` back-to-back sweeps (a timed window of ~0.3 s or more)."""
            start = time.perf_counter()
            for _ in range(runs):
                result = run_engine(gamma, alpha0, options)
            return (time.perf_counter() - start) / runs, result

        for _ in range(args.repeat):  # interleaved, so a slow spell of the machine hits every method
            elapsed, (engine, path) = timed_engine(args.engine_runs)
            times["engine"].append(elapsed)
            start = time.perf_counter()
            baseline = run_baseline(gg, aa, baseline_rtol, baseline_atol)
            times["baseline"].append(time.perf_counter() - start)
            start = time.perf_counter()
            run_baseline(gg, aa, baseline_rtol, baseline_atol, events=True)
            times["baseline_events"].append(time.perf_counter() - start)
        threads = thread_count()
    engine_time, baseline_time, baseline_events_time = (statistics.median(times[k]) for k in times)

    rng = np.random.default_rng(0)
    subset = rng.choice(n, size=min(args.check, n), replace=False)
    reference = run_baseline(gg[subset], aa[subset], 1e-13, 1e-14)
    engine_error = np.abs(engine[subset] - reference).max()
    baseline_error = np.abs(baseline[subset] - reference).max()
    statuses = {str(s): int(c) for s, c in zip(*np.unique(path.status, return_counts=True))}

    print(f"cases                      {n}   (median of {args.repeat} run(s) of each method; "
          f"the engine on {threads} thread(s))")
    print(f"engine: {path.results[0].engine}")
    print(f"engine (default options)   {engine_time:8.3f} s   max error {engine_error:.2e}   statuses {statuses}   "
          f"(compilation or cache load before: {compile_time:.1f} s)")
    print(f"baseline (solve_ivp loop)  {baseline_time:8.3f} s   max error {baseline_error:.2e}")
    print(f"baseline with the same events located  {baseline_events_time:8.3f} s")
    print(f"ratio baseline / engine           {baseline_time / engine_time:8.1f} x (no events in the baseline)")
    print(f"ratio baseline+events / engine    {baseline_events_time / engine_time:8.1f} x (same job)")
    per_run = [b / e for b, e in zip(times["baseline"], times["engine"])]
    print(f"ratio baseline / engine, run by run: {', '.join(f'{r:.0f}' for r in per_run)} x")
    counters = path.results[0].counters
    attempts = counters["accepted"] + counters["rejected"]
    print(f"step attempts per case: {attempts.mean():.2f} (accepted {counters['accepted'].mean():.2f})")
    print(f"events located by the engine (the baseline locates none): {int(counters['located'].sum())}")


if __name__ == "__main__":
    main()
