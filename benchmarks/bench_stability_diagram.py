"""Stability diagram throughput: 65,536 cases with their events located (issue 6).

The problem: the programme of ``studies/stability_diagram.toml`` (lateral
preload F2* from rest with F1 held at 0, then Delta_1* driven to 0.6 with F2*
held; alpha0 = pi/4, secondary contacts ignored, sample_step = 0.05) for one law
over a side x side grid of gamma in [0.1, 2] x F2* in [0, 0.8]; by default
256 x 256 = 65,536 cases, followed in-process with :func:`ncstab.follow`.

Run:  python benchmarks/bench_stability_diagram.py [--side 256] [--law mcnamara] [--repeat 1] [--dataset] [--tracemalloc]

Prints the time of ``follow`` (the median of ``--repeat`` runs), and with
``--dataset`` that of ``to_dataset``, the
cases per second, the peak memory (peak resident set size of the process, and
with ``--tracemalloc`` the tracemalloc peak of Python allocations during
``follow``, which slows it several times: measure time without it), the statuses, and
how many cases located each event.  This is a benchmark, not a test: nothing
here asserts a time.
"""

from __future__ import annotations

import argparse
import collections
import math
import resource
import statistics
import sys
import time
import tracemalloc

import numpy as np

import ncstab
from ncstab.paths import PathOptions, SystemSpec

PROGRAMME = [
    {"hold": {"F1": 0.0}, "drive": {"F2": "F2_lateral"}},
    {"hold": {"F2": "current"}, "drive": {"D1": 0.6}},
]
EVENTS = ("hill_loss", "limit_point", "controllability_loss")


def peak_rss_mib() -> float:
    """Peak resident set size of this process, MiB (ru_maxrss is KiB on Linux, bytes on macOS)."""
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
    return peak / 2**20 if sys.platform == "darwin" else peak / 2**10


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--side", type=int, default=256, help="grid points per parameter (cases = side^2)")
    parser.add_argument("--law", default="mcnamara")
    parser.add_argument("--repeat", type=int, default=1, help="runs of follow; the median is reported")
    parser.add_argument("--dataset", action="store_true", help="also time Path.to_dataset()")
    parser.add_argument("--tracemalloc", action="store_true",
                        help="also trace the peak of Python allocations (slows follow several times; a separate run)")
    args = parser.parse_args(argv)

    gamma = np.linspace(0.1, 2.0, args.side)
    lateral = np.linspace(0.0, 0.8, args.side)
    n_cases = gamma.size * lateral.size
    print(f"stability diagram benchmark: {args.law}, {args.side} x {args.side} = {n_cases:,} cases")
    rss_before = peak_rss_mib()
    if args.tracemalloc:
        tracemalloc.start()
    times = []
    for _ in range(args.repeat):
        start = time.perf_counter()
        path = ncstab.follow(
            SystemSpec(secondary_contacts="ignore"),
            [args.law],
            PROGRAMME,
            {"gamma": gamma.tolist(), "F2_lateral": lateral.tolist(), "alpha0": math.pi / 4},
            PathOptions(sample_step=0.05),
        )
        times.append(time.perf_counter() - start)
    elapsed = statistics.median(times)
    traced_peak = tracemalloc.get_traced_memory()[1] if args.tracemalloc else float("nan")
    if args.tracemalloc:
        tracemalloc.stop()
    runs = f" (median of {len(times)}: {', '.join(f'{t:.1f}' for t in times)} s)" if len(times) > 1 else ""
    print(f"follow: {elapsed:.1f} s, {n_cases / elapsed:,.0f} cases/s{runs}")
    print(f"peak RSS: {peak_rss_mib():,.0f} MiB (before follow: {rss_before:,.0f} MiB); "
          f"tracemalloc peak during follow: "
          + (f"{traced_peak / 2**20:,.0f} MiB" if args.tracemalloc else "not traced (--tracemalloc)"))
    result = path.results[0]
    steps = result.n_steps
    print(f"stored states per case: mean {steps.mean():.1f}, max {steps.max()}; "
          f"accepted steps {int(result.counters['accepted'].sum()):,}, rejected {int(result.counters['rejected'].sum()):,}")
    statuses = collections.Counter(path.status.ravel().astype(str).tolist())
    print("statuses: " + ", ".join(f"{name}: {count:,}" for name, count in sorted(statuses.items())))
    located = {event: int(np.isfinite(result.events[event]["s"]).sum()) for event in EVENTS}
    print("events located: " + ", ".join(f"{event}: {count:,}" for event, count in located.items()))
    if args.dataset:
        start = time.perf_counter()
        dataset = path.to_dataset()
        print(f"to_dataset: {time.perf_counter() - start:.1f} s, {dataset.nbytes / 2**20:,.0f} MiB; "
              f"peak RSS now {peak_rss_mib():,.0f} MiB")


if __name__ == "__main__":
    main()
